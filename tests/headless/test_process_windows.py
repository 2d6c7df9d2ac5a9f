"""Windows on a wavy surface end to end (issue 23): ``peaks`` names the sidebands, ``process``
demodulates each peak with its own window and says which, ``--radius`` bound or a number."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import tifffile
from headless_sim import run_cli

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "processing"))
from wavy_scene import FPS, render, travelling_waves, true_peaks, wavy_setup

OPTICS = ["--pixel-pitch-um", "40", "--wavelength-nm", "532", "--fluid", "water"]


@pytest.fixture(scope="module")
def wavy_folder(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """Six frames of the wavy surface as a folder of TIFFs, and the true carriers."""
    setup = wavy_setup()
    frames, _ = render(setup, travelling_waves(1), 6, seed=3)
    folder = tmp_path_factory.mktemp("wavy") / "frames"
    folder.mkdir()
    for i, frame in enumerate(frames):
        tifffile.imwrite(folder / f"f{i:03d}.tif", frame)
    return folder, {p.label: p.carrier for p in true_peaks(setup)}


def _labels(carriers: dict, *names: str) -> list[str]:
    return [a for n in names for a in ("--label", f"{n}={carriers[n][0]},{carriers[n][1]}")]


def test_peaks_names_the_surface_sidebands(wavy_folder, capsys: pytest.CaptureFixture) -> None:
    folder, _ = wavy_folder
    status, out, _ = run_cli(["peaks", str(folder), *OPTICS, "--json"], capsys)
    assert status == 0
    detected = json.loads(out)["detected"]
    sidebands = [p for p in detected if p["kind"] == "surface"]
    assert len(sidebands) >= 8
    assert {p["sideband"]["of"] for p in sidebands} >= {"RB1", "RF", "RB2"}
    assert all(p["label"] is None and "surface" in p["flags"] for p in sidebands)
    assert any("sideband of RB1 at q = (" in p["sideband"]["text"] for p in sidebands)
    named = {p["label"] for p in detected if p["kind"] == "first order"}
    assert {"RB1", "RF", "FB1", "RB2"} <= named
    status, table, _ = run_cli(["peaks", str(folder), *OPTICS], capsys)
    assert status == 0 and "sideband of RB1 at q = (" in table


def test_each_peak_is_demodulated_with_its_own_window(
    wavy_folder, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    folder, carriers = wavy_folder
    argv = ["process", str(folder), *OPTICS, "--fps", str(FPS), "--maps"]
    argv += ["--reference", "absolute", *_labels(carriers, "RB1", "RF")]
    status, _, err = run_cli([*argv, "--out", str(tmp_path / "matched")], capsys)
    assert status == 0, err
    summary = json.loads((tmp_path / "matched" / "summary.json").read_text())
    assert summary["parameters"]["radius"] == "matched"
    windows = {label: p["window"] for label, p in summary["peaks"].items()}
    assert {"RB1", "RF", "FB1", "RB2"} <= set(windows)
    for label in ("RB1", "RF", "RB2"):
        w = windows[label]
        assert w["rule"] == "matched" and "matched" in w["reason"]
        # the strongest waves' sidebands (0.015 cycles/px) do not shrink the window
        assert 0.02 < w["radius_cpp"] <= w["bound_cpp"] + 1e-12
        assert w["bound_cpp"] > 0.045
    with h5py.File(tmp_path / "matched" / "results.h5", "r") as results:
        for label, w in windows.items():
            attrs = results["maps"][label].attrs
            assert attrs["radius_cpp"] == pytest.approx(w["radius_cpp"])
            assert attrs["window_rule"] == w["rule"]
        assert list(results["peaks/radius_cpp"][:]) == pytest.approx(
            [
                summary["peaks"][str(n, "utf-8") if isinstance(n, bytes) else n]["window"][
                    "radius_cpp"
                ]
                for n in results["peaks/label"][:]
            ]
        )
    # in two processes: the windows the parent matched, the same maps to the last bit
    status, _, err = run_cli([*argv, "--jobs", "2", "--out", str(tmp_path / "two")], capsys)
    assert status == 0, err
    two = json.loads((tmp_path / "two" / "summary.json").read_text())
    assert two["timing"]["workers"] == "2 processes"
    assert {label: p["window"] for label, p in two["peaks"].items()} == windows
    with (
        h5py.File(tmp_path / "matched" / "results.h5", "r") as one,
        h5py.File(tmp_path / "two" / "results.h5", "r") as other,
    ):
        for name in (*windows, "fused"):
            np.testing.assert_array_equal(one["maps"][name][:], other["maps"][name][:])
    # --radius bound: today's widest windows; a number: that one, not refused
    status, _, err = run_cli([*argv, "--radius", "bound", "--out", str(tmp_path / "b")], capsys)
    assert status == 0, err
    bound = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert bound["parameters"]["radius"] == "bound"
    for label, w in windows.items():
        got = bound["peaks"][label]["window"]
        assert got["rule"] == "bound" and got["radius_cpp"] == pytest.approx(w["bound_cpp"])
    status, _, err = run_cli([*argv, "--radius", "0.045", "--out", str(tmp_path / "g")], capsys)
    assert status == 0, err
    given = json.loads((tmp_path / "g" / "summary.json").read_text())
    assert {p["window"]["radius_cpp"] for p in given["peaks"].values()} == {0.045}
    assert {p["window"]["rule"] for p in given["peaks"].values()} == {"given"}
    assert np.isfinite(given["fused"]["rate_m_per_s"] or 0.0)
