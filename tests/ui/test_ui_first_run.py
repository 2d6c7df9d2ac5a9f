"""The first minute: what to do next is said, labels a source knows are offered (a
recording's are applied, with the way back)."""

from __future__ import annotations

from pathlib import Path

import pytest

from holoview.cli import main
from holoview.engine.experiment import Experiment
from holoview.ui.main_window import MainWindow

pytestmark = [
    pytest.mark.gui,
    pytest.mark.qt_log_ignore(r"This plugin does not support (propagateSizeHints|raise)\(\)"),
]


def _open(qtbot, tmp_path: Path, source: str, **kwargs) -> MainWindow:
    window = MainWindow(source=source, experiment_path=tmp_path / "experiment.json", **kwargs)
    qtbot.addWidget(window)
    window.show()
    qtbot.waitUntil(lambda: not window.opening and window.session is not None, timeout=20000)
    return window


def test_the_simulators_labels_are_offered_then_used_in_one_click(qtbot, tmp_path: Path) -> None:
    options = {"shape": (256, 256), "frame_rate_hz": 30.0, "seed": 1}
    window = _open(qtbot, tmp_path, "sim", source_options=options)
    try:
        spectrum = window.spectrum
        assert spectrum.first_run.isVisible() and spectrum.use_suggestions.isVisible()
        assert set(spectrum.suggestions) == {"RF", "RB1", "FB1"}  # drawn, not yet labels
        assert "simulator" in spectrum.first_step.text()
        assert window.surface.empty_hint.isVisible() and window.trends.empty_hint.isVisible()
        assert not window.experiment.peaks
        spectrum.use_suggestions.click()
        assert {p.label for p in window.experiment.peaks} == {"RF", "RB1", "FB1"}
        named = {"RF", "RB1", "FB1", "RB2"}
        qtbot.waitUntil(lambda: named <= set(spectrum.labelled), timeout=15000)
        qtbot.waitUntil(lambda: "fused" in window.surface.names, timeout=15000)
        assert not spectrum.first_run.isVisible() and not spectrum.suggestions
        assert not window.surface.empty_hint.isVisible()
        qtbot.waitUntil(lambda: not window.trends.empty_hint.isVisible(), timeout=15000)
        window.clear_label("RF")  # labels left: no offer comes back
        assert not spectrum.suggestions
    finally:
        window.close()


def test_a_recordings_experiment_is_applied_and_one_click_goes_back(qtbot, tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    argv = ["-q", "simulate", str(path), "--size", "128", "--frames", "8", "--seed", "3"]
    assert main(argv) == 0
    window = _open(qtbot, tmp_path, f"replay:{path}")
    try:
        stored = window.session.known_experiment()[0]
        # applied as holoview process applies it, and said
        assert window.experiment.peaks == stored.peaks
        assert "Using the experiment the recording carries" in window.notice.text
        assert "RB1" in window.notice.text
        assert not window.spectrum.suggestions
        window.notice.button.click()  # back to the labels before: none
        assert window.experiment.peaks == ()
        assert window.notice.text == ""
        # offered again once the spectrum shows no label: the frame shown again comes
        # back without them (a result drawn before the click still holds the labels)
        qtbot.waitUntil(lambda: "run.h5" in window.spectrum.first_step.text(), timeout=15000)
        assert set(window.spectrum.suggestions) == {"RF", "RB1", "FB1"}
        window.use_known_labels()
        assert window.experiment.peaks == stored.peaks
        assert Experiment.load(tmp_path / "experiment.json").peaks == stored.peaks
    finally:
        window.close()


def test_without_known_labels_the_first_step_is_said(qtbot, tmp_path: Path, hologram_file) -> None:
    Experiment().save(tmp_path / "experiment.json")
    window = _open(qtbot, tmp_path, f"replay:{hologram_file}")
    try:
        assert window.spectrum.first_run.isVisible()
        assert not window.spectrum.use_suggestions.isVisible()
        assert "click a bright peak" in window.spectrum.first_step.text()
        window.use_known_labels()
        assert "suggests no labels" in window.banner_text
    finally:
        window.close()
