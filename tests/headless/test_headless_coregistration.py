"""Co-registration in a headless run: displacements measured, reported, used by the fused map."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import tifffile
from headless_sim import Simulated, run_cli

from holoview.engine.map_step import FUSION_METHOD, fuse_maps
from holoview.processing.maps.coregister import MIN_MAP_SIDE, Displacement
from holoview.processing.maps.heights import fuse
from holoview.processing.maps.map_moves import coregister


def test_displacements_are_reported_and_stored_with_the_maps(
    waves: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "run"
    argv = ["process", str(waves.path), "--out", str(out), "--maps", "--frames", "0:60"]
    status, _, err = run_cli([*argv, *waves.label_args("RB1", "FB1")], capsys)
    assert status == 0, err
    summary = json.loads((out / "summary.json").read_text())
    labels = list(summary["peaks"])
    first = summary["peaks"][labels[0]]["displacement"]
    assert first["measured"] and first["shift_map_px"] == [0.0, 0.0]
    with h5py.File(out / "results.h5", "r") as f:
        step = f["maps/fused"].attrs["pixel_step_px"]
        assert f["maps/fused"].attrs["grid_of"] == labels[0]
        pitch = f.attrs["pixel_pitch_m"]
        for label in labels:
            entry = summary["peaks"][label]["displacement"]
            attrs = f["maps"][label].attrs
            np.testing.assert_allclose(attrs["displacement_px"], entry["shift_map_px"])
            assert bool(attrs["displacement_measured"]) == entry["measured"]
            np.testing.assert_allclose(
                entry["shift_frame_px"], np.multiply(entry["shift_map_px"], step)
            )
            np.testing.assert_allclose(
                entry["shift_m"], np.multiply(entry["shift_frame_px"], pitch)
            )
            if not entry["measured"]:
                assert entry["shift_map_px"] == [0.0, 0.0]


def test_fuse_maps_moves_the_maps_and_leaves_out_a_peak_that_stepped() -> None:
    """The maps step's fusion: moved by the displacements (Keys' cubic), stepped peaks out."""
    rng = np.random.default_rng(0)
    maps = [rng.normal(size=(32, 32)).astype(np.float32) for _ in range(3)]
    shifts = [(0.0, 0.0), (0.5, -0.25), (1.0, 2.0)]
    displacements = [Displacement(s, (0.01, 0.01), True, 50) for s in shifts]
    noise = [0.1e-9, 0.2e-9, 0.3e-9]
    steps = [[False, False, False], [False, True, False], [True, True, True]]
    for stepped, chosen in zip(steps, ([0, 1, 2], [0, 2], [0, 1, 2]), strict=True):
        fused = fuse_maps(maps, noise, stepped, displacements)
        moved = coregister(
            [maps[j] for j in chosen], [shifts[j] for j in chosen], method=FUSION_METHOD
        )
        expected, _ = fuse(moved, [noise[j] for j in chosen], masks=[np.isfinite(m) for m in moved])
        np.testing.assert_allclose(fused, expected, rtol=1e-5, equal_nan=True)
    assert fuse_maps([maps[0], None, None], noise, steps[0], displacements) is None  # one map


def test_maps_too_small_to_co_register_are_fused_as_they_are(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    with h5py.File(evaporation.path, "r") as f:
        frames = f["frames"][:20, :32, :32]
    path = tmp_path / "small.tif"
    tifffile.imwrite(path, frames)
    out = tmp_path / "out"
    argv = ["process", str(path), "--out", str(out), "--maps", "--wavelength-nm", "532"]
    argv += ["--fluid", "water", "--fps", str(evaporation.fps), "--radius", "0.06"]
    status, _, err = run_cli([*argv, *evaporation.label_args("RB1", "RF")], capsys)
    assert status == 0, err
    summary = json.loads((out / "summary.json").read_text())
    with h5py.File(out / "results.h5", "r") as f:
        assert min(f["maps/fused"].shape[1:]) < MIN_MAP_SIDE
        assert "displacement_px" not in f["maps/RB1"].attrs
        assert np.isfinite(f["maps/fused"][5]).any()
    assert all(p["displacement"] is None for p in summary["peaks"].values())
