"""Synthetic multiplexed holograms for the GUI tests (no simulator needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import tifffile

from holoview.optics.families import alpha_of, infer_carriers

N1, N2 = 1.0, 1.333
WAVELENGTH_M = 532e-9
#: Two labelled carriers (cycles/pixel); the model gives the others.
RB1 = (0.19, -0.06)
FB1 = (0.11, 0.17)
FAMILIES = ("RB1", "FB1", "RF", "RB2")


def carriers() -> dict[str, tuple[float, float]]:
    """The carriers of :data:`FAMILIES` as the model places them from RB1 and FB1."""
    model = infer_carriers({"RB1": RB1, "FB1": FB1}, N1, N2)
    return {k: model[k] for k in FAMILIES}


def hologram_stack(
    n: int,
    shape: tuple[int, int] = (256, 256),
    seed: int = 0,
    shifts: dict[str, tuple[float, float]] | None = None,
) -> np.ndarray:
    """Return ``n`` 12-bit frames holding the four families, a bump rising 5 nm per frame.

    ``shifts`` gives families a displacement ``(dy, dx)`` in pixels: they image the
    bump at ``r + shift`` (paper section 2).
    """
    rng = np.random.default_rng(seed)
    rows, cols = shape
    y, x = np.mgrid[0:rows, 0:cols].astype(np.float64)

    def bump(dy: float, dx: float) -> np.ndarray:
        r2 = (x + dx - cols / 2) ** 2 + (y + dy - rows / 2) ** 2
        return np.exp(-r2 / (2 * (cols / 8) ** 2))

    bumps = {name: bump(*(shifts or {}).get(name, (0.0, 0.0))) for name in FAMILIES}
    frames = np.empty((n, rows, cols), np.uint16)
    for t in range(n):
        image = np.ones(shape)
        for amplitude, (name, (fx, fy)) in zip(
            (0.2, 0.12, 0.08, 0.05), carriers().items(), strict=True
        ):
            h = bumps[name] * 5e-9 * t
            phase = (
                2 * np.pi * (fx * x + fy * y)
                + 4 * np.pi * alpha_of(name, N1, N2) * h / WAVELENGTH_M
            )
            image += 2 * amplitude * np.cos(phase)
        frames[t] = np.clip(rng.poisson(image * 1500), 0, 4095)
    return frames


def write_stack(path: Path, n: int = 8, shape: tuple[int, int] = (256, 256)) -> Path:
    """Write :func:`hologram_stack` as a TIFF stack; return its path."""
    tifffile.imwrite(path, hologram_stack(n, shape))
    return path
