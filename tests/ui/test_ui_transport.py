"""The replay transport bar in the window: shown for replays only; buttons, keys and slider
move the frame shown; a seek outside the file is a banner message."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PyQt6.QtCore import Qt

from holoview.engine.experiment import Experiment, LabelledPeak
from holoview.ui.main_window import MainWindow

from .holograms import FB1, N1, N2, RB1, WAVELENGTH_M

pytestmark = [
    pytest.mark.gui,
    pytest.mark.qt_log_ignore(r"This plugin does not support (propagateSizeHints|raise)\(\)"),
]


def _window(qtbot, open_windows, tmp_path: Path, source: str, peaks=()) -> MainWindow:
    path = tmp_path / "experiment.json"
    Experiment(wavelength_m=WAVELENGTH_M, n1=N1, n2=N2, radius=0.05, peaks=peaks).save(path)
    window = MainWindow(source=source, experiment_path=path)
    qtbot.addWidget(window)
    open_windows.append(window)
    window.show()
    qtbot.waitUntil(lambda: not window.opening, timeout=20000)
    return window


def _newest_index(window: MainWindow) -> int:
    newest = window.session.newest_frame() if window.session is not None else None
    return -1 if newest is None else newest[2].file_index


def _shows(qtbot, window: MainWindow, index: int) -> None:
    """Wait until frame ``index`` is the camera's newest and the bar says so."""
    qtbot.waitUntil(lambda: _newest_index(window) == index, timeout=5000)
    window.redraw()
    assert window.transport.slider.value() == index
    assert window.transport.position_label.text().startswith(f"frame {index} / 15 · ")


def test_the_bar_is_shown_for_a_replay_and_not_for_the_simulator(
    qtbot, open_windows, tmp_path, hologram_file
):
    window = _window(qtbot, open_windows, tmp_path, "sim")
    assert window.session is not None and window.session.replay is None
    assert not window.transport.isVisibleTo(window)
    assert not any(act.isEnabled() for act in window.transport.shortcuts)
    window.start_source(f"replay:{hologram_file}")
    qtbot.waitUntil(lambda: not window.opening, timeout=20000)
    assert window.transport.isVisibleTo(window)
    assert all(act.isEnabled() for act in window.transport.shortcuts)
    window.reset_layout()  # the default layout was saved with the bar hidden
    assert window.transport.isVisibleTo(window)
    window.stop_source()
    assert not window.transport.isVisibleTo(window)


def test_buttons_keys_and_slider_move_the_frame_shown(qtbot, open_windows, tmp_path, hologram_file):
    window = _window(qtbot, open_windows, tmp_path, f"replay:{hologram_file}")
    bar = window.transport
    qtbot.mouseClick(bar.play_button, Qt.MouseButton.LeftButton)  # pause
    assert window.session.replay.state().paused
    bar.slider.setValue(5)  # as a drag does
    _shows(qtbot, window, 5)
    # a TIFF has no timestamps: 30 frames/s
    assert bar.position_label.text() == "frame 5 / 15 · 0.167 s"
    qtbot.mouseClick(bar.forward_button, Qt.MouseButton.LeftButton)
    _shows(qtbot, window, 6)
    qtbot.mouseClick(bar.back_button, Qt.MouseButton.LeftButton)
    _shows(qtbot, window, 5)
    window.activateWindow()
    qtbot.keyClick(window, Qt.Key.Key_Left)
    _shows(qtbot, window, 4)
    qtbot.keyClick(window, Qt.Key.Key_Right, Qt.KeyboardModifier.ShiftModifier)
    _shows(qtbot, window, 14)
    qtbot.keyClick(window, Qt.Key.Key_Home)
    _shows(qtbot, window, 0)
    qtbot.keyClick(window, Qt.Key.Key_End)
    _shows(qtbot, window, 15)
    qtbot.keyClick(window, Qt.Key.Key_BracketLeft)
    assert bar.speed_box.currentText() == "0.5x"
    assert window.source_panel.editor("speed_factor").value() == pytest.approx(0.5)
    qtbot.keyClick(window, Qt.Key.Key_Space)  # play: held at the end, so from the start
    qtbot.waitUntil(lambda: 0 <= _newest_index(window) < 15, timeout=5000)
    assert not window.session.replay.state().paused


