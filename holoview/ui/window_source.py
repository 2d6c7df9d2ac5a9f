"""The main window's source: opening one on a thread, its settings, stopping it, recording.

A mixin of :class:`~holoview.ui.main_window.MainWindow`. A source (the simulator, a
camera, a replayed file) opens on a thread (:class:`~holoview.ui.background.BackgroundCall`)
while the window stays responsive; when it is open the views follow it, the optics it
knows go into the experiment and a recording's experiment is applied; the cameras are
looked for on a thread as well. Settings go to the source and what it reads back is
shown; recording starts and stops on the session.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from holoview.errors import HoloviewError
from holoview.live.session import LiveSession, RecordRequest, discover_sources
from holoview.ui.open_files import Opened, opened_source
from holoview.ui.status_bar import LiveFigures

if TYPE_CHECKING:
    from collections.abc import Callable

    from PyQt6.QtCore import QTimer, pyqtBoundSignal

    from holoview.engine.experiment import Experiment
    from holoview.live.maps_pipeline import LiveResult
    from holoview.ui.background import BackgroundCall
    from holoview.ui.hologram_view import HologramView
    from holoview.ui.recording_panel import RecordingPanel
    from holoview.ui.run_trends import RunTrends
    from holoview.ui.source_panel import SourcePanel
    from holoview.ui.status_bar import LiveStatusBar
    from holoview.ui.surface_view import SurfaceView
    from holoview.ui.transport_bar import TransportBar


class SourceActions:
    """The source and recording part of the main window (mixed into it)."""

    session: LiveSession | None
    experiment: Experiment
    optics: dict[str, float]
    source_options: dict[str, Any]
    _optioned_source: str
    _opening_spec: str
    _last_seq: int
    _camera_seq: int
    _drawn: LiveResult | None
    opener: BackgroundCall
    discovery: BackgroundCall
    timer: QTimer
    mapsReady: pyqtBoundSignal
    hologram: HologramView
    surface: SurfaceView
    source_panel: SourcePanel
    recording_panel: RecordingPanel
    transport: TransportBar
    run_trends: RunTrends
    status: LiveStatusBar
    show_message: Callable[[str], None]
    _set_experiment: Callable[[Experiment], None]
    _apply_recording_experiment: Callable[..., None]
    _learn_known_labels: Callable[[], None]
    _waves_session: Callable[[], None]

    # ---- source ------------------------------------------------------------
    def start_source(self, spec: str, paused: bool = False) -> None:
        """Open and start ``spec`` on a thread; the window stays responsive meanwhile.

        Opening a camera or timing the simulator can take a second. When it is done
        (:attr:`opening` is False again) the views follow the new source, or the banner
        says why it could not start. A replay starts ``paused`` on its first frame
        when asked; the experiment a recording carries is read on the same thread.
        """
        if self.opener.busy:
            self.show_message(f"still opening {self._opening_spec}; try again when it is open")
            return
        self.stop_source()
        options = dict(self.source_options if spec == self._optioned_source else {})
        if paused:
            options["speed"] = "step"
        experiment = self.experiment

        def open_session() -> Opened | str:
            try:
                session = LiveSession.open(spec, experiment, source_options=options)
            except HoloviewError as exc:
                return f"cannot start {spec}: {exc}"
            return opened_source(session, paused)

        self._opening_spec = spec
        self.source_panel.set_opening(spec)
        self.opener.start(open_session)

    @property
    def opening(self) -> bool:
        """True while a source is being opened."""
        return self.opener.busy

    def _opened(self, outcome: object) -> None:
        if not isinstance(outcome, Opened):
            internal = f"cannot start {self._opening_spec}: internal error (see the log)"
            self.show_message(outcome if isinstance(outcome, str) else internal)
            self.source_panel.set_streaming(False)
            return
        self.session = outcome.session
        self._last_seq = -1
        self._camera_seq = -1
        self._drawn = None
        self.session.on_maps(self.mapsReady.emit)
        self._adopt_source_setup(self.session.source_setup())
        for note in outcome.notes:
            self.show_message(note)
        self._apply_recording_experiment(outcome.stored, self.session.source_setup())
        self._learn_known_labels()
        self.hologram.set_saturation_value(self.session.saturation_value)
        self.source_panel.set_settings(
            self.session.describe_settings(), self.session.read_settings()
        )
        self.source_panel.set_streaming(True, self.session.description)
        self.transport.attach(self.session.replay)
        self._attach_run()
        self._waves_session()
        self.timer.start()

    def _attach_run(self) -> None:
        """Measure the whole run of a replayed file (the trends view shows it); else nothing."""
        replay = self.session.replay if self.session is not None else None
        if replay is None:
            self.run_trends.attach(None)
            return
        clock = replay.clock()
        self.run_trends.attach(replay.path, self.experiment, clock.rate_hz, clock.text)

    def _adopt_source_setup(self, setup: dict[str, Any]) -> None:
        """Take the optics a source knows (simulator, recording) into the experiment."""
        fields = ("wavelength_m", "pixel_pitch_m", "n1", "n2")
        changes = {k: float(setup[k]) for k in fields if k in setup and k not in self.optics}
        if not changes or all(getattr(self.experiment, k) == v for k, v in changes.items()):
            return
        try:
            self._set_experiment(self.experiment.with_optics(changes))
        except HoloviewError as exc:
            self.show_message(f"the source's optical setup is not usable: {exc}")
            return
        text = ", ".join(f"{k} = {v:g}" for k, v in changes.items())
        self.status.showMessage(f"optics from the source: {text}", 8000)

    def stop_source(self) -> None:
        """Stop the running session (recording included) and its threads."""
        if self.session is None:
            return
        self.timer.stop()
        self.transport.attach(None)
        self.run_trends.attach(None)
        self.surface.stats_label.clear()
        self.session.close()
        self.session = None
        self.recording_panel.set_progress(None)
        self.source_panel.set_streaming(False)
        self.status.set_figures(LiveFigures())

    def find_sources(self) -> None:
        """Look for GenICam cameras and V4L2 devices (on a thread) and offer them."""
        if self.discovery.start(discover_sources):
            self.source_panel.refresh_button.setEnabled(False)
            self.source_panel.state_label.setText("looking for cameras...")

    def _discovery_done(self, outcome: object) -> None:
        self.source_panel.refresh_button.setEnabled(self.session is None)
        if not isinstance(outcome, tuple):
            self.show_message("looking for cameras failed (see the log)")
            return
        specs, problems = outcome
        self.source_panel.set_sources(specs)
        self.source_panel.state_label.setText(f"{len(specs)} sources found")
        for problem in problems:
            self.show_message(problem)

    def apply_setting(self, name: str, value: object) -> None:
        """Send a setting to the source and show what it reads back."""
        if self.session is None:
            self.show_message(f"start a source before setting {name}")
            return
        try:
            self.session.set_setting(name, value)
        except HoloviewError as exc:
            self.show_message(str(exc))
        self._last_seq = -1
        self._camera_seq = -1
        if self.session.replay is not None:
            clock = self.session.replay.clock()
            self.run_trends.set_clock(clock.rate_hz, clock.text)
        self.source_panel.show_values(self.session.read_settings())
        self.source_panel.set_streaming(self.session.running, self.session.description)

    def _show_source_values(self) -> None:
        if self.session is not None:
            self.source_panel.show_values(self.session.read_settings())

    # ---- recording ---------------------------------------------------------
    def start_recording(self, request: RecordRequest) -> None:
        """Start recording what the source delivers, as ``request`` asks."""
        if self.session is None:
            self.show_message("start a source before recording")
            return
        try:
            self.session.start_recording(request)
        except HoloviewError as exc:
            self.show_message(f"cannot record: {exc}")
            return
        self.recording_panel.set_progress(self.session.recording_progress())

    def stop_recording(self) -> None:
        """Stop the recording (the file is closed and complete)."""
        if self.session is not None:
            self.session.stop_recording()
            self.recording_panel.set_progress(self.session.recording_progress())
