"""The Waves panel in the window: a full-speed replay of simulated travelling waves fills it
from every frame, its fit is the truth's, a click on the field sets the centre; each bad input
is one line in the panel."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest
from PyQt6.QtCore import QPoint, QPointF, Qt

from holoview.acquire.recording_reader import RecordingReader
from holoview.engine.experiment import Experiment
from holoview.live.wave_window import LiveWaves, WaveHistory, WaveSettings, analyse_window
from holoview.processing.waves.fit_text import with_error
from holoview.ui.main_window import MainWindow
from holoview.ui.waves_view import WavesView, rate_text

pytestmark = [
    pytest.mark.gui,
    pytest.mark.qt_log_ignore(r"This plugin does not support (propagateSizeHints|raise)\(\)"),
]

#: Frames of the ``travelling_waves`` recording (tests/conftest.py).
FRAMES = 160


def _window(qtbot, open_windows, tmp_path: Path, recording: Path) -> MainWindow:
    with RecordingReader(recording) as reader:
        experiment = Experiment.from_json(reader.experiments()[-1][1])
        assert len(reader) == FRAMES
    path = tmp_path / "experiment.json"
    experiment.save(path)
    window = MainWindow(
        source=f"replay:{recording}",
        experiment_path=path,
        source_options={"loop": False, "speed": "fast"},
    )
    qtbot.addWidget(window)
    open_windows.append(window)
    window.show()
    qtbot.waitUntil(lambda: not window.opening, timeout=60000)
    return window


def _click_field(qtbot, view: WavesView, x_m: float, y_m: float) -> None:
    """Click the field view at map coordinates (m)."""
    target = view.field.getViewBox().mapViewToScene(QPointF(x_m * 1e3, y_m * 1e3))  # mm
    point = view.graphics.mapFromScene(target)
    qtbot.mouseClick(view.graphics.viewport(), Qt.MouseButton.LeftButton, pos=QPoint(point))


def test_a_full_speed_replay_fills_the_panel_and_fits_the_truth(
    qtbot, open_windows, tmp_path, travelling_waves
) -> None:
    window = _window(qtbot, open_windows, tmp_path, travelling_waves)
    session = window.session
    assert session is not None and session.replay is not None
    assert not window.waves_shown  # a tab behind Trends: no worker
    assert session.waves_worker is None
    window.show_waves()
    qtbot.waitUntil(lambda: session.waves_worker is not None, timeout=10000)
    assert window.waves_shown
    worker = session.waves_worker
    view = window.waves
    qtbot.waitUntil(lambda: session.replay.state().held, timeout=60000)  # the first pass
    qtbot.waitUntil(lambda: view.map_box.findText("RB1") >= 0, timeout=30000)  # offered
    view.length_box.setCurrentIndex(view.length_box.findData(128))
    view.choose_map("RB1")
    qtbot.waitUntil(
        lambda: (
            worker.settings.label == "RB1"
            and worker.history.length == 128
            and worker.backlog() == 0
        ),
        timeout=30000,
    )
    pushed = worker.history.pushed  # held: no frame comes until play
    # the second pass (from the first frame again: a new record, every frame); its frames
    # are those of the file, not the first one's (the HDF5 refresh at the first pass's end)
    session.replay.play()
    qtbot.waitUntil(lambda: worker.history.pushed >= pushed + FRAMES, timeout=60000)
    # an analysis begun after the last map: the one under way may hold an older window
    done = session.waves()
    qtbot.waitUntil(
        lambda: (w := session.waves()) is not None and w.seq >= (done.seq if done else 0) + 2,
        timeout=30000,
    )
    waves = session.waves()
    assert waves is not None and waves.label == "RB1" and waves.frames == 128
    assert waves.stride == 1 and waves.gaps == 0 and worker.status().dropped == 0
    fit = waves.fit
    assert fit is not None, waves.problems
    with h5py.File(travelling_waves, "r") as f:
        truth = dict(f["truth/waves"].attrs)
    sigma, depth = truth["sigma_n_per_m"], truth["depth_m"]  # 5 % / 10 %, or 3 errors
    assert abs(fit.surface_tension - sigma) < max(0.05 * sigma, 3 * fit.surface_tension_stderr)
    assert abs(fit.depth - depth) < max(0.10 * depth, 3 * fit.depth_stderr)
    qtbot.waitUntil(lambda: view._waves is session.waves(), timeout=10000)  # drawn
    text = view.fit_label.text()
    shown = view._waves.fit
    sigma = with_error(shown.surface_tension * 1e3, shown.surface_tension_stderr * 1e3)
    assert text.startswith(f"σ = {sigma} mN/m") and "d = " in text
    assert "RB1: 128 maps at 250 maps/s; every camera frame; f up to 125 Hz" in (
        view.rate_label.text()
    )
    assert view.omega_k_image.image is not None and view.fit_curve.getData()[0] is not None
    # wavenumbers drawn in rad/m, the unit of the fit's messages and of --k-range
    k_cut = view._waves.spectrum.k_cut
    assert [line.value() for line in view.cut_lines] == pytest.approx([-k_cut, k_cut])
    assert f"k cut-off {k_cut:.0f} rad/m" in view.rate_label.text()
    assert not view.message_label.isVisibleTo(view)

    _click_field(qtbot, view, 0.02, 0.02)  # the centre of the 41 mm field
    qtbot.waitUntil(lambda: (w := session.waves()) is not None and w.mf is not None, timeout=30000)
    centre = session.waves().centre
    assert centre == pytest.approx((0.02, 0.02), abs=1e-3)
    title = f"(m, f) at ({centre[0] * 1e3:.3g}, {centre[1] * 1e3:.3g}) mm"
    qtbot.waitUntil(lambda: view.mf.titleLabel.text == title, timeout=10000)

    view.set_centre((0.2, 0.2))  # 20 cm: off the field
    qtbot.waitUntil(lambda: "outside the maps" in view.message_label.text(), timeout=30000)
    assert view.message_label.isVisibleTo(view) and "Traceback" not in view.message_label.text()
    assert session.waves().fit is not None  # the rest goes on


def _waves(maps: list[np.ndarray], pixel_size=(5e-4, 5e-4)) -> LiveWaves:
    history = WaveHistory(len(maps))
    history.label = "RB1"
    history.pixel_size = pixel_size
    for i, frame in enumerate(maps):
        history.push(frame, i / 500.0, i)
    window = history.snapshot()
    assert window is not None
    return analyse_window(window, WaveSettings(label="RB1", length=64, segment=32))


@pytest.mark.parametrize(
    ("case", "line"),
    [
        ("no pixel size", "no omega-k spectrum: the pixel size is not known"),
        ("too few", "no omega-k spectrum yet: 20 maps without a gap, a segment needs 32"),
        ("all NaN", "no omega-k spectrum: the RB1 maps are all NaN (untrusted)"),
    ],
)
def test_each_bad_input_is_one_line_in_the_panel(qtbot, case: str, line: str) -> None:
    view = WavesView()
    qtbot.addWidget(view)
    rng = np.random.default_rng(0)
    maps = [rng.normal(0, 1e-9, (32, 32)).astype(np.float32) for _ in range(40)]
    if case == "no pixel size":
        waves = _waves(maps, pixel_size=None)
    elif case == "too few":
        waves = _waves(maps[:20])
    else:
        waves = _waves([np.full((32, 32), np.nan, np.float32)] * 40)
    view.set_waves(waves)
    assert view.message_label.text().startswith(line) and "\n" not in view.message_label.text()
    assert view.message_label.isVisibleTo(view)
    assert view.fit_label.text() == "σ, d, U: no fit"  # no number without its error
    assert view.omega_k_image.image is None


def test_a_map_rate_below_the_camera_says_where_f_is_cut() -> None:
    waves = LiveWaves(
        seq=1,
        label="fused",
        frames=100,
        rate=30.0,
        camera_rate=60.0,
        stride=2,
        gaps=1,
        latest=None,
        pixel_size=None,
        map_seconds=0.025,
    )
    text = rate_text(waves)
    assert "1 camera frame in 2 of 60 frames/s" in text
    assert "(a map takes 25 ms, a frame comes every 16.7 ms)" in text
    assert "f is cut at 15 Hz, half the map rate (not the camera's)" in text
    assert "1 gap (lost frames) left open" in text
    waiting = rate_text(replace(waves, map_cpu_seconds=0.007))  # the processor was busy
    assert (
        "(a map takes 25 ms, 7 ms of it computing and the rest waiting for the processor, "
        "a frame comes every 16.7 ms)"
    ) in waiting
    assert rate_text(replace(waves, map_cpu_seconds=0.02)) == text  # mostly computing


def test_a_shown_panel_closed_with_a_paint_pending_goes_cleanly(qtbot) -> None:
    """Deleting a shown pyqtgraph view with a paint pending crashed pytest once; closing the
    panel takes its plots down first, and whatever comes after draws nothing."""
    view = WavesView()
    qtbot.addWidget(view)
    view.resize(900, 360)
    view.show()
    qtbot.waitExposed(view)
    rng = np.random.default_rng(1)
    view.set_waves(_waves([rng.normal(0, 1e-9, (32, 32)).astype(np.float32) for _ in range(64)]))
    assert view.omega_k_image.image is not None
    view.set_centre((0.008, 0.008))
    view.graphics.viewport().update()  # a paint pending
    view.close()
    assert view.released and not view.graphics.scene().items()
    view.set_waves(_waves([rng.normal(0, 1e-9, (32, 32)).astype(np.float32) for _ in range(64)]))
    view.direction.setValue(45)
    view.set_centre(None)  # still a setting, drawn nowhere
    assert view.settings().centre is None
    view.release()  # again: nothing
    view.deleteLater()
    qtbot.wait(50)


def test_closing_the_window_stops_the_waves_worker_then_releases_the_panel(
    qtbot, open_windows, tmp_path, travelling_waves
) -> None:
    window = _window(qtbot, open_windows, tmp_path, travelling_waves)
    window.show_waves()
    qtbot.waitUntil(lambda: window.session is not None and window.session.waves_worker is not None)
    worker = window.session.waves_worker
    window.close()
    assert not worker.running and window.session is None and not window.timer.isActive()
    assert window.waves.released


def test_a_value_is_shown_to_the_decimal_place_of_its_error() -> None:
    assert with_error(76.76, 3.4) == "76.8 ± 3.4"
    assert with_error(0.8964, 0.076) == "0.896 ± 0.076"
    assert with_error(1234.5, 120.0) == "1234 ± 120"
    assert with_error(20.0, 0.0) == "20 ± 0"


def test_the_segments_are_counted_in_words() -> None:
    rng = np.random.default_rng(2)
    maps = [rng.normal(0, 1e-9, (32, 32)).astype(np.float32) for _ in range(64)]
    assert "; 3 segments of 32 maps" in rate_text(_waves(maps))  # hop 16 in 64
    assert rate_text(_waves(maps[:32])).endswith("; 1 segment of 32 maps")
