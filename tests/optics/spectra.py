"""Small spectral helpers for the optics tests (the real demodulator lives in processing)."""

from __future__ import annotations

import numpy as np


def spectrum(frame: np.ndarray) -> np.ndarray:
    """Return the FFT of a frame with its mean removed, normalised by mean and size.

    A cosine of modulation depth ``A`` gives ``A / 2`` at its carrier bin.
    """
    data = np.asarray(frame, dtype=float)
    mean = data.mean()
    return np.fft.fft2(data - mean) / (data.size * mean)


def bin_of(carrier: tuple[float, float], shape: tuple[int, int]) -> tuple[int, int]:
    """Return the (row, col) FFT bin nearest to a carrier (fx, fy), cycles/pixel."""
    rows, cols = shape
    return round(carrier[1] * rows) % rows, round(carrier[0] * cols) % cols


def peak_near(
    spec: np.ndarray, carrier: tuple[float, float], search: int = 3
) -> tuple[float, float, float]:
    """Return (fx, fy, magnitude) of the largest bin within ``search`` bins of ``carrier``.

    The position is refined by a parabola through the neighbours on each axis.
    """
    rows, cols = spec.shape
    r0, c0 = bin_of(carrier, spec.shape)
    best = (0.0, r0, c0)
    for dr in range(-search, search + 1):
        for dc in range(-search, search + 1):
            value = abs(spec[(r0 + dr) % rows, (c0 + dc) % cols])
            if value > best[0]:
                best = (value, r0 + dr, c0 + dc)
    magnitude, r, c = best

    def refine(minus: float, centre: float, plus: float) -> float:
        denominator = minus - 2 * centre + plus
        return 0.0 if denominator == 0 else 0.5 * (minus - plus) / denominator

    a = np.abs(spec)
    dr = refine(a[(r - 1) % rows, c % cols], a[r % rows, c % cols], a[(r + 1) % rows, c % cols])
    dc = refine(a[r % rows, (c - 1) % cols], a[r % rows, c % cols], a[r % rows, (c + 1) % cols])
    fy = ((r + dr) / rows + 0.5) % 1.0 - 0.5
    fx = ((c + dc) / cols + 0.5) % 1.0 - 0.5
    return fx, fy, magnitude


def demodulate(frame: np.ndarray, carrier: tuple[float, float], radius: float) -> np.ndarray:
    """Return the complex hologram of one carrier through a Tukey window in the spectrum.

    ``radius`` in cycles/pixel; flat out to 60 % of it, then a cosine taper to 0. The
    result keeps the carrier (multiply by a conjugate reference to remove it).
    """
    data = np.asarray(frame, dtype=float)
    rows, cols = data.shape
    fy = np.fft.fftfreq(rows)[:, None]
    fx = np.fft.fftfreq(cols)[None, :]
    dx = (fx - carrier[0] + 0.5) % 1.0 - 0.5
    dy = (fy - carrier[1] + 0.5) % 1.0 - 0.5
    distance = np.hypot(dx, dy) / radius
    taper = np.clip((distance - 0.6) / 0.4, 0.0, 1.0)
    window = np.where(distance < 1, 0.5 * (1 + np.cos(np.pi * taper)), 0.0)
    return np.fft.ifft2(np.fft.fft2(data - data.mean()) * window)
