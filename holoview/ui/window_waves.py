"""The main window's Waves panel: a tab beside Trends, its worker running only while shown.

A mixin of :class:`~holoview.ui.main_window.MainWindow`. The Waves dock is a tab of the
Trends dock (placed once the window is shown). While it is shown (its tab raised, or
the dock moved out) the session runs the waves worker
(:meth:`~holoview.live.session.LiveSession.open_waves`), which demodulates the chosen map
from every camera frame; behind another tab or closed, the worker stops and costs
nothing. The redraw timer draws a new analysis when one comes (about once a second)
and offers the labelled peaks' maps.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from PyQt6.QtCore import Qt, QTimer
from PyQt6.QtGui import QShowEvent
from PyQt6.QtWidgets import QDockWidget

from holoview.live.wave_window import WaveSettings
from holoview.ui.waves_view import WavesView

if TYPE_CHECKING:
    from holoview.live.maps_pipeline import LiveResult
    from holoview.live.session import LiveSession


#: Share of the window's height the Waves dock is given when it is raised.
WAVES_HEIGHT = 0.6


class WavesActions:
    """The Waves part of the main window (mixed into it)."""

    session: LiveSession | None
    docks: dict[str, QDockWidget]
    _last_result: LiveResult | None
    waves: WavesView
    _waves_drawn: object
    _waves_placed: bool
    _waves_shown: bool

    def _add_waves_dock(self) -> QDockWidget:
        """Make the Waves view and its dock, hidden; return the dock."""
        self.waves = WavesView()
        self._waves_drawn = None
        self._waves_placed = False
        self._waves_shown = False
        dock = QDockWidget("Waves", self)  # type: ignore[call-overload]
        dock.setObjectName("dock-waves")
        dock.setWidget(self.waves)
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)  # type: ignore[attr-defined]
        dock.hide()  # placed once the window is shown (:meth:`showEvent`)
        dock.visibilityChanged.connect(self._waves_visibility)
        self.waves.settingsChanged.connect(self._waves_settings)
        return dock

    def show_waves(self) -> None:
        """Raise the Waves tab (its worker starts)."""
        self._place_waves()
        QTimer.singleShot(0, self.docks["Waves"].raise_)  # after the placing's own raise

    def _waves_height(self) -> None:
        """Give the shown Waves dock :data:`WAVES_HEIGHT` of the window's height at least
        (its spectra are unreadable in a strip)."""
        dock = self.docks["Waves"]
        wanted = int(WAVES_HEIGHT * self.height())  # type: ignore[attr-defined]
        if not dock.isFloating() and dock.height() < wanted:
            self.resizeDocks([dock], [wanted], Qt.Orientation.Vertical)  # type: ignore[attr-defined]

    def showEvent(self, event: QShowEvent | None) -> None:
        """Once shown, put the Waves dock in the Trends dock's tabs (not raised)."""
        super().showEvent(event)  # type: ignore[misc]
        if not self._waves_placed:
            self._waves_placed = True
            QTimer.singleShot(0, self._place_waves)  # after the window's first layout

    def _place_waves(self) -> None:
        """Make the Waves dock a tab beside Trends, unless it is one already.

        Done once the window is shown: a second group of tabs made before that is drawn
        twice by Qt (:func:`~holoview.ui.window_layout.arrange_docks`).
        """
        waves, trends = self.docks["Waves"], self.docks["Trends"]
        if waves in self.tabifiedDockWidgets(trends):  # type: ignore[attr-defined]
            return
        group = [trends, *self.tabifiedDockWidgets(trends)]  # type: ignore[attr-defined]
        shown = [d for d in (waves, *group) if not d.visibleRegion().isEmpty()]
        self.tabifyDockWidget(trends, waves)  # type: ignore[attr-defined]
        waves.show()
        QTimer.singleShot(0, (shown[0] if shown else trends).raise_)  # it stays shown

    @property
    def waves_shown(self) -> bool:
        """True while the Waves panel is on screen (its tab raised, or the dock alone)."""
        return self._waves_shown

    def _waves_visibility(self, visible: bool) -> None:
        self._waves_shown = visible
        self._waves_session()
        if visible:  # its tab clicked, or raised: room for the spectra
            QTimer.singleShot(0, self._waves_height)

    def _waves_session(self) -> None:
        """Run the waves worker while the dock is shown and a session runs."""
        session = self.session
        if session is None:
            return
        if self._waves_shown:
            session.open_waves(self.waves.settings())
        else:
            session.close_waves()

    def _waves_settings(self, settings: WaveSettings) -> None:
        if self.session is not None and self._waves_shown:
            self.session.open_waves(settings)

    def draw_waves(self) -> None:
        """Offer the labelled maps and draw the newest analysis (from the redraw timer)."""
        session = self.session
        if session is None or not self._waves_shown:
            return
        result = self._last_result
        if result is not None:
            self.waves.set_labels(sorted(result.heights_m))
        waves = session.waves()
        if waves is not None and waves is not self._waves_drawn:
            self._waves_drawn = waves
            self.waves.set_waves(waves)