def test_maps_follow_a_jump_and_the_trends_keep_the_whole_run(
    qtbot, open_windows, tmp_path, hologram_file
):
    peaks = (LabelledPeak("RB1", RB1), LabelledPeak("FB1", FB1))
    window = _window(qtbot, open_windows, tmp_path, f"replay:{hologram_file}", peaks)
    assert window.experiment.reference == "relative"
    qtbot.waitUntil(lambda: window.run_trends.series is not None, timeout=30000)
    whole = window.trends.curves["RB1"].getData()[0]
    assert len(whole) == 16  # every frame of the file, before any was played twice
    window.transport.toggle()  # pause
    # frame 9 may have been played already (a loaded machine plays the file's first pass
    # while the run is measured): the frame sought is of a later segment than any before
    played = window.session.replay.state().segment
    window.transport.seek(9)
    qtbot.waitUntil(
        lambda: (
            (r := window._last_result) is not None and r.frame_index == 9 and r.segment > played
        ),
        timeout=10000,
    )
    sought = window._last_result
    assert sought.heights_m and not any(h.any() for h in sought.heights_m.values())
    for index in (10, 11):
        window.transport.step(1)
        qtbot.waitUntil(lambda i=index: window._last_result.frame_index == i, timeout=10000)
        assert window._last_result.segment == sought.segment
    assert any(h.any() for h in window._last_result.heights_m.values())  # 11 against 10
    window.redraw()
    # the jump changed nothing of the run; the cursor is at frame 11 (a TIFF: 30 frames/s)
    np.testing.assert_array_equal(window.trends.curves["RB1"].getData()[0], whole)
    assert window.trends.cursor_line.isVisible()
    assert window.trends.cursor_line.value() == pytest.approx(11 / 30)
    assert not window.trends.empty_hint.isVisibleTo(window.trends)
    window.transport.step(-1)
    qtbot.waitUntil(lambda: window._last_result.frame_index == 10, timeout=10000)
    assert window._last_result.segment == sought.segment + 1


def test_a_seek_outside_the_file_is_a_message_and_the_replay_goes_on(
    qtbot, open_windows, tmp_path, hologram_file
):
    window = _window(qtbot, open_windows, tmp_path, f"replay:{hologram_file}")
    window.transport.seek(99)
    assert window.banner_text == "frame 99 is outside holograms.tif: it has 16 frames, 0 to 15"
    assert window.session is not None and window.session.running
    assert window.transport.isVisibleTo(window)


def test_unticking_loop_holds_the_last_frame(qtbot, open_windows, tmp_path, hologram_file):
    window = _window(qtbot, open_windows, tmp_path, f"replay:{hologram_file}")
    bar = window.transport
    assert bar.loop_box.isChecked()  # replays loop in the window by default
    qtbot.mouseClick(bar.loop_box, Qt.MouseButton.LeftButton)
    assert not window.session.replay.state().loop
    bar.set_speed(float("inf"))
    qtbot.waitUntil(lambda: window.session.replay.state().held, timeout=5000)
    assert _newest_index(window) == 15 and window.session.running
    window.redraw()
    assert bar.play_button.toolTip() == "play (Space)"


def test_a_replayed_file_that_disappears_is_a_message_and_the_window_goes_on(
    qtbot, open_windows, tmp_path, hologram_file
):
    window = _window(qtbot, open_windows, tmp_path, f"replay:{hologram_file}")
    qtbot.waitUntil(lambda: _newest_index(window) >= 0, timeout=5000)
    hologram_file.unlink()
    qtbot.waitUntil(lambda: "disappeared" in window.banner_text, timeout=5000)
    assert window.banner_text.startswith(f"replay:{hologram_file} stopped: {hologram_file}: ")
    assert "the file disappeared while it was replayed (at frame " in window.banner_text
    assert not window.transport.isVisibleTo(window)
    window.start_source("sim")  # the window still works
    qtbot.waitUntil(lambda: not window.opening, timeout=20000)
    assert window.session is not None and window.session.running
