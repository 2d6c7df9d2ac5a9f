"""Wave fields for the wave-analysis tests: maps of the simulator's surfaces on a map grid."""

from __future__ import annotations

import numpy as np

from holoview.optics.wave_fields import random_travelling_waves


def grid(size: int, pixel: float) -> tuple[np.ndarray, np.ndarray]:
    """Map coordinates x (1, size) and y (size, 1), m, from the first pixel's centre."""
    axis = np.arange(size) * pixel
    return axis[np.newaxis, :], axis[:, np.newaxis]


def sample(surface, times, size: int, pixel: float, *, noise: float = 0.0, seed: int = 0):
    """Maps (frames, size, size) float32 of ``surface`` at ``times``, white noise added (m)."""
    x, y = grid(size, pixel)
    rng = np.random.default_rng(seed)
    return np.array(
        [surface(t, x, y) + rng.normal(0.0, noise, (size, size)) for t in times], np.float32
    )


def travelling(seed: int = 1, **changes):
    """Broadband capillary-gravity waves on a 3 mm layer with a flow (the truth)."""
    settings = {
        "k_range": (300.0, 1600.0),
        "components": 200,
        "rms": 30e-9,
        "depth": 3e-3,
        "flow": (0.02, -0.01),
    } | changes
    return random_travelling_waves(np.random.default_rng(seed), **settings)
