"""Fixtures of the live engine's tests."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from holoview.cli import main


@pytest.fixture(scope="session")
def simulate_evaporation(tmp_path_factory: pytest.TempPathFactory) -> Callable[[int], Path]:
    """Make a recording: evaporation at 60 um/min, 128 x 128, N frames at 20 frames/s.

    It carries the simulator's experiment (its true labels).
    """

    def make(frames: int) -> Path:
        path = tmp_path_factory.mktemp("live") / "evaporation.h5"
        argv = ["-q", "simulate", str(path), "--scenario", "evaporation", "--size", "128"]
        argv += ["--frames", str(frames), "--fps", "20", "--seed", "5"]
        assert main([*argv, "--evaporation-um-per-min", "60"]) == 0
        return path

    return make
