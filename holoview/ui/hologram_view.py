"""The raw camera frame: persistent levels, percentile auto-levels, saturation, readout."""

from __future__ import annotations

import contextlib
import importlib
import math
import time
from collections.abc import Iterator

import numpy as np
import pyqtgraph as pg
from PyQt6.QtCore import QPointF, QRectF, pyqtSignal
from PyQt6.QtWidgets import QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

#: pyqtgraph's module of colour-map menus (:func:`_no_uncategorised_matplotlib_maps`).
_MENUS = importlib.import_module("pyqtgraph.widgets.ColorMapMenu")

#: Percentiles used by the auto-levels button (low, high).
AUTO_LEVEL_PERCENTILES = (0.5, 99.5)

#: RGBA of the saturation overlay.
SATURATION_RGBA = (255, 0, 0, 200)

#: Seconds between histogram updates (computing one per frame costs display rate).
HISTOGRAM_INTERVAL_S = 0.5


@contextlib.contextmanager
def _no_uncategorised_matplotlib_maps() -> Iterator[None]:
    """Within the block, pyqtgraph's colour-map menus leave out matplotlib's "Others".

    A histogram's gradient builds its colour-map menu at once, and the menu lists
    matplotlib's maps outside its categories by importing ``matplotlib.pyplot``: 1.36 s
    of the window's 1.8 s build (cProfile, 2 cores), at every start of ``holoview live``.
    The categories' submenus stay (built when opened); only that one is left out.
    """
    name = "find_mpl_leftovers"  # by name: not part of pyqtgraph's typed interface
    saved = getattr(_MENUS, name, None)
    if saved is None:  # another pyqtgraph: nothing to leave out
        yield
        return
    setattr(_MENUS, name, list)
    try:
        yield
    finally:
        setattr(_MENUS, name, saved)


