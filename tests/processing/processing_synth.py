"""A small hologram synthesiser for the processing tests: plane-wave carriers, Poisson noise.

``frame = Poisson(photons * (1 + sum_m 2 A_m cos(2 pi (fx x + fy y) + phi_m(y, x))))``:
each carrier ``m`` is a complex exponential of relative amplitude ``A_m`` plus its
twin, the convention of :class:`holoview.processing.peaks.detection.Peak`. The shot-noise
floor of a demodulated phase is then ``sqrt(eta / (2 photons)) / A`` (docs/design.md).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: Carriers (fx, fy) in cycles/pixel, amplitudes and prefactors of a four-peak bench
#: (paper supplement eq. 7 with R = 0.1416; alpha on the twin where it is positive).
BENCH = (
    ("RB1", (-0.15, 0.17), 0.1225, 0.333),
    ("RF", (0.20, 0.05), 0.0177, 1.0),
    ("FB1", (0.05, 0.22), 0.0174, 1.333),
    ("RB2", (-0.10, 0.39), 0.0174, 2 * 1.333 - 1.0),
)
WAVELENGTH = 532e-9


def bump(shape: tuple[int, int], height: float, sigma: float) -> np.ndarray:
    """A Gaussian bump (m) of ``height`` and width ``sigma`` (pixels) in the frame's centre."""
    rows, cols = shape
    y, x = np.mgrid[:rows, :cols]
    r2 = (y - rows / 2) ** 2 + (x - cols / 2) ** 2
    return height * np.exp(-r2 / (2 * sigma**2))


def intensity(
    shape: tuple[int, int],
    carriers: Sequence[tuple[float, float]],
    amplitudes: Sequence[float],
    phases: Sequence[float | np.ndarray],
) -> np.ndarray:
    """Return the noiseless relative intensity ``1 + sum 2 A cos(...)``."""
    rows, cols = shape
    y, x = np.mgrid[:rows, :cols].astype(np.float64)
    out = np.ones(shape)
    for (fx, fy), a, phi in zip(carriers, amplitudes, phases, strict=True):
        out += 2 * a * np.cos(2 * np.pi * (fx * x + fy * y) + phi)
    return out


def frame(
    shape: tuple[int, int],
    carriers: Sequence[tuple[float, float]],
    amplitudes: Sequence[float],
    phases: Sequence[float | np.ndarray],
    *,
    photons: float = 800.0,
    rng: np.random.Generator,
    dtype: type = np.uint16,
) -> np.ndarray:
    """Return a Poisson-noisy frame with ``photons`` mean counts per pixel."""
    mean = photons * intensity(shape, carriers, amplitudes, phases)
    return rng.poisson(mean).astype(dtype)


def bench_frame(
    shape: tuple[int, int],
    h: np.ndarray | float,
    *,
    rng: np.random.Generator,
    photons: float = 800.0,
) -> np.ndarray:
    """A frame of the four-peak :data:`BENCH` with surface height ``h`` (m)."""
    k0 = 2 * np.pi / WAVELENGTH
    phases = [2 * k0 * alpha * np.asarray(h) + 0.7 * i for i, (_, _, _, alpha) in enumerate(BENCH)]
    return frame(
        shape,
        [c for _, c, _, _ in BENCH],
        [a for _, _, a, _ in BENCH],
        phases,
        photons=photons,
        rng=rng,
    )
