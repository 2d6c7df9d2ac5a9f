"""Experiment files and stored experiments a careless or hostile user hands over.

JSON nested 100 000 deep (Python's parser raises RecursionError), a radius of 5000
digits (Python refuses to convert such an integer), a FIFO named as the file (reading
it waits for a writer): each is one line and exit status 2 in ``process``, ``peaks``,
``record`` and ``live`` (the window names a file it cannot load in its banner). A
recording carrying such an experiment is replayed by a live window that says why and
stays usable (``process`` and ``peaks``: ``test_faults_hdf5_layout``).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py
import numpy as np
import pytest
from faults_helpers import one_line_error, run_holoview, run_main

from holoview.ui.main_window import MainWindow

DEEP = "[" * 100_000 + "]" * 100_000
BIG_RADIUS = '{"format": "holoview-experiment", "version": 2, "radius": ' + "7" * 5000 + "}"
BIG_CARRIER = (
    '{"format": "holoview-experiment", "version": 2, "peaks": '
    '[{"label": "RB1", "carrier": [0.1, ' + "3" * 4000 + "]}]}"
)

FILES = {
    "nested-100000": (DEEP, "nested too deeply"),
    "radius-5000-digits": (BIG_RADIUS, "radius must be finite"),
    "carrier-4000-digits": (BIG_CARRIER, "is not finite"),
}


def commands(path: Path, tmp_path: Path) -> dict[str, list[str]]:
    return {
        "process": ["-q", "process", str(path), "--out", str(tmp_path / "o")],
        "peaks": ["-q", "peaks", str(path)],
        "record": ["-q", "record", str(tmp_path / "r.h5"), "--frames", "2"],
    }


@pytest.mark.parametrize("command", ["process", "peaks", "record"])
@pytest.mark.parametrize("name", list(FILES))
def test_hostile_experiment_files_are_one_line(
    sim_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture, name: str, command: str
) -> None:
    text, reason = FILES[name]
    experiment = tmp_path / f"{name}.json"
    experiment.write_text(text)
    argv = commands(sim_recording, tmp_path)[command]
    done = run_main([*argv, "--experiment", str(experiment)], capsys)
    one_line_error(done, 2, f"experiment file {experiment}", reason)
    assert not (tmp_path / "o").exists() and not (tmp_path / "r.h5").exists()


@pytest.mark.parametrize("command", ["process", "peaks", "record", "live"])
def test_an_experiment_fifo_is_refused_without_waiting(
    sim_recording: Path, tmp_path: Path, command: str
) -> None:
    fifo = tmp_path / "experiment.json"
    os.mkfifo(fifo)
    argv = commands(sim_recording, tmp_path).get(command, ["-q", "live"])
    done = run_holoview(*argv, "--experiment", str(fifo), timeout=60)  # it hung before
    one_line_error(done, 2, f"experiment file {fifo}", "a FIFO (named pipe), not a regular file")


def test_the_live_window_names_a_hostile_experiment_file_and_runs(
    sim_recording: Path, tmp_path: Path
) -> None:
    """The README: a file that cannot be loaded is named in the banner; nothing else changes."""
    experiment = tmp_path / "deep.json"
    experiment.write_text(DEEP)
    done = run_holoview(
        "live",
        "--source",
        f"replay:{sim_recording}",
        "--experiment",
        str(experiment),
        "--quit-after",
        "2",
        timeout=90,
    )
    assert done.status == 0, done.err
    assert "Traceback" not in done.err
    assert "experiment settings ignored" in done.err and "nested too deeply" in done.err


def _store_experiment(path: Path, raw: bytes | None) -> None:
    """Replace the recording's stored experiment with ``raw`` (None: a damaged layout)."""
    with h5py.File(path, "a") as f:
        group = f["experiment"]
        del group["json"], group["changes"]
        if raw is None:
            group["json"] = json.dumps({"format": "holoview-experiment", "version": 2})
            group["changes"] = np.array([0.0, 0.0, 10.0])
            return
        text = np.frombuffer(raw, np.uint8)
        group["json"] = text
        group["changes"] = np.array([[0, 0, text.size]], dtype=np.int64)


STORED = {
    "nested-100000": (DEEP.encode(), "nested too deeply"),
    "radius-5000-digits": (BIG_RADIUS.encode(), "radius must be finite"),
    "damaged-layout": (None, "/experiment/json is object of shape ()"),
}


@pytest.mark.gui
@pytest.mark.qt_log_ignore(r"This plugin does not support (propagateSizeHints|raise)\(\)")
@pytest.mark.parametrize("name", list(STORED))
def test_the_live_window_replays_a_recording_whose_experiment_is_unreadable(
    qtbot, sim_recording: Path, tmp_path: Path, name: str
) -> None:
    """It stuck at "opening replay:..." with Start disabled; now it says why and plays."""
    raw, reason = STORED[name]
    path = tmp_path / "run.h5"
    path.write_bytes(sim_recording.read_bytes())
    _store_experiment(path, raw)
    window = MainWindow(source=f"replay:{path}", experiment_path=tmp_path / "experiment.json")
    qtbot.addWidget(window)
    window.show()
    try:
        qtbot.waitUntil(lambda: not window.opening and window.session is not None, timeout=20000)
        qtbot.waitUntil(lambda: reason in window.banner_text, timeout=10000)
        assert "no labels to suggest" in window.banner_text
        panel = window.source_panel
        assert panel.start_button.isEnabled() and panel.start_button.text() == "Stop"
        assert not panel.state_label.text().startswith("opening")
        qtbot.waitUntil(lambda: window.session.latest() is not None, timeout=20000)
        panel.start_button.click()  # stop: the window stays usable
        qtbot.waitUntil(lambda: window.session is None, timeout=10000)
        assert panel.start_button.text() == "Start" and panel.start_button.isEnabled()
    finally:
        window.close()