class HologramView(QWidget):
    """Show raw frames with levels that persist across frames.

    Levels change only when the operator asks (the auto-levels button or the
    histogram), never on their own, so the image does not flicker. Pixels at or
    above the saturation value are painted red. The cursor readout gives the pixel
    (row, column) and its raw value. An ROI rectangle can be drawn for the source.

    Signals
    -------
    roiChosen(tuple)
        ``(left, top, width, height)`` in pixels, when the operator applies the ROI.
    """

    roiChosen = pyqtSignal(tuple)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._frame: np.ndarray | None = None
        self._levels: tuple[float, float] | None = None
        self._saturation_value: float | None = None
        self.graphics = pg.GraphicsLayoutWidget()
        self.plot = self.graphics.addPlot()
        self.plot.setAspectLocked(True)
        self.plot.invertY(True)
        self.plot.setLabel("bottom", "column", units="px")
        self.plot.setLabel("left", "row", units="px")
        for axis in ("bottom", "left"):
            self.plot.getAxis(axis).enableAutoSIPrefix(False)
        # large frames are subsampled to the screen's resolution before drawing
        # (set_frame); the readout always uses the raw values
        self.image = pg.ImageItem(axisOrder="row-major")
        self.overlay = pg.ImageItem(axisOrder="row-major")
        self._overlay_shown = False
        self._histogram_at = -math.inf
        self._step = 1
        self._placed: tuple[tuple[int, ...], QRectF] | None = None  # shown shape, rectangle
        self.overlay.setZValue(10)
        self.plot.addItem(self.image)
        self.plot.addItem(self.overlay)
        with _no_uncategorised_matplotlib_maps():
            self.histogram = pg.HistogramLUTItem(image=self.image)
        self.image.sigImageChanged.disconnect(self.histogram.imageChanged)
        self.histogram.sigLevelsChanged.connect(self._levels_from_histogram)
        self.graphics.addItem(self.histogram)
        self.roi: pg.RectROI | None = None

        self.readout = QLabel("move the cursor over the image")
        self.auto_button = QPushButton("Auto levels")
        self.auto_button.setToolTip(
            f"set levels to the {AUTO_LEVEL_PERCENTILES[0]}-{AUTO_LEVEL_PERCENTILES[1]} "
            "percentiles of the current frame"
        )
        self.auto_button.clicked.connect(self.auto_levels)
        self.saturation_button = QPushButton("Saturation")
        self.saturation_button.setCheckable(True)
        self.saturation_button.setChecked(True)
        self.saturation_button.setToolTip("paint saturated pixels red")
        self.saturation_button.toggled.connect(self._update_overlay)
        self.roi_button = QPushButton("Draw ROI")
        self.roi_button.setCheckable(True)
        self.roi_button.toggled.connect(self._toggle_roi)
        self.apply_roi_button = QPushButton("Apply ROI")
        self.apply_roi_button.setEnabled(False)
        self.apply_roi_button.clicked.connect(self._apply_roi)

        buttons = QHBoxLayout()
        for widget in (
            self.auto_button,
            self.saturation_button,
            self.roi_button,
            self.apply_roi_button,
        ):
            buttons.addWidget(widget)
        buttons.addStretch(1)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addLayout(buttons)
        layout.addWidget(self.graphics, 1)
        layout.addWidget(self.readout)
        self.graphics.scene().sigMouseMoved.connect(self._mouse_moved)

    @property
    def levels(self) -> tuple[float, float] | None:
        """The display levels (raw counts), or None before the first frame."""
        return self._levels

    def set_saturation_value(self, value: float | None) -> None:
        """Set the raw value at and above which a pixel counts as saturated (None: off)."""
        self._saturation_value = value
        self._update_overlay()

    def shown(self) -> bool:
        """Whether any of the view is on screen (not closed, not a tab behind another)."""
        return self.isVisible() and not self.visibleRegion().isEmpty()

    def display_step(self) -> int:
        """Frame pixels per screen pixel, rounded down (1 when zoomed in or not shown)."""
        if self._frame is None or not self.shown():
            return 1
        try:
            px, py = self.plot.vb.viewPixelSize()
        except (ZeroDivisionError, np.linalg.LinAlgError):
            return 1
        size = min(px, py)
        return max(1, int(size)) if math.isfinite(size) else 1

    def _shown(self, array: np.ndarray, step: int) -> tuple[np.ndarray, QRectF]:
        """Every ``step``-th pixel of ``array`` and the frame rectangle it covers.

        Drawing a large frame on a smaller screen area shows every n-th pixel anyway;
        taking them here spares the colour lookup and the scaling of the others.
        """
        rows, cols = (array.shape[0] // step) * step, (array.shape[1] // step) * step
        return array[:rows:step, :cols:step], QRectF(0, 0, cols, rows)

    def set_frame(self, frame: np.ndarray) -> None:
        """Show ``frame`` (rows, cols) with the current levels (the first frame sets them)."""
        first = self._frame is None or self._frame.shape != frame.shape
        self._frame = frame
        if self._levels is None:  # the histogram's too: a paused replay draws one frame only
            self.set_levels(*self._percentile_levels(frame))
        self._step = 1 if first else self.display_step()
        shown, rect = self._shown(frame, self._step)
        self.image.setImage(shown, autoLevels=False, levels=self._levels)
        # setRect scales by the image's shape when called: a new display step changes
        # the shape shown, not the rectangle, and needs it again
        if (shown.shape, rect) != self._placed:
            self._placed = (shown.shape, rect)
            self.image.setRect(rect)
        now = time.monotonic()
        if first or now - self._histogram_at >= HISTOGRAM_INTERVAL_S:
            self._histogram_at = now
            self.histogram.imageChanged()
        if first:
            self.plot.autoRange(padding=0)
        self._update_overlay()

    def set_levels(self, low: float, high: float) -> None:
        """Fix the display levels to ``(low, high)`` raw counts."""
        if not high > low:
            high = low + 1.0
        self._levels = (float(low), float(high))
        self.histogram.setLevels(*self._levels)
        self.image.setLevels(self._levels)

    def auto_levels(self) -> None:
        """Set levels once from the percentiles of the current frame; they then persist."""
        if self._frame is not None:
            self.set_levels(*self._percentile_levels(self._frame))

    @staticmethod
    def _percentile_levels(frame: np.ndarray) -> tuple[float, float]:
        step = max(1, frame.size // 262144)
        sample = frame.reshape(-1)[::step]
        low, high = np.percentile(sample, AUTO_LEVEL_PERCENTILES)
        return float(low), float(max(high, low + 1))

    def _levels_from_histogram(self) -> None:
        low, high = self.histogram.getLevels()
        self._levels = (float(low), float(high))

    def _update_overlay(self) -> None:
        if (
            self._frame is None
            or self._saturation_value is None
            or not self.saturation_button.isChecked()
        ):
            self.overlay.clear()
            return
        mask = self._frame >= self._saturation_value
        if not mask.any():
            if self._overlay_shown:
                self.overlay.clear()
                self._overlay_shown = False
            return
        self._overlay_shown = True
        step = self._step
        shown, rect = self._shown(mask, step)
        shown = shown.copy()
        for dy in range(step):
            for dx in range(step):
                if dy or dx:  # a saturated pixel anywhere in a block marks the block
                    shown |= mask[
                        dy : shown.shape[0] * step : step, dx : shown.shape[1] * step : step
                    ]
        rgba = np.zeros((*shown.shape, 4), dtype=np.uint8)
        rgba[shown] = SATURATION_RGBA
        self.overlay.setImage(rgba, autoLevels=False)
        self.overlay.setRect(rect)  # the frame's extent at this step's shape

    def saturated_count(self) -> int:
        """Return how many pixels of the current frame are at or above saturation."""
        if self._frame is None or self._saturation_value is None:
            return 0
        return int(np.count_nonzero(self._frame >= self._saturation_value))

    def readout_at(self, x: float, y: float) -> str:
        """Return the readout text for image coordinates ``x`` (column), ``y`` (row)."""
        if self._frame is None:
            return "no frame"
        row, col = int(np.floor(y)), int(np.floor(x))
        rows, cols = self._frame.shape[:2]
        if not (0 <= row < rows and 0 <= col < cols):
            return f"outside the frame ({rows} x {cols})"
        return f"row {row}, column {col}: {self._frame[row, col]}"

    def _mouse_moved(self, pos: QPointF) -> None:
        if self.plot.sceneBoundingRect().contains(pos):
            point = self.plot.vb.mapSceneToView(pos)
            self.readout.setText(self.readout_at(point.x(), point.y()))

    def _toggle_roi(self, on: bool) -> None:
        if on and self._frame is not None:
            rows, cols = self._frame.shape[:2]
            self.roi = pg.RectROI(
                [cols // 4, rows // 4], [cols // 2, rows // 2], pen=pg.mkPen("y", width=2)
            )
            self.roi.addScaleHandle([0, 0], [1, 1])
            self.plot.addItem(self.roi)
        elif self.roi is not None:
            self.plot.removeItem(self.roi)
            self.roi = None
        self.apply_roi_button.setEnabled(self.roi is not None)

    def current_roi(self) -> tuple[int, int, int, int] | None:
        """Return the drawn ROI as ``(left, top, width, height)`` in pixels, or None."""
        if self.roi is None:
            return None
        x, y = self.roi.pos()
        w, h = self.roi.size()
        return round(x), round(y), round(w), round(h)

    def _apply_roi(self) -> None:
        roi = self.current_roi()
        if roi is not None:
            self.roiChosen.emit(roi)
            self.roi_button.setChecked(False)
