"""The main window: docks an operator can rearrange, a redraw timer, menus, shortcuts.

The window owns no processing. A :class:`~holoview.live.session.LiveSession` runs the
camera thread, the recorder and the demodulation worker. A QTimer (at most
:data:`REDRAW_HZ`) draws the camera's newest frame, so the hologram moves at the
display's rate whatever rate the maps come at; a maps result is drawn when it comes
(the maps worker wakes the window, at most once a result), so the window never
receives one signal per camera frame. Operator actions go back to the session as
commands. Problems (a camera gone, a broken file, a click with no peak) are shown
in a banner and the status bar; the rest keeps running.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from PyQt6.QtCore import QByteArray, QRect, Qt, QTimer, pyqtSignal
from PyQt6.QtGui import QAction, QCloseEvent, QKeySequence
from PyQt6.QtWidgets import (
    QDockWidget,
    QLabel,
    QMainWindow,
    QMenu,
    QMenuBar,
    QToolBar,
    QWidget,
)

from holoview import __version__
from holoview.engine.experiment import Experiment, default_experiment_path
from holoview.live.maps_pipeline import LiveResult
from holoview.live.session import LiveSession
from holoview.ui.background import BackgroundCall
from holoview.ui.exports import WindowExports
from holoview.ui.hologram_view import HologramView
from holoview.ui.notice_bar import NoticeBar
from holoview.ui.open_files import FileOpening, Opened
from holoview.ui.recording_panel import RecordingPanel
from holoview.ui.run_trends import RunTrends, maps_frame_text
from holoview.ui.settings import ui_settings
from holoview.ui.source_panel import SourcePanel
from holoview.ui.spectrum_view import SpectrumView
from holoview.ui.status_bar import LiveFigures, LiveStatusBar, RateMeter
from holoview.ui.surface_view import SurfaceView
from holoview.ui.transport_bar import TransportBar
from holoview.ui.trends_view import TrendsView
from holoview.ui.window_experiment import ExperimentActions
from holoview.ui.window_layout import (
    FRAME_ALLOWANCE,
    arrange_docks,
    available_area,
    fitted,
    initial_size,
    layout_for,
)
from holoview.ui.window_source import SourceActions
from holoview.ui.window_waves import WavesActions

logger = logging.getLogger(__name__)

#: Highest redraw rate of the display timer, Hz.
REDRAW_HZ = 30.0
#: How long a banner message stays, seconds.
BANNER_S = 8.0


class MainWindow(
    WavesActions, SourceActions, FileOpening, ExperimentActions, WindowExports, QMainWindow
):
    """holoview's live window.

    Parameters
    ----------
    source : str
        Source specification to offer first (``sim``, ``aravis:ID``, ``v4l2:N``,
        ``replay:PATH``).
    autostart : bool
        Start the source at once.
    experiment_path : Path, optional
        The experiment settings file (default: :func:`default_experiment_path`).
    source_options : dict, optional
        Passed to the constructor of ``source`` (e.g. the simulator's frame shape and
        rate) whenever that source is started; other sources get none.
    optics : dict, optional
        ``wavelength_m``, ``pixel_pitch_m``, ``n1``, ``n2`` over the experiment's (the
        command line's); they also win over a source's own optics.
    """

    #: Emitted on the maps thread when a result is ready (drawn on the GUI thread).
    mapsReady = pyqtSignal()

    def __init__(
        self,
        source: str = "sim",
        autostart: bool = True,
        experiment_path: Path | None = None,
        source_options: dict[str, Any] | None = None,
        optics: dict[str, float] | None = None,
    ) -> None:
        super().__init__()
        self.setObjectName("holoview-main")
        self.setWindowTitle(f"holoview {__version__}")
        self.session: LiveSession | None = None
        self.source_options = dict(source_options or {})
        self._optioned_source = source
        self._last_seq = -1
        self._camera_seq = -1
        self._trend_seq = -1
        self._last_result: LiveResult | None = None
        #: The newest result whose maps are drawn (a restart's reference frame is not).
        self._maps_result: LiveResult | None = None
        self._drawn: LiveResult | None = None
        self.display_rate = RateMeter()
        self.last_latency_s: float | None = None
        self._banner_until = 0.0
        self._contradiction: str | None = None
        self._known: tuple[Experiment, str] | None = None
        self.experiment_path = experiment_path or default_experiment_path()
        self.experiment = Experiment()
        self.optics = dict(optics or {})
        start_problem = self._load_experiment_at_start()

        self.hologram = HologramView()
        self.spectrum = SpectrumView()
        self.surface = SurfaceView()
        self.trends = TrendsView()
        self.source_panel = SourcePanel()
        self.recording_panel = RecordingPanel(default_dir=Path.cwd())
        self.status = LiveStatusBar()
        self.setStatusBar(self.status)
        self.banner = QLabel()
        self.banner.setStyleSheet(
            "background: #fff3cd; color: #664d03; padding: 4px; font-weight: bold;"
        )
        self.banner.setWordWrap(True)
        self.banner_bar = QToolBar("Messages")
        self.banner_bar.setObjectName("messages")
        self.banner_bar.addWidget(self.banner)
        self.banner_bar.setVisible(False)
        self.addToolBar(Qt.ToolBarArea.TopToolBarArea, self.banner_bar)
        self.addToolBarBreak(Qt.ToolBarArea.TopToolBarArea)
        self.notice = NoticeBar(self)
        self.addToolBar(Qt.ToolBarArea.TopToolBarArea, self.notice)
        self._previous_experiment: Experiment | None = None
        self.run_trends = RunTrends(self.trends, self)
        self.setAcceptDrops(True)
        self.transport = TransportBar(self)
        self.addToolBar(Qt.ToolBarArea.BottomToolBarArea, self.transport)

        self.docks: dict[str, QDockWidget] = {}
        self.setDockNestingEnabled(True)
        central = QWidget()
        central.setMaximumSize(0, 0)
        self.setCentralWidget(central)
        self._add_dock("Source", self.source_panel)
        self._add_dock("Recording", self.recording_panel)
        self._add_dock("Hologram", self.hologram)
        self._add_dock("Spectrum", self.spectrum)
        self._add_dock("Surface", self.surface)
        self._add_dock("Trends", self.trends)
        available = available_area(self).size()
        self.resize(initial_size(available))
        self.dock_layout = layout_for(available)
        arrange_docks(self, self.docks, self.dock_layout)
        self.docks["Waves"] = self._add_waves_dock()  # a tab beside Trends once shown
        self._default_state = self.saveState()
        self._make_actions()
        self._connect()
        self.surface.set_reference(self.experiment.reference)
        self.spectrum.set_model(
            {p.label: (p.fx, p.fy) for p in self.experiment.peaks}, {}, self.experiment.fixed_radius
        )
        self._restore_layout()

        self.timer = QTimer(self)
        self.timer.setObjectName("holoview-redraw")
        self.timer.setInterval(int(1000 / REDRAW_HZ))
        self.timer.timeout.connect(self.redraw)
        self.mapsReady.connect(self.draw_maps)
        self.opener = BackgroundCall("holoview-open", "holoview-open", self)
        self.opener.done.connect(self._opened)
        self._opening_spec = ""
        self.discovery = BackgroundCall("holoview-discover", "holoview-discovery", self, 50)
        self.discovery.done.connect(self._discovery_done)
        self.source_panel.set_sources(["sim"], current=source)
        if start_problem:
            self.show_message(start_problem)
        if autostart:
            self.start_source(source)

    # ---- construction ------------------------------------------------------
    def _add_dock(self, title: str, widget: QWidget) -> None:
        dock = QDockWidget(title, self)
        dock.setObjectName(f"dock-{title.lower()}")
        dock.setWidget(widget)
        self.docks[title] = dock

    def _make_actions(self) -> None:
        def action(text: str, shortcut: str | None, slot: Callable[[], object]) -> QAction:
            act = QAction(text, self)
            if shortcut:
                act.setShortcut(QKeySequence(shortcut))
                act.setShortcutContext(Qt.ShortcutContext.ApplicationShortcut)
            act.triggered.connect(slot)
            self.addAction(act)
            return act

        self.start_action = action("Start/stop source", "F5", self.source_panel.toggle)
        self.record_action = action("Record/stop", "Ctrl+R", self.recording_panel.toggle)
        self.snapshot_action = action("Snapshot", "Ctrl+Shift+S", self.snapshot)
        self.export_action = action("Export maps...", "Ctrl+E", self.export_maps_dialog)
        self.png_action = action("Save window as PNG...", "Ctrl+P", self.save_png_dialog)
        self.load_action = action(
            "Load experiment settings...", "Ctrl+Shift+O", self.load_experiment_dialog
        )
        self.save_action = action(
            "Save experiment settings as...", "Ctrl+S", self.save_experiment_dialog
        )
        self.quit_action = action("Quit", "Ctrl+Q", self.close)
        self.reset_layout_action = action("Reset layout", None, self.reset_layout)
        self.auto_levels_action = action("Auto levels", "Ctrl+L", self.hologram.auto_levels)
        self.match_action = action("Match windows to the surface", "Ctrl+M", self.match_windows)
        menus = self.menuBar()
        assert menus is not None  # a QMainWindow makes its menu bar when first asked
        file_menu = _menu(menus, "&File")
        for act in self._make_file_actions():
            file_menu.addAction(act)
        file_menu.addMenu(self.recent_menu)
        file_menu.addSeparator()
        for act in (
            self.load_action,
            self.save_action,
            self.export_action,
            self.png_action,
            self.snapshot_action,
            self.quit_action,
        ):
            file_menu.addAction(act)
        acq = _menu(menus, "&Acquisition")
        acq.addAction(self.start_action)
        acq.addAction(self.record_action)
        acq.addAction(self.auto_levels_action)
        acq.addAction(self.match_action)
        view = _menu(menus, "&View")
        for dock in self.docks.values():
            view.addAction(dock.toggleViewAction())
        view.addAction(self.banner_bar.toggleViewAction())
        view.addSeparator()
        view.addAction(self.reset_layout_action)
        replay = _menu(menus, "&Replay")
        for act in self.transport.shortcuts:
            replay.addAction(act)
            self.addAction(act)

    def _connect(self) -> None:
        self.source_panel.startRequested.connect(self.start_source)
        self.source_panel.stopRequested.connect(self.stop_source)
        self.source_panel.settingRequested.connect(self.apply_setting)
        self.source_panel.refresh_button.clicked.connect(self.find_sources)
        self.hologram.roiChosen.connect(lambda roi: self.apply_setting("roi", roi))
        self.spectrum.peakLabelled.connect(self.label_peak)
        self.spectrum.labelCleared.connect(self.clear_label)
        self.spectrum.radiusChanged.connect(self.set_radius)
        self.spectrum.suggestionsAccepted.connect(self.use_known_labels)
        self.spectrum.message.connect(self.show_message)
        self.surface.referenceChanged.connect(self.set_reference)
        self.trends.pcaRequested.connect(self._pca_requested)
        self.trends.resetRequested.connect(self._reset_trends)
        self.recording_panel.startRequested.connect(self.start_recording)
        self.recording_panel.stopRequested.connect(self.stop_recording)
        self.transport.message.connect(self.show_message)
        self.transport.changed.connect(self._show_source_values)
        self.run_trends.message.connect(self.show_message)
        self.run_trends.seekRequested.connect(self.transport.seek)

    # ---- messages ----------------------------------------------------------
    def show_message(self, text: str) -> None:
        """Show ``text`` in the banner and the status bar (and log it)."""
        logger.warning("%s", text)
        self.banner.setText(text)
        self.banner_bar.setVisible(True)
        self._banner_until = time.monotonic() + BANNER_S
        self.status.showMessage(text, int(BANNER_S * 1000))

    @property
    def banner_text(self) -> str:
        """The message in the banner ('' when hidden)."""
        return self.banner.text() if self.banner_bar.isVisibleTo(self) else ""

    # ---- trends -----------------------------------------------------------
    def _pca_requested(self, on: bool) -> None:
        if self.session is not None:
            self.session.set_pca(on)

    def match_windows(self) -> None:
        """Ask the maps worker to match every window to the surface again (maps restart)."""
        if self.session is not None:
            self.session.match_windows()

    def _reset_trends(self) -> None:
        if self.session is not None:
            self.session.reset_trends()

    # ---- redraw ------------------------------------------------------------
    def redraw(self) -> None:
        """Draw the camera's newest frame and any new result; refresh figures and messages."""
        session = self.session
        if session is None:
            return
        for problem in session.drain_messages():
            self.show_message(problem)
        if self._banner_until and time.monotonic() > self._banner_until:
            self._banner_until = 0.0
            self.banner_bar.setVisible(False)
        newest = session.newest_frame() if self.hologram.shown() else None
        if newest is not None and newest[0] != self._camera_seq:
            self._camera_seq = newest[0]
            self._draw_camera(newest[1])
            self.display_rate.tick()
        self.draw_maps()
        self.draw_waves()
        state = session.replay.state() if session.replay is not None else None
        if state is not None:
            maps_index = -1 if self._last_result is None else self._last_result.frame_index
            self.surface.stats_label.setText(maps_frame_text(state, maps_index))
        if self.run_trends.showing and state is not None:
            self.run_trends.refresh(state.index)
            self._trend_seq = -1
        elif (trend := session.trend()) is not None and trend.seq != self._trend_seq:
            self._trend_seq = trend.seq
            self.trends.set_series(trend.times_s, trend.depths_m, jumped=trend.segment > 0)
            self.trends.set_rate(trend.rate_m_per_s, trend.rate_stderr_m_per_s, trend.rate_fit)
            self.trends.set_pca(trend.pca_confidence, trend.pca_prefactors)
        self.recording_panel.set_progress(session.recording_progress())
        self.transport.refresh()
        rates = session.rates()
        self.status.set_figures(
            LiveFigures(
                camera_fps=rates.camera_fps,
                series_fps=rates.series_fps,
                maps_fps=rates.maps_fps,
                display_fps=self.display_rate.rate(),
                series_missed=rates.series_missed,
                dropped=rates.dropped,
                latency_s=self.last_latency_s,
                camera=session.description,
            )
        )
        if not session.running:
            reason = session.stop_reason
            self.source_panel.set_streaming(False, "stopped: " + reason)
            self.transport.attach(None)
            if session.camera.error is not None:
                self.show_message(f"{session.spec} stopped: {reason}")
            self.timer.stop()

    def draw_maps(self) -> None:
        """Draw the session's newest maps result if it was not drawn yet.

        A restart's reference frame (maps of zeros, not drawn) does not replace the
        maps shown, which exports write (:attr:`_maps_result`)."""
        result = None if self.session is None else self.session.latest()
        if result is not None and result.seq != self._last_seq:
            self._last_seq = result.seq
            self._last_result = result
            if not result.reference:
                self._maps_result = result
            self._draw(result)
            self.last_latency_s = time.time() - result.t_host

    def _draw_camera(self, frame: np.ndarray) -> None:
        self.hologram.set_frame(frame)

    def _draw(self, result: LiveResult) -> None:
        previous = self._drawn
        self._drawn = result
        if result.spectrum is not None and (
            previous is None or result.spectrum is not previous.spectrum
        ):
            self.spectrum.set_spectrum(result.spectrum)
        if previous is None or result.peaks != previous.peaks:
            self.spectrum.set_peaks(result.peaks, result.frame.shape)
        self.spectrum.set_model(result.labelled, result.predicted, result.radius, result.radii)
        self.spectrum.set_notes(result.notes)
        if result.contradiction != self._contradiction:
            self._contradiction = result.contradiction
            if result.contradiction is not None:  # an error headless: said aloud here
                self.show_message(f"{result.contradiction}: the heights of these labels are wrong")
        if result.heights_m or result.phases_rad:
            self.surface.set_maps(
                result.heights_m,
                result.fused_m,
                result.phases_rad,
                result.shifts_px,
                result.grid_of,
                reference=result.reference,
            )

    # ---- layout ------------------------------------------------------------
    def _restore_layout(self) -> None:
        settings = ui_settings()
        geometry = settings.value("main/geometry")
        state = settings.value("main/state")
        if isinstance(geometry, QByteArray):
            self.restoreGeometry(geometry)
        if isinstance(state, QByteArray):
            self.restoreState(state)
            self._bars_as_they_are()
        self.fit_to_screen()

    def fit_to_screen(self) -> None:
        """Move and shrink the window (a restored geometry too) into its screen's free area."""
        layout = self.layout()  # a QMainWindow has its own (the stubs allow None)
        if layout is not None:
            layout.activate()  # the docks' minimum sizes as they are arranged now
        frame, client = self.frameGeometry(), self.geometry()
        margins = frame.size() - client.size()
        if not self.isVisible():  # the window manager's frame is not known yet
            margins = margins.expandedTo(FRAME_ALLOWANCE)
            frame = QRect(frame.topLeft(), client.size() + margins)
        position, size = fitted(frame, margins, available_area(self))
        self.resize(size)
        self.move(position)

    def save_layout(self) -> None:
        """Remember the window geometry and dock layout (QSettings)."""
        settings = ui_settings()
        settings.setValue("main/geometry", self.saveGeometry())
        settings.setValue("main/state", self.saveState())
        settings.sync()

    def reset_layout(self) -> None:
        """Put the docks back where they start."""
        self.restoreState(self._default_state)
        self._place_waves()
        self._bars_as_they_are()

    def _bars_as_they_are(self) -> None:
        """Show the bars a restored layout hid or showed by their state, not the layout's."""
        self.transport.attach(self.transport.control)  # shown only while steering
        self.banner_bar.setVisible(bool(self.banner.text()) and self._banner_until > 0)
        self.notice.setVisible(bool(self.notice.label.text()) and self.notice.has_action)

    def shut_down(self) -> None:
        """Stop every thread and timer (a recording's file closed), remember the layout.

        What closing the window does before it goes; also called alone when the display
        is lost (:mod:`holoview.ui.app`), where the window cannot be closed.
        """
        self.timer.stop()
        opened = self.opener.wait()
        if isinstance(opened, Opened):
            opened.session.close()
        self.discovery.wait()
        self.run_trends.close()
        self.stop_source()
        self.save_layout()

    def closeEvent(self, event: QCloseEvent | None) -> None:
        """Stop every thread and timer, remember the layout, take the Waves plots down
        (:meth:`~holoview.ui.waves_view.WavesView.release`), then close."""
        self.shut_down()
        self.waves.release()
        super().closeEvent(event)


def _menu(bar: QMenuBar, title: str) -> QMenu:
    """A new menu ``title`` at the end of ``bar`` (owned by it)."""
    menu = QMenu(title, bar)
    bar.addMenu(menu)
    return menu
