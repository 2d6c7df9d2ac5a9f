"""Fixtures of the headless tests: small simulated recordings with their truth."""

from __future__ import annotations

import pytest
from headless_sim import EVAPORATION_UM_PER_MIN, Simulated, simulate


@pytest.fixture(scope="session")
def evaporation(tmp_path_factory: pytest.TempPathFactory) -> Simulated:
    """Water evaporating at 60 um/min, 128 x 128, 120 frames at 20 frames/s."""
    path = tmp_path_factory.mktemp("sim") / "evaporation.h5"
    return simulate(path, "evaporation", "--evaporation-um-per-min", str(EVAPORATION_UM_PER_MIN))


@pytest.fixture(scope="session")
def waves(tmp_path_factory: pytest.TempPathFactory) -> Simulated:
    """Standing waves of 40 nm rms on water, 128 x 128, 120 frames at 20 frames/s."""
    path = tmp_path_factory.mktemp("sim") / "waves.h5"
    return simulate(path, "waves", "--wave-rms-nm", "40")
