"""The main window's Waves panel: a dock shown on demand, its worker running only while shown.

A mixin of :class:`~holoview.ui.main_window.MainWindow`. The Waves dock starts hidden
(View menu): while it is shown the session runs the waves worker
(:meth:`~holoview.live.session.LiveSession.open_waves`), which demodulates the chosen map
from every camera frame; hidden, the worker stops and costs nothing. Opened for the first
time, the dock joins the Trends dock as a tab. The redraw timer draws a new analysis when
one comes (about once a second) and offers the labelled peaks' maps.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from PyQt6.QtCore import Qt
from PyQt6.QtWidgets import QDockWidget

from holoview.live.wave_window import WaveSettings
from holoview.ui.waves_view import WavesView

if TYPE_CHECKING:
    from holoview.live.pipeline import LiveResult
    from holoview.live.session import LiveSession


class WavesActions:
    """The Waves part of the main window (mixed into it)."""

    session: LiveSession | None
    docks: dict[str, QDockWidget]
    _last_result: LiveResult | None
    waves: WavesView
    _waves_drawn: object
    _waves_placed: bool

    def _add_waves_dock(self) -> QDockWidget:
        """Make the Waves view and its dock, hidden; return the dock."""
        self.waves = WavesView()
        self._waves_drawn = None
        self._waves_placed = False
        dock = QDockWidget("Waves", self)  # type: ignore[call-overload]
        dock.setObjectName("dock-waves")
        dock.setWidget(self.waves)
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)  # type: ignore[attr-defined]
        dock.hide()
        dock.visibilityChanged.connect(self._waves_visibility)
        dock.toggleViewAction().triggered.connect(self._place_waves)
        self.waves.settingsChanged.connect(self._waves_settings)
        return dock

    def show_waves(self) -> None:
        """Show the Waves dock (beside Trends) and start its worker."""
        dock = self.docks["Waves"]
        self._place_waves()
        dock.show()
        dock.raise_()

    def _place_waves(self) -> None:
        if self._waves_placed or "Trends" not in self.docks:
            return
        self._waves_placed = True
        self.tabifyDockWidget(self.docks["Trends"], self.docks["Waves"])  # type: ignore[attr-defined]

    def _waves_visibility(self, visible: bool) -> None:
        self._waves_session()

    def _waves_session(self) -> None:
        """Run the waves worker while the dock is shown and a session runs."""
        session = self.session
        if session is None:
            return
        if self.docks["Waves"].isVisible():
            session.open_waves(self.waves.settings())
        else:
            session.close_waves()

    def _waves_settings(self, settings: WaveSettings) -> None:
        if self.session is not None and self.docks["Waves"].isVisible():
            self.session.open_waves(settings)

    def draw_waves(self) -> None:
        """Offer the labelled maps and draw the newest analysis (from the redraw timer)."""
        session = self.session
        if session is None or not self.docks["Waves"].isVisible():
            return
        result = self._last_result
        if result is not None:
            self.waves.set_labels(sorted(result.heights_m))
        waves = session.waves()
        if waves is not None and waves is not self._waves_drawn:
            self._waves_drawn = waves
            self.waves.set_waves(waves)
