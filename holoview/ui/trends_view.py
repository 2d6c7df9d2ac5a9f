"""Mean depth change per peak and fused against time, with the evaporation rate."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pyqtgraph as pg
from PyQt6.QtCore import Qt, pyqtSignal
from PyQt6.QtWidgets import QCheckBox, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from holoview.processing.series.rate_fits import format_rate
from holoview.ui.legends import curve_pen, side_legend

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


class TrendsView(QWidget):
    """Depth change against time per peak and fused; rate, PCA confidence and prefactors.

    Signals
    -------
    pcaRequested(bool)
        The operator asked for (or stopped asking for) the PCA identification.
    resetRequested()
        The operator asked to restart the series from now.
    """

    pcaRequested = pyqtSignal(bool)
    resetRequested = pyqtSignal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.plot = pg.PlotWidget()
        self.plot.setLabel("bottom", "time", units="s")
        self.plot.setLabel("left", "mean depth change (nm)")
        self.plot.getAxis("left").enableAutoSIPrefix(False)
        self.legend = side_legend(self.plot.getPlotItem())
        self.plot.showGrid(x=True, y=True, alpha=0.3)
        self.curves: dict[str, pg.PlotDataItem] = {}
        self.fit_curve = pg.PlotDataItem(pen=pg.mkPen("y", width=1, style=Qt.PenStyle.DotLine))
        self.plot.addItem(self.fit_curve)
        self.rate_label = QLabel("evaporation rate: waiting for data")
        self.rate_label.setStyleSheet("font-weight: bold;")
        self.pca_box = QCheckBox("PCA identification")
        self.pca_box.toggled.connect(self.pcaRequested.emit)
        self.reset_button = QPushButton("Restart series")
        self.reset_button.setToolTip("start the series and the absolute reference from now")
        self.reset_button.clicked.connect(self.resetRequested.emit)
        self.pca_label = QLabel()
        self.pca_label.setWordWrap(True)
        row = QHBoxLayout()
        row.addWidget(self.rate_label, 1)
        row.addWidget(self.pca_box)
        row.addWidget(self.reset_button)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        self.empty_hint = QLabel(NO_TRENDS)
        self.empty_hint.setWordWrap(True)
        self.empty_hint.setStyleSheet("color: gray;")
        layout.addLayout(row)
        layout.addWidget(self.empty_hint)
        layout.addWidget(self.plot, 1)
        layout.addWidget(self.pca_label)

    def set_series(
        self, times_s: np.ndarray, depths_m: Mapping[str, np.ndarray], *, jumped: bool = False
    ) -> None:
        """Show the mean depth change (metres, shown in nm) of each series against time (s).

        With no series the view says how they come: ``jumped`` says a replay jumped
        (the series start over), else that a peak must be labelled.
        """
        self.empty_hint.setText(JUMPED if jumped else NO_TRENDS)
        self.empty_hint.setVisible(not depths_m)
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

    def set_rate(
        self,
        rate_m_per_s: float | None,
        stderr_m_per_s: float | None = None,
        fit: tuple[Sequence[float], Sequence[float]] | None = None,
    ) -> None:
        """Show the evaporation rate with its standard error, and the fitted line.

        Parameters
        ----------
        rate_m_per_s, stderr_m_per_s : float or None
            Rate of the fused depth change and its standard error, metres per second
            (shown in µm/min). None: not enough data yet.
        fit : (times_s, depths_m), optional
            Two or more points of the fitted line.
        """
        if rate_m_per_s is None or not np.isfinite(rate_m_per_s):
            self.rate_label.setText("evaporation rate: waiting for data")
            self.fit_curve.setData([], [])
            return
        self.rate_label.setText(
            "evaporation rate: " + format_rate(rate_m_per_s, stderr_m_per_s or 0.0)
        )
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
