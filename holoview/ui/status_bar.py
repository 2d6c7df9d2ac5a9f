"""The status bar: camera, series, maps and display rates, missed and dropped frames, latency.

:class:`RateMeter` measures the display's own rate (redraws a second); the other rates
are the live engine's.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

from PyQt6.QtWidgets import QLabel, QStatusBar, QWidget


class RateMeter:
    """Count events and report their rate over the last ``window_s`` seconds.

    Parameters
    ----------
    window_s : float
        Length of the averaging window, seconds.
    """

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_s = window_s
        self._ticks: deque[tuple[float, int]] = deque()

    def tick(self, count: int = 1, now: float | None = None) -> None:
        """Record ``count`` events at ``now`` (``time.monotonic()`` seconds by default)."""
        t = time.monotonic() if now is None else now
        self._ticks.append((t, count))
        self._trim(t)

    def rate(self, now: float | None = None) -> float:
        """Return events per second over the window ending at ``now`` (0 with < 2 ticks)."""
        self._trim(time.monotonic() if now is None else now)
        if len(self._ticks) < 2:
            return 0.0
        span = self._ticks[-1][0] - self._ticks[0][0]
        events = sum(c for _, c in list(self._ticks)[1:])
        return events / span if span > 0 else 0.0

    def _trim(self, now: float) -> None:
        while self._ticks and self._ticks[0][0] < now - self.window_s:
            self._ticks.popleft()


@dataclass(frozen=True)
class LiveFigures:
    """What the status bar shows.

    Attributes
    ----------
    camera_fps, series_fps, maps_fps, display_fps : float
        Frames per second delivered by the camera, measured by the series (every frame
        when it keeps up), demodulated into maps (the newest), and shown in the camera
        view (the newest camera frame at each redraw).
    series_missed : int
        Frames the ring overwrote before the series took them.
    dropped : int
        Frames the camera or transport lost, and frames the recorder missed.
    latency_s : float or None
        Time from the host timestamp of the newest map's frame to when the map was
        drawn, seconds.
    camera : str
        What the source is (name, shape, pixel format).
    """

    camera_fps: float = 0.0
    series_fps: float = 0.0
    maps_fps: float = 0.0
    display_fps: float = 0.0
    series_missed: int = 0
    dropped: int = 0
    latency_s: float | None = None
    camera: str = "no source"


class LiveStatusBar(QStatusBar):
    """A status bar with permanent fields for the live figures and a message area."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.camera_label = QLabel()
        self.camera_fps_label = QLabel()
        self.series_fps_label = QLabel()
        self.maps_fps_label = QLabel()
        self.display_fps_label = QLabel()
        self.dropped_label = QLabel()
        self.latency_label = QLabel()
        for label in (
            self.camera_label,
            self.camera_fps_label,
            self.series_fps_label,
            self.maps_fps_label,
            self.display_fps_label,
            self.dropped_label,
            self.latency_label,
        ):
            self.addPermanentWidget(label)
        self._figures: LiveFigures | None = None
        self.set_figures(LiveFigures())

    def set_figures(self, figures: LiveFigures) -> None:
        """Show ``figures`` in the permanent fields (nothing is redone when unchanged)."""
        previous, self._figures = self._figures, figures
        if figures == previous:
            return
        lost = figures.dropped + figures.series_missed
        if previous is None or bool(lost) != bool(previous.dropped + previous.series_missed):
            self.dropped_label.setStyleSheet("color: #c00000;" if lost else "")
        self.camera_label.setText(figures.camera)
        self.camera_fps_label.setText(f"camera {figures.camera_fps:5.1f} fps")
        self.series_fps_label.setText(f"series {figures.series_fps:5.1f} fps")
        self.maps_fps_label.setText(f"maps {figures.maps_fps:5.1f} fps")
        self.display_fps_label.setText(f"display {figures.display_fps:4.1f} fps")
        self.dropped_label.setText(
            f"dropped {figures.dropped}, series missed {figures.series_missed}"
        )
        latency = "-" if figures.latency_s is None else f"{figures.latency_s * 1e3:4.0f} ms"
        self.latency_label.setText(f"map latency {latency}")
