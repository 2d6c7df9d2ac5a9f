"""Fixtures of the fault tests: a real small disk, a small simulated recording."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np
import pytest
from faults_helpers import mounted_tmpfs, reap_children

from holoview.cli import main


@pytest.fixture(autouse=True)
def _no_child_left() -> Iterator[None]:
    """Children a failed test left running are killed at its end."""
    yield
    reap_children()


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A real 20 MB file system (tmpfs), unmounted after the test; skipped where refused."""
    with mounted_tmpfs(tmp_path / "disk", size_mb=20) as disk:
        yield disk


@pytest.fixture(scope="session")
def sim_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated evaporation, 128 x 128, 40 frames at 20 frames/s (with its setup)."""
    path = tmp_path_factory.mktemp("faults") / "evaporation.h5"
    argv = ["-q", "simulate", str(path), "--scenario", "evaporation", "--size", "128"]
    assert main([*argv, "--frames", "40", "--fps", "20", "--seed", "5"]) == 0
    return path


@pytest.fixture(scope="session")
def long_stack(tmp_path_factory: pytest.TempPathFactory, sim_recording: Path) -> Path:
    """3000 frames (the simulation's 40, over and over) as a numpy stack: a run of seconds."""
    with h5py.File(sim_recording, "r") as f:
        frames = f["frames"][:]
    path = tmp_path_factory.mktemp("long") / "long.npy"
    np.save(path, np.tile(frames, (75, 1, 1)))
    return path
