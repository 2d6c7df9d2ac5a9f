"""The status bar: camera, processing and display rates, dropped frames, latency."""

from __future__ import annotations

from dataclasses import dataclass

from PyQt6.QtWidgets import QLabel, QStatusBar, QWidget


@dataclass(frozen=True)
class LiveFigures:
    """What the status bar shows.

    Attributes
    ----------
    camera_fps, processing_fps, display_fps : float
        Frames per second delivered by the camera, demodulated, and drawn.
    dropped : int
        Frames the ring overwrote before a consumer that takes every frame read them,
        plus frames the camera or transport lost.
    latency_s : float or None
        Time from the frame's host timestamp to when it was drawn, seconds.
    camera : str
        What the source is (name, shape, pixel format).
    """

    camera_fps: float = 0.0
    processing_fps: float = 0.0
    display_fps: float = 0.0
    dropped: int = 0
    latency_s: float | None = None
    camera: str = "no source"


class LiveStatusBar(QStatusBar):
    """A status bar with permanent fields for the live figures and a message area."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.camera_label = QLabel()
        self.camera_fps_label = QLabel()
        self.processing_fps_label = QLabel()
        self.display_fps_label = QLabel()
        self.dropped_label = QLabel()
        self.latency_label = QLabel()
        for label in (
            self.camera_label,
            self.camera_fps_label,
            self.processing_fps_label,
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
        if previous is None or bool(figures.dropped) != bool(previous.dropped):
            self.dropped_label.setStyleSheet("color: #c00000;" if figures.dropped else "")
        self.camera_label.setText(figures.camera)
        self.camera_fps_label.setText(f"camera {figures.camera_fps:5.1f} fps")
        self.processing_fps_label.setText(f"processing {figures.processing_fps:5.1f} fps")
        self.display_fps_label.setText(f"display {figures.display_fps:4.1f} fps")
        self.dropped_label.setText(f"dropped {figures.dropped}")
        latency = "-" if figures.latency_s is None else f"{figures.latency_s * 1e3:4.0f} ms"
        self.latency_label.setText(f"latency {latency}")
