"""The report's drawing helpers: ticks that cover the range and read apart, a readable PNG."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from headless_sim import Simulated, run_cli

from holoview.headless.plotting import nice_ticks, tick_labels
from holoview.headless.report import WIDTH


@pytest.mark.parametrize(
    ("low", "high"),
    [(-9944.3, -9941.8), (0.0, 9.7), (-0.5, 0.5), (-61.0, 12.0), (1e-3, 2.5e-3), (3e-9, 7e-9)],
)
def test_ticks_lie_in_the_range_and_their_labels_differ(low: float, high: float) -> None:
    ticks = nice_ticks(low, high, count=4)
    assert 2 <= len(ticks) <= 9
    assert all(low - 1e-9 * abs(high - low) <= t <= high + 1e-9 * abs(high - low) for t in ticks)
    steps = np.diff(ticks)
    np.testing.assert_allclose(steps, steps[0], rtol=1e-6)
    labels = tick_labels(ticks)
    assert len(set(labels)) == len(labels)
    np.testing.assert_allclose([float(s) for s in labels], ticks, rtol=1e-2, atol=1e-12)


def test_report_is_a_readable_png(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "r"
    argv = ["process", str(evaporation.path), "--out", str(out), "--frames", ":30"]
    status, _, _ = run_cli([*argv, *evaporation.label_args("RB1", "FB1")], capsys)
    assert status == 0
    image = cv2.imread(str(out / "report.png"))
    assert image is not None and image.shape[1] == WIDTH and image.shape[0] > 800
    # the drawing is not blank: the spectrum, curves and maps put colour on the page
    assert np.mean(image < 250) > 0.1
    assert json.loads((out / "summary.json").read_text())["frames"]["processed"] == 30
