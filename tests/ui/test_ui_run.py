"""A file opened in the window (issue 27): its whole run at once, before it plays; the frame
shown is a cursor on it; seeking keeps it; a range fit is ``process --frames A:B``'s rate."""

from __future__ import annotations

import threading
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PyQt6.QtCore import QMimeData, QObject, QPointF, Qt, QUrl
from PyQt6.QtGui import QDropEvent

from holoview.acquire.replay import DEFAULT_RATE_HZ
from holoview.cli import main
from holoview.engine.experiment import Experiment, LabelledPeak
from holoview.headless.run import process_file
from holoview.headless.settings import ProcessOptions
from holoview.live.replay_control import ReplayState
from holoview.processing.series.rate_fits import format_rate
from holoview.ui.background import LatestCall
from holoview.ui.main_window import MainWindow
from holoview.ui.open_files import recent_files
from holoview.ui.run_trends import maps_frame_text
from holoview.ui.trends_view import NO_TRENDS

from .holograms import FB1, N1, N2, RB1, WAVELENGTH_M

pytestmark = [
    pytest.mark.gui,
    pytest.mark.qt_log_ignore(r"This plugin does not support (propagateSizeHints|raise)\(\)"),
]

#: Frames of the recording, and its frame rate (frames/s).
FRAMES, FPS = 60, 20.0


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Evaporation at 60 um/min, 128 x 128, 60 frames at 20 frames/s, with its experiment."""
    path = tmp_path_factory.mktemp("run") / "evaporation.h5"
    argv = ["-q", "simulate", str(path), "--scenario", "evaporation", "--size", "128"]
    argv += ["--frames", str(FRAMES), "--fps", str(FPS), "--seed", "5"]
    assert main([*argv, "--evaporation-um-per-min", "60"]) == 0
    return path


def _window(qtbot, open_windows, tmp_path: Path) -> MainWindow:
    """A window that starts nothing (as ``holoview FILE`` opens it)."""
    window = MainWindow(source="sim", autostart=False, experiment_path=tmp_path / "exp.json")
    qtbot.addWidget(window)
    open_windows.append(window)
    window.show()
    return window


def _opened(qtbot, window: MainWindow) -> None:
    """Wait until the file is open and its whole run measured."""
    qtbot.waitUntil(lambda: not window.opening and window.session is not None, timeout=20000)
    qtbot.waitUntil(lambda: window.run_trends.series is not None, timeout=60000)


def _process_rate(path: Path, out: Path, frames: str | None = None) -> float:
    outcome = process_file(path, out, ProcessOptions(frames=frames, report=None))
    assert outcome.analysis.fit is not None
    return outcome.analysis.fit.rate


def test_a_file_opened_shows_its_whole_run_before_it_plays(
    qtbot, open_windows, tmp_path, recording
) -> None:
    window = _window(qtbot, open_windows, tmp_path)
    window.open_file(recording)
    _opened(qtbot, window)
    replay = window.session.replay
    state = replay.state()
    assert state.paused and state.index == 0  # nothing played
    assert "Using the experiment the recording carries" in window.notice.text
    curves = window.trends.curves
    assert {"RB1", "fused"} <= set(curves)
    assert len(curves["fused"].getData()[0]) == FRAMES
    run = window.run_trends.series
    assert run.fit is not None
    assert run.fit.rate == _process_rate(recording, tmp_path / "out")
    assert format_rate(run.fit.rate, run.fit.stderr) in window.trends.rate_label.text()
    assert window.trends.rate_label.text().startswith("whole run: ")  # the file's own clock
    window.trends.pca_box.setChecked(True)  # the run's PCA, as process reports it
    confidence = run.analysis.pca["confidence"]
    assert f"{confidence * 100:.2f} %" in window.trends.pca_label.text()
    window.redraw()
    assert window.trends.cursor_line.isVisible() and window.trends.cursor_line.value() == 0.0
    assert recent_files()[0] == recording
    window.recent_menu.aboutToShow.emit()
    assert [a.text() for a in window.recent_menu.actions()] == [recording.name]


def test_seeking_and_playing_keep_the_run_and_move_the_cursor(
    qtbot, open_windows, tmp_path, recording
) -> None:
    window = _window(qtbot, open_windows, tmp_path)
    window.open_file(recording)
    _opened(qtbot, window)
    times, fused = (np.array(a) for a in window.trends.curves["fused"].getData())
    for index in (30, 29, 0, 59):
        window.transport.seek(index)
        qtbot.waitUntil(
            lambda i=index: (
                window._last_result is not None and window._last_result.frame_index == i
            ),
            timeout=10000,
        )
        window.redraw()
        assert window.trends.cursor_line.value() == pytest.approx(index / FPS)
    # the cursor dragged asks the replay for the frame under it
    window.trends.cursorMoved.emit(12.2 / FPS)
    qtbot.waitUntil(lambda: window._last_result.frame_index == 12, timeout=10000)
    window.transport.set_speed(8.0)
    window.transport.toggle()  # play at 8x, looping
    ends: list[int] = []

    def looped() -> bool:
        index = window.session.replay.state().index
        if index > FRAMES - 10:
            ends.append(index)
        return bool(ends) and 0 <= index < 20

    qtbot.waitUntil(looped, timeout=20000)
    window.redraw()
    again, fused_again = (np.array(a) for a in window.trends.curves["fused"].getData())
    np.testing.assert_array_equal(again, times)
    np.testing.assert_array_equal(fused_again, fused)
    assert not window.trends.empty_hint.isVisibleTo(window.trends)


def test_a_range_chosen_on_the_plot_is_fitted_as_process_frames_a_b(
    qtbot, open_windows, tmp_path, recording
) -> None:
    window = _window(qtbot, open_windows, tmp_path)
    window.open_file(recording)
    _opened(qtbot, window)
    window.trends.choose_range(10 / FPS, 40 / FPS)
    qtbot.waitUntil(lambda: window.run_trends.range_series is not None, timeout=60000)
    part = window.run_trends.range_series
    assert part.request.frames == "10:41"
    assert part.fit.rate == _process_rate(recording, tmp_path / "out", frames="10:41")
    label = window.trends.range_label
    assert label.text().startswith("frames 10:41 (0.50-2.00 s): ")
    assert format_rate(part.fit.rate, part.fit.stderr) in label.text()
    assert "holoview process evaporation.h5 --frames 10:41" in label.toolTip()
    window.trends.range_button.click()  # put the range away
    assert not label.isVisibleTo(window.trends) and window.trends.chosen_range() is None


def test_labels_changed_measure_the_run_again(qtbot, open_windows, tmp_path, recording) -> None:
    window = _window(qtbot, open_windows, tmp_path)
    window.open_file(recording)
    _opened(qtbot, window)
    first = window.run_trends.series
    window.notice.button.click()  # back to the labels before: none
    assert window.experiment.peaks == ()
    assert window.run_trends.series is None and window.trends.empty_hint.text() == NO_TRENDS
    assert not window.trends.curves
    window.use_known_labels()  # the recording's again
    qtbot.waitUntil(lambda: window.run_trends.series is not None, timeout=60000)
    assert window.run_trends.series is not first
    assert window.run_trends.series.fit.rate == first.fit.rate


def test_a_file_dropped_on_the_window_opens_and_a_missing_one_is_said(
    qtbot, open_windows, tmp_path, hologram_file
) -> None:
    window = _window(qtbot, open_windows, tmp_path)
    mime = QMimeData()
    mime.setUrls([QUrl.fromLocalFile(str(hologram_file))])
    drop = QDropEvent(
        QPointF(10, 10),
        Qt.DropAction.CopyAction,
        mime,
        Qt.MouseButton.LeftButton,
        Qt.KeyboardModifier.NoModifier,
    )
    window.dropEvent(drop)
    qtbot.waitUntil(lambda: not window.opening and window.session is not None, timeout=20000)
    assert window.session.replay.path == hologram_file
    assert window.run_trends.active and window.run_trends.series is None  # no label yet
    assert window.trends.empty_hint.text() == NO_TRENDS
    missing = tmp_path / "gone.h5"
    window.open_file(missing)
    assert window.banner_text == f"{missing}: no such file or folder"
    assert recent_files() == [hologram_file]


def test_maps_behind_the_frame_shown_are_said() -> None:
    playing = ReplayState(135, 300, 6.75, paused=False, held=False, speed=8.0, loop=True)
    assert maps_frame_text(playing, 131) == "maps of frame 131 (4 behind)"
    assert maps_frame_text(playing, 134) == "maps of frame 134"
    assert maps_frame_text(replace(playing, index=2), 297) == "maps of frame 297 (5 behind)"
    paused = ReplayState(135, 300, 6.75, paused=True, held=False, speed=8.0, loop=True)
    assert maps_frame_text(paused, 131) == "maps of frame 131"
    assert maps_frame_text(playing, -1) == ""


def test_a_newer_measurement_replaces_the_one_under_way(qtbot) -> None:
    owner = QObject()
    call = LatestCall("holoview-test-call", "holoview-test-call", owner)
    started = threading.Event()
    given_up = threading.Event()

    def slow(progress, cancelled) -> str:
        progress(1, 100)
        started.set()
        while not cancelled():
            time.sleep(0.001)
        given_up.set()
        return "slow"

    call.start(slow)
    assert started.wait(10)
    qtbot.waitUntil(lambda: call.progress() == (1, 100), timeout=5000)
    with qtbot.waitSignal(call.done, timeout=10000) as blocker:
        call.start(lambda progress, cancelled: "newest")
    assert given_up.is_set()
    assert blocker.args == ["newest"]  # the slow one's outcome is never emitted
    assert not call.busy and not call.timer.isActive()
    started.clear()
    call.start(slow)
    assert started.wait(10)
    call.wait()  # the window closing: given up and joined
    assert not call.busy and not call.timer.isActive()


def test_a_tiff_s_rate_is_assumed_and_said_until_one_is_given(
    qtbot, open_windows, tmp_path, hologram_file
) -> None:
    peaks = (LabelledPeak("RB1", RB1), LabelledPeak("FB1", FB1))
    Experiment(wavelength_m=WAVELENGTH_M, n1=N1, n2=N2, peaks=peaks).save(tmp_path / "exp.json")
    window = _window(qtbot, open_windows, tmp_path)
    window.open_file(hologram_file)
    _opened(qtbot, window)
    assumed = window.run_trends.series
    assert assumed.request.fps_hz == DEFAULT_RATE_HZ
    assert window.trends.rate_label.text().startswith(
        f"whole run, {DEFAULT_RATE_HZ:g} frames/s, assumed: "
    )
    assert "holograms.tif carries no frame times" in window.trends.rate_label.toolTip()
    window.apply_setting("rate_hz", 10.0)  # the Source panel's rate
    qtbot.waitUntil(
        lambda: window.run_trends.series is not None and window.run_trends.series is not assumed,
        timeout=60000,
    )
    given = window.run_trends.series
    assert given.times[-1] == pytest.approx(15 / 10.0)
    assert window.trends.rate_label.text().startswith("whole run, 10 frames/s, given: ")
    assert given.fit.rate == pytest.approx(assumed.fit.rate * 10.0 / DEFAULT_RATE_HZ, rel=1e-9)
