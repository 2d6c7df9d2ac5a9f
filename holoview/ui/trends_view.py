"""Mean depth change per peak and fused against time, with the evaporation rate.

Two modes. Live (a camera): the series of the frames as they come, from the live
engine. A replayed file: the whole run, measured when the file opens
(:mod:`holoview.headless.run_series`), drawn at once; a vertical cursor marks the
frame the replay shows (dragging it asks for another frame), and with "Fit a range"
a region of the plot picks a time range whose rate is fitted (the rate ``holoview
process --frames A:B`` gives). The view only draws: what it shows comes from the
window.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pyqtgraph as pg
from PyQt6.QtCore import QEvent, QObject, Qt, pyqtSignal
from PyQt6.QtGui import QResizeEvent
from PyQt6.QtWidgets import (
    QCheckBox,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from holoview.processing.series.rate_fits import format_rate
from holoview.ui.legends import curve_pen, fit_legend, side_legend

#: What the empty view says before a peak is labelled.
NO_TRENDS = (
    "Trends start once a peak is labelled in the Spectrum: the mean depth change of "
    "every labelled peak and the fused depth, from every camera frame."
)
#: What the empty view says after a replay jumped (a seek, a step back, a loop).
JUMPED = (
    "The replay jumped: the trends start over from the frame shown (no rate is fitted "
    "across a jump) and are drawn from the third frame played on."
)
#: What the view says while a replayed file's whole run is measured.
MEASURING = "Measuring the whole run: its trends and rates appear when every frame is measured."
#: Pens of the cursor (the frame shown) and of the range's fitted line.
CURSOR_PEN = pg.mkPen("#ffd700", width=1)
RANGE_PEN = pg.mkPen("#00e5ff", width=2)
#: The range region's fill.
RANGE_BRUSH = pg.mkBrush(0, 229, 255, 40)


class TrendsView(QWidget):
    """Depth change against time per peak and fused; rate, PCA confidence and prefactors.

    Signals
    -------
    pcaRequested(bool)
        The operator asked for (or stopped asking for) the PCA identification.
    resetRequested()
        The operator asked to restart the series from now.
    cursorMoved(float)
        The operator dragged the cursor to this time, s (a replayed run).
    rangeChosen(float, float)
        The operator chose a time range to fit, s (a replayed run).
    rangeCleared()
        The operator put the range away.
    """

    pcaRequested = pyqtSignal(bool)
    resetRequested = pyqtSignal()
    cursorMoved = pyqtSignal(float)
    rangeChosen = pyqtSignal(float, float)
    rangeCleared = pyqtSignal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.plot = pg.PlotWidget()
        self.plot.setLabel("bottom", "time", units="s")
        self.plot.setLabel("left", "depth change (nm)")
        self.plot.getAxis("left").enableAutoSIPrefix(False)
        self.legend = side_legend(self.plot.getPlotItem())
        self.plot.installEventFilter(self)  # resized: the legend's columns (fit_legend)
        self.plot.showGrid(x=True, y=True, alpha=0.3)
        self.curves: dict[str, pg.PlotDataItem] = {}
        self.fit_curve = pg.PlotDataItem(pen=pg.mkPen("y", width=1, style=Qt.PenStyle.DotLine))
        self.plot.addItem(self.fit_curve)
        self.cursor_line = pg.InfiniteLine(angle=90, movable=True, pen=CURSOR_PEN)
        self.cursor_line.setToolTip("the frame the replay shows: drag to go to another")
        self.cursor_line.setZValue(10)
        self.cursor_line.sigDragged.connect(lambda line: self.cursorMoved.emit(float(line.value())))
        self.cursor_line.setVisible(False)
        self.plot.addItem(self.cursor_line, ignoreBounds=True)
        self.region = pg.LinearRegionItem(brush=RANGE_BRUSH)
        self.region.setZValue(-10)
        self.region.setVisible(False)
        self.region.sigRegionChangeFinished.connect(self._region_changed)
        self.plot.addItem(self.region, ignoreBounds=True)
        self.range_curve = pg.PlotDataItem(pen=RANGE_PEN)
        self.plot.addItem(self.range_curve)
        self.rate_label = QLabel("evaporation rate: waiting for data")
        self.rate_label.setStyleSheet("font-weight: bold;")
        self.rate_label.setWordWrap(True)
        self.pca_box = QCheckBox("PCA identification")
        self.pca_box.toggled.connect(self.pcaRequested.emit)
        self.reset_button = QPushButton("Restart series")
        self.reset_button.setToolTip("start the series and the absolute reference from now")
        self.reset_button.clicked.connect(self.resetRequested.emit)
        self.range_button = QPushButton("Fit a range")
        self.range_button.setCheckable(True)
        self.range_button.setToolTip(
            "choose a time range on the plot (drag its edges): its rate is fitted, as "
            "holoview process --frames A:B gives it"
        )
        self.range_button.toggled.connect(self._range_toggled)
        self.range_button.setVisible(False)
        self.progress = QProgressBar()
        self.progress.setVisible(False)
        self.range_label = QLabel()
        self.range_label.setWordWrap(True)
        self.range_label.setStyleSheet("color: #00e5ff;")
        self.range_label.setVisible(False)
        self.pca_label = QLabel()
        self.pca_label.setWordWrap(True)
        row = QHBoxLayout()
        row.addWidget(self.rate_label, 1)
        row.addWidget(self.range_button)
        row.addWidget(self.pca_box)
        row.addWidget(self.reset_button)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        self.empty_hint = QLabel(NO_TRENDS)
        self.empty_hint.setWordWrap(True)
        self.empty_hint.setStyleSheet("color: gray;")
        layout.addLayout(row)
        layout.addWidget(self.progress)
        layout.addWidget(self.range_label)
        layout.addWidget(self.empty_hint)
        layout.addWidget(self.plot, 1)
        layout.addWidget(self.pca_label)

    # ---- the series --------------------------------------------------------
    def set_series(
        self,
        times_s: np.ndarray,
        depths_m: Mapping[str, np.ndarray],
        *,
        jumped: bool = False,
        hint: str | None = None,
    ) -> None:
        """Show the mean depth change (metres, shown in nm) of each series against time (s).

        With no series the view says how they come: ``hint`` when given, else that a
        replay jumped (``jumped``: the series start over), else that a peak must be
        labelled.
        """
        self.empty_hint.setText(hint or (JUMPED if jumped else NO_TRENDS))
        self.empty_hint.setVisible(not depths_m)
        named = set(self.curves)
        for name in list(self.curves):
            if name not in depths_m:
                self.plot.removeItem(self.curves.pop(name))
        for i, (name, depth) in enumerate(depths_m.items()):
            curve = self.curves.get(name)
            if curve is None:
                pen = curve_pen(name, i)
                curve = self.curves[name] = self.plot.plot([], [], pen=pen, name=name)
                curve.setDownsampling(auto=True, method="peak")
                curve.setClipToView(True)
            curve.setData(np.asarray(times_s), np.asarray(depth) * 1e9)
        if set(self.curves) != named:
            self._fit_legend()
        # the auto range now, not as the paint starts: there it changes the view again
        # and the plot is painted twice (axes, ticks and curves: 21 ms a paint at 1920 px)
        self.plot.getViewBox().prepareForPaint()

    def eventFilter(self, watched: QObject | None, event: QEvent | None) -> bool:
        """The plot resized: its legend's columns again (:func:`fit_legend`)."""
        if watched is self.plot and isinstance(event, QResizeEvent):
            self._fit_legend(event.size().height())
        return super().eventFilter(watched, event)

    def _fit_legend(self, height_px: int | None = None) -> None:
        """The legend's columns for the plot's height (now, or ``height_px`` it is given)."""
        height = self.plot.height() if height_px is None else height_px
        fit_legend(self.plot.getPlotItem(), self.legend, height - 2 * self.plot.frameWidth())

    def set_rate(
        self,
        rate_m_per_s: float | None,
        stderr_m_per_s: float | None = None,
        fit: tuple[Sequence[float], Sequence[float]] | None = None,
        *,
        caption: str = "evaporation rate",
    ) -> None:
        """Show the evaporation rate with its standard error, and the fitted line.

        Parameters
        ----------
        rate_m_per_s, stderr_m_per_s : float or None
            Rate of the fused depth change and its standard error, metres per second
            (shown in µm/min). None: not enough data yet.
        fit : (times_s, depths_m), optional
            Two or more points of the fitted line.
        caption : str
            What the rate is (``"whole run (300 frames, camera clock)"``).
        """
        if rate_m_per_s is None or not np.isfinite(rate_m_per_s):
            self.rate_label.setText(f"{caption}: waiting for data")
            self.fit_curve.setData([], [])
            return
        self.rate_label.setText(f"{caption}: " + format_rate(rate_m_per_s, stderr_m_per_s or 0.0))
        if fit is not None:
            self.fit_curve.setData(np.asarray(fit[0]), np.asarray(fit[1]) * 1e9)

    def set_pca(self, confidence: float | None, prefactors: Mapping[str, float] | None) -> None:
        """Show the PCA confidence (0..1) and the prefactor per peak, or hide them (None)."""
        if confidence is None:
            self.pca_label.clear()
            return
        parts = ", ".join(f"{k}: {v:.3f}" for k, v in (prefactors or {}).items())
        self.pca_label.setText(
            f"PCA confidence sg_p = {confidence * 100:.2f} %; prefactors {parts}"
        )

    # ---- a replayed run ----------------------------------------------------
    def set_run_mode(self, on: bool) -> None:
        """Show a whole run (cursor, range fits) or the live series (restart button)."""
        self.reset_button.setVisible(not on)
        self.range_button.setVisible(on)
        if not on:
            self.range_button.setChecked(False)
            self.set_cursor(None)
            self.set_progress(None)

    def set_progress(self, done: int | None, total: int = 0, text: str = "") -> None:
        """Show a measurement's progress (``done`` of ``total`` frames), or hide it (None)."""
        if done is None:
            self.progress.setVisible(False)
            return
        self.progress.setRange(0, max(1, total))
        self.progress.setValue(min(done, total))
        self.progress.setFormat(f"{text} %v / %m frames")
        self.progress.setVisible(True)

    def set_cursor(self, time_s: float | None) -> None:
        """Put the cursor at ``time_s`` (s), or hide it (None or NaN)."""
        if time_s is None or not np.isfinite(time_s):
            self.cursor_line.setVisible(False)
            return
        if self.cursor_line.value() != time_s and not self.cursor_line.moving:
            self.cursor_line.setValue(time_s)
        self.cursor_line.setVisible(True)

    def set_range_fit(
        self, text: str | None, line: tuple[Sequence[float], Sequence[float]] | None = None
    ) -> None:
        """Say what the range fit gave (None: nothing) and draw its line (times s, depths m)."""
        self.range_label.setText(text or "")
        self.range_label.setVisible(bool(text))
        if line is None:
            self.range_curve.setData([], [])
        else:
            self.range_curve.setData(np.asarray(line[0]), np.asarray(line[1]) * 1e9)

    def chosen_range(self) -> tuple[float, float] | None:
        """The time range chosen, s (None while "Fit a range" is off)."""
        if not self.range_button.isChecked():
            return None
        low, high = self.region.getRegion()
        return float(low), float(high)

    def choose_range(self, t0_s: float, t1_s: float) -> None:
        """Show the range ``[t0_s, t1_s]`` (s) and ask for its fit, as a drag does."""
        self.range_button.setChecked(True)
        self.region.setRegion((t0_s, t1_s))
        self._region_changed()

    def _range_toggled(self, on: bool) -> None:
        self.region.setVisible(on)
        if not on:
            self.set_range_fit(None)
            self.rangeCleared.emit()
            return
        times = [c.xData for c in self.curves.values() if c.xData is not None and len(c.xData)]
        if times:  # the middle half of the run to start with
            start, end = float(times[0][0]), float(times[0][-1])
            quarter = (end - start) / 4
            self.region.blockSignals(True)
            self.region.setRegion((start + quarter, end - quarter))
            self.region.blockSignals(False)
        self._region_changed()

    def _region_changed(self) -> None:
        chosen = self.chosen_range()
        if chosen is not None:
            self.rangeChosen.emit(*chosen)
