"""Benches for the optics tests: random but valid tilts, carriers on FFT bins."""

from __future__ import annotations

import numpy as np

from holoview.optics.setup import Setup


def random_setup(rng: np.random.Generator, **changes: object) -> Setup:
    """Return a setup with random tilts whose first-order carriers are well apart.

    RF and FB1 are drawn in 0.06..0.2 cycles/pixel per axis with random signs, and
    redrawn until RF, FB1, RB1 and their twins are at least 0.05 cycles/pixel apart
    and from the origin.
    """
    base = Setup(**changes)  # type: ignore[arg-type]
    scale = 2 * base.pixel_pitch / base.wavelength
    while True:
        rf = rng.uniform(0.06, 0.2, 2) * rng.choice([-1, 1], 2)
        fb1 = rng.uniform(0.06, 0.2, 2) * rng.choice([-1, 1], 2)
        rb1 = fb1 - rf
        points = [rf, fb1, rb1, -rf, -fb1, -rb1, np.zeros(2)]
        gaps = [np.abs(a - b).max() for i, a in enumerate(points) for b in points[i + 1 :]]
        if min(gaps) > 0.05 and np.abs(rb1).max() < 0.45:
            break
    m_r = tuple(float(f / (scale * base.n1)) for f in rf)
    m_b = tuple(float(f / (scale * base.n2)) for f in fb1)
    return base.replace(m_r=m_r, m_b=m_b)


def integer_bin_setup(
    shape: tuple[int, int], rf_bins: tuple[int, int], fb1_bins: tuple[int, int], **changes: object
) -> Setup:
    """Return a setup whose RF and FB1 carriers (hence every family's) sit on FFT bins."""
    base = Setup(shape=shape, **changes)  # type: ignore[arg-type]
    rows, cols = shape
    scale = 2 * base.pixel_pitch / base.wavelength
    m_r = (rf_bins[0] / cols / (scale * base.n1), rf_bins[1] / rows / (scale * base.n1))
    m_b = (fb1_bins[0] / cols / (scale * base.n2), fb1_bins[1] / rows / (scale * base.n2))
    return base.replace(m_r=m_r, m_b=m_b)
