"""The live spatial-frequency spectrum: peaks, labels, predicted carriers, windows.

Axes are in cycles per pixel: fx along columns (horizontal), fy along rows
(vertical, increasing downwards as in the image). A click near a detected peak
(or its twin) snaps to it and offers a label; dragging a window circle's handle
changes the window radius. The view only draws and emits commands.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import pyqtgraph as pg
from PyQt6.QtCore import QRectF, Qt, pyqtSignal
from PyQt6.QtGui import QCursor
from PyQt6.QtWidgets import (
    QGraphicsEllipseItem,
    QHBoxLayout,
    QInputDialog,
    QLabel,
    QMenu,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from holoview.engine.experiment import PEAK_LABELS
from holoview.engine.peak_geometry import Carrier, swallowed_neighbour, window_warnings
from holoview.processing.peaks.snapping import SNAP_BINS, snap
from holoview.ui.label_layout import PeakLabel, place_labels

if TYPE_CHECKING:
    from pyqtgraph.GraphicsScene.mouseEvents import MouseClickEvent

#: Pen colour of a labelled peak's marker, window and label.
LABEL_COLOUR = "#33ddff"
#: Pen colour of model-predicted carriers.
PREDICTED_COLOUR = "#ffd24d"
#: Size of a labelled peak's marker, pixels.
LABEL_MARKER_PX = 12
#: Pen colour of the labels a source suggests before the operator accepts them.
SUGGESTED_COLOUR = "#b0b0b0"
#: What the spectrum says while no peak is labelled.
FIRST_STEP = (
    "No peak labelled yet: click a bright peak and name it (RB1, FB1, RF); "
    "two names let the model name the others."
)
#: Margin around the spectrum plot, pixels, so that the end tick labels show.
SPECTRUM_MARGIN_PX = 10.0
#: Choice returned by the label menu to remove a label.
CLEAR = "\x00clear"

LabelChooser = Callable[[Carrier, str | None], str | None]


def menu_label_chooser(parent: QWidget) -> LabelChooser:
    """Return a chooser that pops up the label menu at the cursor."""

    def choose(carrier: Carrier, current: str | None) -> str | None:
        menu = QMenu(parent)
        menu.addSection(f"peak at ({carrier[0]:+.4f}, {carrier[1]:+.4f}) cycles/px")
        actions = {menu.addAction(name): name for name in PEAK_LABELS}
        custom = menu.addAction("Custom...")
        clear = menu.addAction(f"Clear label {current}") if current else None
        chosen = menu.exec(QCursor.pos())
        if chosen is None:
            return None
        if chosen is clear:
            return CLEAR
        if chosen is custom:
            text, ok = QInputDialog.getText(parent, "Peak label", "Label:")
            return text.strip() or None if ok else None
        return actions[chosen]

    return choose


class SpectrumView(QWidget):
    """Log-magnitude spectrum with peak markers, labels, predicted carriers and windows.

    Signals
    -------
    peakLabelled(str, float, float)
        Label and carrier (cycles per pixel) chosen by the operator.
    labelCleared(str)
        The operator removed this label.
    radiusChanged(float)
        New window radius in cycles per pixel, after a drag that was accepted.
    suggestionsAccepted()
        The operator took the labels the source suggests (:meth:`set_suggestions`).
    message(str)
        A problem to show the operator (no peak near the click, radius refused).
    """

    peakLabelled = pyqtSignal(str, float, float)
    labelCleared = pyqtSignal(str)
    radiusChanged = pyqtSignal(float)
    suggestionsAccepted = pyqtSignal()
    message = pyqtSignal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.choose_label: LabelChooser = menu_label_chooser(self)
        self._peaks: list[Carrier] = []
        self._shape: tuple[int, int] = (1024, 1024)
        self._labelled: dict[str, Carrier] = {}
        self._predicted: dict[str, Carrier] = {}
        self._radius = 0.06
        self._radii: dict[str, float] = {}
        self._notes: tuple[str, ...] = ()
        self._levels: tuple[float, float] | None = None
        self._circles: dict[str, pg.CircleROI] = {}
        self._texts: list[pg.TextItem] = []
        self._text_peaks: list[PeakLabel] = []
        self._suggested: dict[str, Carrier] = {}
        self._suggested_from = ""
        self._suggestion_items: list[pg.GraphicsObject] = []
        self._updating = False

        self.graphics = pg.GraphicsLayoutWidget()
        self.plot = self.graphics.addPlot()
        self.plot.setAspectLocked(True)
        self._pad = (0.0, 0.0)
        m = SPECTRUM_MARGIN_PX
        self.graphics.ci.setContentsMargins(m, m, m, m)
        self.plot.getViewBox().sigResized.connect(self._keep_square)
        self.plot.getViewBox().sigTransformChanged.connect(self._place_texts)
        self.plot.invertY(True)
        self.plot.setLabel("bottom", "fx", units="cycles/px")
        self.plot.setLabel("left", "fy", units="cycles/px")
        for axis in ("bottom", "left"):
            self.plot.getAxis(axis).enableAutoSIPrefix(False)
        self.image = pg.ImageItem(axisOrder="row-major")
        self.image.setColorMap(pg.colormap.get("inferno"))
        self.plot.addItem(self.image)
        self.detected_markers = pg.ScatterPlotItem(
            symbol="o", size=14, pen=pg.mkPen("w", width=1), brush=None
        )
        self.labelled_markers = pg.ScatterPlotItem(
            symbol="o", size=LABEL_MARKER_PX, pen=pg.mkPen(LABEL_COLOUR, width=2), brush=None
        )
        self.predicted_markers = pg.ScatterPlotItem(
            symbol="x", size=14, pen=pg.mkPen(PREDICTED_COLOUR, width=2), brush=PREDICTED_COLOUR
        )
        for item in (self.detected_markers, self.labelled_markers, self.predicted_markers):
            item.setZValue(20)
            self.plot.addItem(item)
        self.warning_label = QLabel()
        self.warning_label.setStyleSheet("color: #b35900; font-weight: bold;")
        self.warning_label.setWordWrap(True)
        self.warning_label.hide()
        hint = QLabel("click near a peak to label it; drag a circle's handle to change the radius")
        hint.setStyleSheet("color: gray;")
        hint.setWordWrap(True)
        self.first_step = QLabel(FIRST_STEP)
        self.first_step.setWordWrap(True)
        self.first_step.setStyleSheet("font-weight: bold;")
        self.use_suggestions = QPushButton("Use these labels")
        self.use_suggestions.setToolTip("label the peaks where the source says they are")
        self.use_suggestions.clicked.connect(self.suggestionsAccepted.emit)
        self.first_run = QWidget()
        row = QHBoxLayout(self.first_run)
        row.setContentsMargins(4, 2, 4, 2)
        row.addWidget(self.first_step, 1)
        row.addWidget(self.use_suggestions)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.first_run)
        layout.addWidget(self.graphics, 1)
        layout.addWidget(self.warning_label)
        layout.addWidget(hint)
        self.graphics.scene().sigMouseClicked.connect(self._scene_clicked)
        self._show_first_run()

    # ---- data in -------------------------------------------------------------
    @property
    def radius(self) -> float:
        """Window radius in cycles per pixel."""
        return self._radius

    @property
    def labelled(self) -> dict[str, Carrier]:
        """Labelled carriers (operator and model), cycles per pixel, by label."""
        return dict(self._labelled)

    @property
    def warnings(self) -> list[str]:
        """The warning lines shown under the spectrum."""
        text = self.warning_label.text()
        return text.split("\n") if text and self.warning_label.isVisibleTo(self) else []

    def set_spectrum(self, spectrum: np.ndarray) -> None:
        """Show a centred log-magnitude spectrum spanning -0.5..0.5 cycles/px on both axes.

        The levels are set from the first spectrum and then persist
        (:meth:`auto_levels` resets them).
        """
        if self._levels is None:
            self._levels = self._spectrum_levels(spectrum)
            self.image.setImage(spectrum, autoLevels=False, levels=self._levels)
            self.image.setRect(QRectF(-0.5, -0.5, 1.0, 1.0))
            self.plot.setRange(xRange=(-0.5, 0.5), yRange=(-0.5, 0.5), padding=0)
        else:
            self.image.setImage(spectrum, autoLevels=False, levels=self._levels)
            self.image.setRect(QRectF(-0.5, -0.5, 1.0, 1.0))

    def _keep_square(self) -> None:
        """Pad the plot so that its data area is square and centred.

        With the aspect ratio locked, a square data area shows the spectrum's
        -0.5..0.5 cycles/px on both axes and nothing beyond it.
        """
        rect = self.plot.getViewBox().geometry()
        width = rect.width() + 2.0 * self._pad[0]
        height = rect.height() + 2.0 * self._pad[1]
        side = min(width, height)
        pad = ((width - side) / 2.0, (height - side) / 2.0)
        if max(abs(pad[0] - self._pad[0]), abs(pad[1] - self._pad[1])) < 0.5:
            return
        self._pad = pad
        m = SPECTRUM_MARGIN_PX
        self.graphics.ci.setContentsMargins(pad[0] + m, pad[1] + m, pad[0] + m, pad[1] + m)

    def auto_levels(self) -> None:
        """Reset the spectrum levels from the current image."""
        if self.image.image is not None:
            self._levels = self._spectrum_levels(self.image.image)
            self.image.setLevels(self._levels)

    @staticmethod
    def _spectrum_levels(spectrum: np.ndarray) -> tuple[float, float]:
        low, high = np.percentile(spectrum[::4, ::4], (50.0, 99.99))
        return float(low), float(max(high, low + 1e-6))

    def set_peaks(self, peaks: Sequence[Carrier], frame_shape: tuple[int, int]) -> None:
        """Mark detected peaks (cycles per pixel) of frames ``(rows, cols)``; twins too.

        The frame shape sets the FFT bin a click snaps within (:data:`SNAP_BINS` bins).
        """
        self._peaks = [(float(fx), float(fy)) for fx, fy in peaks]
        self._shape = (int(frame_shape[0]), int(frame_shape[1]))
        pts = self._peaks + [(-fx, -fy) for fx, fy in self._peaks]
        self.detected_markers.setData(pos=np.asarray(pts, dtype=float).reshape(-1, 2))

    def set_model(
        self,
        labelled: Mapping[str, Carrier],
        predicted: Mapping[str, Carrier],
        radius: float | None,
        radii: Mapping[str, float] | None = None,
    ) -> None:
        """Draw the labelled peaks with their windows, and the predicted carriers.

        Parameters
        ----------
        labelled : mapping of str to (float, float)
            Every named peak, by the operator or matched by the model, cycles per pixel.
        predicted : mapping of str to (float, float)
            Carriers the model predicts from two labels, cycles per pixel.
        radius : float or None
            Window radius, cycles per pixel (None: automatic, not known yet; the
            circles keep the last radius drawn).
        radii : mapping of str to float, optional
            Each labelled peak's own window radius in use (automatic radii differ
            from peak to peak), cycles per pixel.
        """
        radius = self._radius if radius is None else radius
        labelled = {k: (float(v[0]), float(v[1])) for k, v in labelled.items()}
        predicted = {k: (float(v[0]), float(v[1])) for k, v in predicted.items()}
        radii = {k: float(v) for k, v in (radii or {}).items()}
        if (labelled, predicted, radius, radii) == (
            self._labelled,
            self._predicted,
            self._radius,
            self._radii,
        ):
            return
        self._labelled, self._predicted, self._radius = labelled, predicted, float(radius)
        self._radii = radii
        self._draw_model()

    def _warnings(self) -> list[str]:
        return window_warnings(self._labelled, self._radius, self._predicted, self._radii)

    def _draw_model(self) -> None:
        self._updating = True
        try:
            lab = np.asarray(list(self._labelled.values()), dtype=float).reshape(-1, 2)
            self.labelled_markers.setData(pos=lab)
            pred = np.asarray(list(self._predicted.values()), dtype=float).reshape(-1, 2)
            self.predicted_markers.setData(pos=pred)
            for text in self._texts:
                self.plot.removeItem(text)
            self._texts, self._text_peaks = [], []
            for name, (fx, fy) in self._labelled.items():
                self._add_text(PeakLabel(name, fx, fy), LABEL_COLOUR)
            for name, (fx, fy) in self._predicted.items():
                if name not in self._labelled:
                    self._add_text(PeakLabel(f"{name}?", fx, fy), PREDICTED_COLOUR)
            self._place_texts()
            for name in list(self._circles):
                if name not in self._labelled:
                    self.plot.removeItem(self._circles.pop(name))
            for name, (fx, fy) in self._labelled.items():
                r = self._radii.get(name, self._radius)
                circle = self._circles.get(name)
                if circle is None:
                    circle = pg.CircleROI(
                        [fx - r, fy - r], [2 * r, 2 * r], movable=False, pen=pg.mkPen(LABEL_COLOUR)
                    )
                    circle.setZValue(15)
                    circle.sigRegionChangeFinished.connect(self._circle_dragged)
                    self.plot.addItem(circle)
                    self._circles[name] = circle
                else:
                    circle.setPos([fx - r, fy - r], update=False, finish=False)
                    circle.setSize([2 * r, 2 * r], update=True, finish=False)
        finally:
            self._updating = False
        self._show_warnings(self._warnings())
        self._show_first_run()

    def set_suggestions(self, labels: Mapping[str, Carrier], where: str = "") -> None:
        """Show the labels a source suggests (grey, dashed) while no peak is labelled.

        Parameters
        ----------
        labels : mapping of str to (float, float)
            Suggested label and carrier, cycles per pixel; empty: no suggestion.
        where : str
            Where they come from, for the hint (``the simulator's setup``).
        """
        suggested = {k: (float(v[0]), float(v[1])) for k, v in labels.items()}
        if suggested == self._suggested and where == self._suggested_from:
            return
        self._suggested, self._suggested_from = suggested, where
        self._show_first_run()

    @property
    def suggestions(self) -> dict[str, Carrier]:
        """The suggested labels drawn now (none once a peak is labelled)."""
        return dict(self._suggested) if self._suggestion_items else {}

    def _show_first_run(self) -> None:
        """The first step's hint and the suggestions, while no peak is labelled."""
        for item in self._suggestion_items:
            self.plot.removeItem(item)
        self._suggestion_items = []
        first = not self._labelled
        self.first_run.setVisible(first)
        offer = first and bool(self._suggested)
        self.use_suggestions.setVisible(offer)
        if not offer:
            self.first_step.setText(FIRST_STEP)
            return
        names = ", ".join(self._suggested)
        where = self._suggested_from or "the source"
        self.first_step.setText(
            f"No peak labelled yet. Suggested by {where}: {names} (grey, dashed). "
            "Use them, or click a peak to name it."
        )
        r = self._radius
        pen = pg.mkPen(SUGGESTED_COLOUR, width=1.5, style=Qt.PenStyle.DashLine)
        for name, (fx, fy) in self._suggested.items():
            circle = QGraphicsEllipseItem(fx - r, fy - r, 2 * r, 2 * r)
            circle.setPen(pen)
            text = pg.TextItem(name, color=SUGGESTED_COLOUR, anchor=(0, 1))
            text.setPos(fx + 0.01, fy - 0.01)
            for item in (circle, text):
                item.setZValue(15)
                self.plot.addItem(item)
                self._suggestion_items.append(item)

    def _add_text(self, label: PeakLabel, colour: str) -> None:
        item = pg.TextItem(label.text, color=colour, anchor=(0, 1))
        item.textItem.document().setDocumentMargin(1)  # the box drawn is the text's own
        item.setZValue(25)
        self.plot.addItem(item)
        self._texts.append(item)
        self._text_peaks.append(label)

    def _place_texts(self) -> None:
        """Set each peak label beside its peak, clear of the other labels and peaks."""
        if not self._texts:
            return
        px, py = self.plot.getViewBox().viewPixelSize()
        (x0, x1), (y0, y1) = self.plot.getViewBox().viewRange()
        height = max(item.boundingRect().height() for item in self._texts)
        width = max(
            item.boundingRect().width() / max(len(peak.text), 1)
            for peak, item in zip(self._text_peaks, self._texts, strict=True)
        )
        spots = place_labels(
            self._text_peaks,
            char_size=(width * px, height * py),
            view=(x0, y0, x1, y1),
            marker=LABEL_MARKER_PX / 2 * px,
        )
        for item, spot in zip(self._texts, spots, strict=True):
            item.setAnchor(spot.anchor)
            item.setPos(*spot.pos)

    @property
    def label_boxes(self) -> dict[str, QRectF]:
        """Each peak label's box as drawn, in scene coordinates."""
        return {
            peak.text: item.mapRectToScene(item.boundingRect())
            for peak, item in zip(self._text_peaks, self._texts, strict=True)
        }

    def set_notes(self, notes: tuple[str, ...]) -> None:
        """Show ``notes`` (from the labelling) under the window warnings."""
        if tuple(notes) != self._notes:
            self._notes = tuple(notes)
            self._show_warnings(self._warnings())

    def _show_warnings(self, lines: list[str]) -> None:
        lines = [*lines, *self._notes]
        self.warning_label.setText("\n".join(lines))
        self.warning_label.setVisible(bool(lines))

    # ---- operator input -----------------------------------------------------
    def click_at(self, fx: float, fy: float) -> None:
        """Handle a click at carrier ``(fx, fy)``: snap to a peak and ask for its label."""
        found = snap((fx, fy), self._peaks, self._shape)
        if found is None:
            self.message.emit(
                f"no peak within {SNAP_BINS:g} FFT bins of ({fx:+.3f}, {fy:+.3f}) cycles/px: "
                "nothing labelled"
            )
            return
        index, twin = found
        px, py = self._peaks[index]
        snapped = (-px, -py) if twin else (px, py)
        current = next((n for n, f in self._labelled.items() if math.dist(f, snapped) < 1e-6), None)
        choice = self.choose_label(snapped, current)
        if choice is None:
            return
        if choice == CLEAR:
            if current is not None:
                self.labelCleared.emit(current)
            return
        self.peakLabelled.emit(choice, snapped[0], snapped[1])

    def _scene_clicked(self, event: MouseClickEvent) -> None:
        if event.button().name != "LeftButton" or event.isAccepted():
            return
        pos = event.scenePos()
        if not self.plot.vb.sceneBoundingRect().contains(pos):
            return
        point = self.plot.vb.mapSceneToView(pos)
        event.accept()
        self.click_at(point.x(), point.y())

    def request_radius(self, label: str, radius: float) -> bool:
        """Ask for a new window radius around ``label``; refuse one that reaches zero frequency.

        A radius that swallows another peak is used as asked, with a warning naming the
        peak (:attr:`message`): its content leaks into the map. Returns whether the
        radius was accepted (then :attr:`radiusChanged` is emitted).
        """
        centre = self._labelled.get(label)
        if centre is None:
            return False
        if radius <= 0 or radius >= math.hypot(*centre):
            self.message.emit(
                f"radius {radius:.3f} cycles/px around {label} would reach zero frequency: "
                f"kept {self._radii.get(label, self._radius):.3f}"
            )
            self._draw_model()
            return False
        others = [
            p for p in (*self._peaks, *self._labelled.values()) if math.dist(p, centre) > 1e-6
        ]
        swallowed = swallowed_neighbour(centre, radius, others)
        if swallowed is not None:
            self.message.emit(
                f"radius {radius:.3f} cycles/px around {label} swallows the peak at "
                f"({swallowed[0]:+.3f}, {swallowed[1]:+.3f}): its content leaks into the map"
            )
        self._radius = float(radius)
        self._radii = {}  # one radius for every peak from now on
        self._draw_model()
        self.radiusChanged.emit(self._radius)
        return True

    def _circle_dragged(self, circle: pg.CircleROI) -> None:
        if self._updating:
            return
        label = next((n for n, c in self._circles.items() if c is circle), None)
        if label is None:
            return
        radius = float(circle.size()[0]) / 2.0
        if abs(radius - self._radii.get(label, self._radius)) > 1e-9:
            self.request_radius(label, radius)
