"""The headless run as a library call: process_file, and what an interruption keeps."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import h5py
import pytest
from headless_sim import Simulated

from holoview.headless.run import process_file
from holoview.headless.settings import PeakChoice, ProcessOptions, ProcessSettings


def test_an_interruption_keeps_the_results_of_the_frames_done(
    evaporation: Simulated, tmp_path: Path
) -> None:
    def stop_after_25(done: int, total: int) -> None:
        assert total == evaporation.frames
        if done == 25:
            raise KeyboardInterrupt

    out = tmp_path / "partial"
    options = ProcessOptions(
        choice=PeakChoice(labels={k: evaporation.carriers[k] for k in ("RB1", "FB1")}),
        settings=ProcessSettings(maps=True),
    )
    outcome = process_file(evaporation.path, out, options, progress=stop_after_25)
    assert outcome.data.interrupted
    assert len(outcome.data.frames) == 25
    summary = json.loads((out / "summary.json").read_text())
    assert summary["input"]["interrupted"] is True
    assert summary["input"]["frames"] == [0, 25]
    assert summary["fused"]["rate_m_per_s"] == pytest.approx(evaporation.rate, rel=0.02)
    with open(out / "trends.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 25 * (len(summary["peaks"]) + 1)
    with h5py.File(out / "results.h5", "r") as f:
        assert f["maps/RB1"].shape[0] == 25
        assert f["maps/fused"].shape[0] == 25
