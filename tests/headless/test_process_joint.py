"""End to end: ``holoview process`` on recordings the old per-peak rule got wrong (issue 13).

The joint per-frame estimate (every peak's 2 pi ambiguity resolved by all of them, and
the reference-arm phase solved for) runs through the whole pipeline: probe, series,
joint estimate, summary and results.h5.
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from headless_sim import run_cli

from holoview.cli import main


def _simulate(path: Path, *args: str) -> None:
    assert main(["-q", "simulate", str(path), *args]) == 0


def _truth(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    with h5py.File(path, "r") as f:
        t = f["truth/time_s"][:]
        return t, f["truth/mean_height_m"][:], f["truth/reference_phase_rad"][:]


def test_reference_arm_vibration_leaves_the_fused_depth(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """15 nm rms of reference-arm jitter: the fused depth is free of it, and it is measured."""
    path = tmp_path / "vibration.h5"
    _simulate(
        path,
        "--scenario",
        "evaporation",
        "--size",
        "128",
        "--frames",
        "80",
        "--fps",
        "20",
        "--seed",
        "4",
        "--vibration-rms-nm",
        "15",
    )
    status, _, _ = run_cli(["-q", "process", str(path), "--out", str(tmp_path / "o")], capsys)
    assert status == 0
    _, height, reference = _truth(path)
    with h5py.File(tmp_path / "o" / "results.h5", "r") as f:
        vibration = f["trends/vibration_rad"][:]
        fused = f["trends/fused_height_m"][:]
        labels = [s.decode() for s in f["trends/label"][:]]
        heights = f["trends/mean_height_m"][:]
    correlation = np.corrcoef(vibration - vibration[0], reference - reference[0])[0, 1]
    assert correlation > 0.9
    truth = height - height[0]
    fused_error = np.std(fused - truth)
    fb1_error = np.nanstd(heights[:, labels.index("FB1")] - truth)  # FB1 has no reference arm
    assert fused_error < fb1_error
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["fused"]["joint"] and summary["fused"]["vibration_rms_rad"] > 0.1


def test_a_fast_injection_uses_the_peaks_that_alias_in_time(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """25 frames/s at 1.74 um/s: RB3 and FB2 step past pi a frame and are still used."""
    path = tmp_path / "injection.h5"
    _simulate(
        path,
        "--scenario",
        "injection",
        "--size",
        "256",
        "--frames",
        "80",
        "--fps",
        "25",
        "--seed",
        "2",
        "--injection-ul-per-s",
        "12.3",
        "--basin-area-cm2",
        "70.6",
    )
    status, _, _ = run_cli(["-q", "process", str(path), "--out", str(tmp_path / "o")], capsys)
    assert status == 0
    t, height, _ = _truth(path)
    rate = np.polyfit(t, height, 1)[0]
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["fused"]["rate_m_per_s"] == pytest.approx(rate, rel=0.003)
    fast = [k for k, p in summary["peaks"].items() if "aliased_in_time" in p["flags"]]
    assert "RB3" in fast
    for label, peak in summary["peaks"].items():
        assert peak["used_in_fused"], label
        assert peak["rate_m_per_s"] == pytest.approx(rate, rel=0.01), label
