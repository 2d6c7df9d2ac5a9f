"""Fixtures of the identify tests: simulated recordings with known truth."""

from __future__ import annotations

import pytest
from identify_model import N_AIR, Recording, model_peaks, simulate


@pytest.fixture
def evaporation() -> Recording:
    """Isopropanol, 5.72 um/min, 10 fps, 60 s; reference arm: 10 nm tones, 3 nm drift."""
    return simulate(
        model_peaks(N_AIR, 1.377),
        -5.72e-6 / 60,
        fps=10.0,
        duration=60.0,
        vibration=10e-9,
        drift=3e-9,
        seed=7,
    )
