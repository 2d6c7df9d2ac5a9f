"""The Waves panel: the omega-k spectrum of one map's last N frames, its dispersion fit, (m, f).

It draws a :class:`~holoview.live.wave_window.LiveWaves` (computed by the waves worker,
:mod:`holoview.live.wave_worker`) and turns its controls into
:class:`~holoview.live.wave_window.WaveSettings`:

- the omega-k power along a direction (signed wavenumber ``q`` in rad/m, as in the fits'
  messages and the command line's options: negative for waves travelling against the
  direction; frequency in Hz up to half the map rate),
  the window's cut-off ``+-k_cut`` dashed, the fitted dispersion relation drawn over
  it (the fluid's nominal one, dotted, before a fit);
- sigma, d and U with their standard errors (or held);
- the newest map (the field view): a click sets the centre of the (m, f) spectrum,
  drawn beside it;
- the rate of the maps and what cuts the frequency axis, and each problem in one line.
"""

from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg
from PyQt6.QtCore import QPointF, QRectF, Qt, pyqtSignal
from PyQt6.QtGui import QCloseEvent, QResizeEvent
from PyQt6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from holoview.live.wave_window import FUSED, LiveWaves, WaveSettings
from holoview.optics.surfaces import FLUID_MECHANICS
from holoview.processing.waves.dispersion import DispersionFit, Fluid, wave_omega
from holoview.processing.waves.fit_text import fit_values

#: Frames the panel can keep (the window analysed).
LENGTHS = (128, 256, 512, 1024)
#: Points of the dispersion curves.
CURVE_POINTS = 400
#: The parameters the fit can hold, and their names on the check boxes.
HOLDS = (("sigma", "σ"), ("depth", "d"), ("flow", "U"))
#: Width over height of the plots' area above which they stand in one row.
ROW_ASPECT = 2.0
#: CPU share of a map's time below which the panel says the rest was waiting (the machine's
#: other work, or the GIL): the map is then slow because the processor is busy, not itself.
WAITING_SHARE = 0.5
#: The plots' titles' size (small: they share a dock with the Trends).
TITLE_SIZE = "9pt"
#: The (m, f) plot's title without a centre.
NO_CENTRE = "(m, f): click the map"
#: What the panel says before its first analysis.
WAITING = "waiting for the first maps (label a peak in the Spectrum)"


def segment_for(length: int) -> int:
    """Frames per Welch segment for a window of ``length`` frames (a quarter, at least 16)."""
    return max(16, length // 4)


def _log_image(power: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
    """log10 of ``power`` (floored) and display levels (1st to 99.9th percentile)."""
    positive = power[power > 0]
    floor = float(positive.min()) if positive.size else 1e-30
    image = np.log10(np.maximum(power, floor)).astype(np.float32)
    low, high = (float(v) for v in np.percentile(image, [1.0, 99.9]))
    return image, (low, high if high > low else low + 1.0)


def _fit_text(fit: DispersionFit) -> str:
    """sigma, d and U with their standard errors (or 'held'), in mN/m, mm, mm/s."""
    sigma, depth, flow = fit_values(fit)
    return f"σ = {sigma}   d = {depth}   U = {flow}"


def rate_text(waves: LiveWaves) -> str:
    """The maps' rate, what cuts the frequency axis, gaps and the cut-off, in words."""
    parts = [f"{waves.label}: {waves.frames} maps"]
    if waves.rate > 0:
        parts[0] += f" at {waves.rate:.4g} maps/s"
    if waves.stride == 1:
        parts.append(
            f"every camera frame; f up to {waves.nyquist:.4g} Hz (half the map rate)"
            if waves.rate > 0
            else "every camera frame"
        )
    else:
        camera = f"{waves.camera_rate:.4g} frames/s" if waves.camera_rate > 0 else "frames"
        cost = ""
        if waves.map_seconds > 0 and waves.camera_rate > 0:
            took = f"a map takes {waves.map_seconds * 1e3:.3g} ms"
            if 0 < waves.map_cpu_seconds < WAITING_SHARE * waves.map_seconds:
                took += (
                    f", {waves.map_cpu_seconds * 1e3:.3g} ms of it computing and the rest "
                    "waiting for the processor"
                )
            cost = f" ({took}, a frame comes every {1e3 / waves.camera_rate:.3g} ms)"
        parts.append(
            f"1 camera frame in {waves.stride} of {camera}: this machine cannot demodulate "
            f"this map at the camera's rate{cost}, so f is cut at {waves.nyquist:.4g} Hz, "
            "half the map rate (not the camera's)"
        )
    if waves.gaps:
        gaps = "1 gap" if waves.gaps == 1 else f"{waves.gaps} gaps"
        parts.append(f"{gaps} (lost frames) left open: no segment spans one")
    spectrum = waves.spectrum
    if spectrum is not None:
        parts.append(
            f"k cut-off {spectrum.k_cut:.0f} rad/m (the demodulation window, dashed); "
            f"{spectrum.segments} segment{'s' if spectrum.segments != 1 else ''} of "
            f"{spectrum.power.shape[0] * 2 - 2} maps"
        )
    return "; ".join(parts)


class WavesView(QWidget):
    """The Waves panel (module docstring).

    Signals
    -------
    settingsChanged(object)
        The operator changed the map, window, fluid, held values or the centre: the
        new :class:`~holoview.live.wave_window.WaveSettings`.
    """

    settingsChanged = pyqtSignal(object)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._centre: tuple[float, float] | None = None
        self._waves: LiveWaves | None = None
        self._field_rect = QRectF()
        self.map_box = QComboBox()
        self.map_box.addItem(FUSED)
        self.map_box.setToolTip("the map whose waves are analysed")
        self.length_box = QComboBox()
        for n in LENGTHS:
            self.length_box.addItem(f"{n} frames", n)
        self.length_box.setCurrentIndex(1)
        self.length_box.setToolTip("maps kept and analysed (the newest)")
        self.direction = QSpinBox()
        self.direction.setRange(-180, 180)
        self.direction.setSuffix("°")
        self.direction.setToolTip("direction of the omega-k cut (0: along x, 90: along y)")
        self.fluid_box = QComboBox()
        for name in FLUID_MECHANICS:
            self.fluid_box.addItem(name)
        self.depth_box = QDoubleSpinBox()
        self.depth_box.setRange(0.01, 10000.0)
        self.depth_box.setDecimals(2)
        self.depth_box.setValue(5.0)
        self.depth_box.setSuffix(" mm")
        self.depth_box.setToolTip("depth: where the fit starts, or the value held")
        self.hold = {name: QCheckBox(f"hold {text}") for name, text in HOLDS}
        self.clear_centre = QPushButton("Clear centre")
        self.clear_centre.setToolTip("click the field view to set the centre of the (m, f) view")
        top, second = QHBoxLayout(), QHBoxLayout()
        for row, items in (
            (top, (("map", self.map_box), ("window", self.length_box), ("cut", self.direction))),
            (second, (("fluid", self.fluid_box), ("d", self.depth_box))),
        ):
            for text, widget in items:
                row.addWidget(QLabel(text))
                row.addWidget(widget)
        top.addWidget(self.clear_centre)
        for box in self.hold.values():
            second.addWidget(box)
        for row in (top, second):
            row.addStretch(1)
        self.fit_label = QLabel("σ, d, U: no fit yet")
        self.fit_label.setStyleSheet("font-weight: bold;")
        self.fit_label.setWordWrap(True)
        self.rate_label = QLabel()
        self.rate_label.setWordWrap(True)
        self.message_label = QLabel(WAITING)
        self.message_label.setWordWrap(True)
        self.message_label.setStyleSheet("color: #b02a37;")
        self.graphics = pg.GraphicsLayoutWidget()
        self._make_plots()
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addLayout(top)
        layout.addLayout(second)
        layout.addWidget(self.fit_label)
        layout.addWidget(self.rate_label)
        layout.addWidget(self.message_label)
        layout.addWidget(self.graphics, 1)
        for combo in (self.map_box, self.length_box, self.fluid_box):
            combo.currentIndexChanged.connect(self._emit)
        self.depth_box.valueChanged.connect(self._emit)
        for box in self.hold.values():
            box.toggled.connect(self._emit)
        self.direction.valueChanged.connect(self._redraw)
        self.clear_centre.clicked.connect(lambda: self.set_centre(None))
        self.graphics.scene().sigMouseClicked.connect(self._clicked)

    def _make_plots(self) -> None:
        self.omega_k = self.graphics.addPlot(row=0, col=0)
        self.omega_k.setLabel("bottom", "q (rad/m); colour: log power")
        self.omega_k.setLabel("left", "f (Hz)")
        self.omega_k_image = pg.ImageItem(axisOrder="row-major")
        self.omega_k_image.setColorMap(pg.colormap.get("inferno"))
        self.omega_k.addItem(self.omega_k_image)
        dashed = pg.mkPen("c", width=1, style=Qt.PenStyle.DashLine)
        self.cut_lines = [pg.InfiniteLine(angle=90, pen=dashed) for _ in range(2)]
        for line in self.cut_lines:
            line.setVisible(False)
            self.omega_k.addItem(line)
        self.fit_curve = pg.PlotDataItem(pen=pg.mkPen("#00e676", width=2), connect="finite")
        self.nominal_curve = pg.PlotDataItem(
            pen=pg.mkPen("w", width=1, style=Qt.PenStyle.DotLine), connect="finite"
        )
        self.omega_k.addItem(self.nominal_curve)
        self.omega_k.addItem(self.fit_curve)
        self.field = self.graphics.addPlot(row=0, col=1)
        self.field.setLabel("bottom", "x (mm)")
        self.field.setLabel("left", "y (mm)")
        self.field.setTitle("map · click: centre", size=TITLE_SIZE)
        self.field.invertY(True)
        self.field.setAspectLocked(True)
        self.field_image = pg.ImageItem(axisOrder="row-major")
        self.field_image.setColorMap(pg.colormap.get("viridis"))
        self.field.addItem(self.field_image)
        self.centre_mark = pg.ScatterPlotItem(
            size=14, symbol="+", pen=pg.mkPen("r", width=2), brush=None
        )
        self.field.addItem(self.centre_mark)
        self.mf = self.graphics.addPlot(row=0, col=2)
        self.mf.setLabel("bottom", "f (Hz)")
        self.mf.setLabel("left", "m")
        self.mf.setTitle(NO_CENTRE, size=TITLE_SIZE)
        self.mf_image = pg.ImageItem(axisOrder="row-major")
        self.mf_image.setColorMap(pg.colormap.get("inferno"))
        self.mf.addItem(self.mf_image)
        for plot in (self.omega_k, self.field, self.mf):
            for side in ("bottom", "left"):
                plot.getAxis(side).enableAutoSIPrefix(False)
        self._in_row = True
        self._arrange(in_row=False)

    def _arrange(self, *, in_row: bool) -> None:
        """The three plots in one row (a wide, short panel), or the spectrum on the left
        and the map over (m, f) on its right (a taller one): each keeps a readable shape."""
        if in_row == self._in_row:
            return
        self._in_row = in_row
        layout = self.graphics.ci
        for plot in (self.omega_k, self.field, self.mf):
            layout.removeItem(plot)
        if in_row:
            layout.addItem(self.omega_k, row=0, col=0)
            layout.addItem(self.field, row=0, col=1)
            layout.addItem(self.mf, row=0, col=2)
            stretches = (2, 1, 1)
        else:
            layout.addItem(self.omega_k, row=0, col=0, rowspan=2)
            layout.addItem(self.field, row=0, col=1)
            layout.addItem(self.mf, row=1, col=1)
            stretches = (3, 2, 0)
        for col, stretch in enumerate(stretches):
            layout.layout.setColumnStretchFactor(col, stretch)

    def resizeEvent(self, event: QResizeEvent | None) -> None:
        """Arrange the plots for the panel's shape (:meth:`_arrange`)."""
        super().resizeEvent(event)
        if not self.released:
            size = self.graphics.size()
            self._arrange(in_row=size.width() > ROW_ASPECT * size.height())

    # ---- life cycle ----------------------------------------------------------
    @property
    def released(self) -> bool:
        """True once :meth:`release` has run (the plots are gone)."""
        return bool(self.graphics.closed)

    def release(self) -> None:
        """Take the plots down before the view is deleted; calling it again does nothing.

        A pyqtgraph view deleted with a paint or a range update pending can reach an
        axis whose C++ side is already gone ("AxisItem has been deleted"), which crashed
        the process once. So the clicks are disconnected, the items dropped and the scene
        emptied and detached from its viewport here (:meth:`pyqtgraph.GraphicsView.close`),
        while every item is still alive; the Qt deletion that follows has nothing to paint.
        """
        if self.released:
            return
        self.graphics.scene().sigMouseClicked.disconnect(self._clicked)
        self._waves = None
        self.graphics.clear()
        self.graphics.close()

    def closeEvent(self, event: QCloseEvent | None) -> None:
        """Closed as a window of its own (a test, a script): release the plots first."""
        self.release()
        super().closeEvent(event)

    # ---- settings ----------------------------------------------------------
    def settings(self) -> WaveSettings:
        """The settings the controls and the centre say."""
        length = int(self.length_box.currentData())
        return WaveSettings(
            label=self.map_box.currentText() or FUSED,
            length=length,
            segment=segment_for(length),
            fluid=Fluid.named(self.fluid_box.currentText()),
            depth=self.depth_box.value() * 1e-3,
            hold=tuple(name for name, box in self.hold.items() if box.isChecked()),
            centre=self._centre,
        )

    def _emit(self) -> None:
        self.settingsChanged.emit(self.settings())

    def set_labels(self, labels: list[str]) -> None:
        """Offer the maps of ``labels`` (peaks with a height) and the fused map."""
        items = [*labels, FUSED]
        if [self.map_box.itemText(i) for i in range(self.map_box.count())] == items:
            return
        current = self.map_box.currentText()
        self.map_box.blockSignals(True)
        self.map_box.clear()
        self.map_box.addItems(items)
        self.map_box.setCurrentIndex(items.index(current) if current in items else 0)
        self.map_box.blockSignals(False)
        if self.map_box.currentText() != current:
            self._emit()

    def choose_map(self, label: str) -> None:
        """Analyse the map ``label`` (offered by :meth:`set_labels`)."""
        self.map_box.setCurrentText(label)

    def set_centre(self, centre: tuple[float, float] | None) -> None:
        """Centre the (m, f) view at ``(x, y)`` m (None: no (m, f) view)."""
        self._centre = centre
        if not self.released:
            x, y = ([], []) if centre is None else ([centre[0] * 1e3], [centre[1] * 1e3])
            self.centre_mark.setData(x, y)
        self._emit()

    def _clicked(self, event: object) -> None:
        pos = event.scenePos()  # type: ignore[attr-defined]
        if not self.field.sceneBoundingRect().contains(pos):
            return
        point: QPointF = self.field.getViewBox().mapSceneToView(pos)
        self.set_centre((point.x() * 1e-3, point.y() * 1e-3))

    # ---- drawing -------------------------------------------------------------
    def set_waves(self, waves: LiveWaves) -> None:
        """Draw an analysis: spectra, fit, rates and problems (nothing once released)."""
        if self.released:
            return
        self._waves = waves
        self.message_label.setText("\n".join(waves.problems))
        self.message_label.setVisible(bool(waves.problems))
        self.rate_label.setText(rate_text(waves))
        self.fit_label.setText(_fit_text(waves.fit) if waves.fit else "σ, d, U: no fit")
        self._draw_field(waves)
        self._draw_mf(waves)
        self._redraw()

    def _redraw(self) -> None:
        if self.released:
            return
        waves = self._waves
        spectrum = None if waves is None else waves.spectrum
        if waves is None or spectrum is None:
            self.omega_k_image.clear()
            self.fit_curve.setData([], [])
            self.nominal_curve.setData([], [])
            for line in self.cut_lines:
                line.setVisible(False)
            return
        angle = math.radians(self.direction.value())
        q, power = spectrum.along(angle)
        image, levels = _log_image(power)
        self.omega_k_image.setImage(image, levels=levels)
        dq, df = q[1] - q[0], spectrum.df
        self.omega_k_image.setRect(
            QRectF(q[0] - dq / 2, -df / 2, dq * q.size, df * spectrum.frequency.size)
        )
        cut = spectrum.k_cut
        for line, value in zip(self.cut_lines, (-cut, cut), strict=True):
            line.setValue(value)
            line.setVisible(True)
        grid = np.linspace(-spectrum.k_cut, spectrum.k_cut, CURVE_POINTS)
        kx, ky = grid * math.cos(angle), grid * math.sin(angle)
        top = float(spectrum.frequency[-1])

        def curve(omega: np.ndarray) -> np.ndarray:
            f = omega / (2 * math.pi)
            return np.where((f >= 0) & (f <= top), f, np.nan)

        fit = waves.fit
        if fit is not None:
            self.fit_curve.setData(grid, curve(fit.omega(kx, ky)))
            self.nominal_curve.setData([], [])
        else:
            settings = self.settings()
            nominal = wave_omega(
                kx,
                ky,
                surface_tension=settings.fluid.surface_tension,
                depth=settings.depth,
                fluid=settings.fluid,
            )
            self.fit_curve.setData([], [])
            self.nominal_curve.setData(grid, curve(nominal))
        self.omega_k.setTitle(f"{waves.label}, cut at {self.direction.value()}°", size=TITLE_SIZE)

    def _draw_field(self, waves: LiveWaves) -> None:
        latest, size = waves.latest, waves.pixel_size
        if latest is None:
            self.field_image.clear()
            return
        data = np.asarray(latest, dtype=np.float32) * 1e9
        finite = data[np.isfinite(data)]
        if finite.size == 0:
            self.field_image.clear()
            return
        low, high = (float(v) for v in np.percentile(finite, [1.0, 99.0]))
        self.field_image.setImage(np.nan_to_num(data, nan=low), levels=(low, max(high, low + 1e-3)))
        rows, cols = data.shape
        dy, dx = (1e-3, 1e-3) if size is None else size  # pixels when the size is not known
        rect = QRectF(-dx / 2 * 1e3, -dy / 2 * 1e3, cols * dx * 1e3, rows * dy * 1e3)
        self.field_image.setRect(rect)
        if rect != self._field_rect:  # a new field (first map, pixel size known): show it whole
            self._field_rect = rect
            self.field.getViewBox().autoRange(items=[self.field_image], padding=0.02)

    def _draw_mf(self, waves: LiveWaves) -> None:
        mf = waves.mf
        if mf is None:
            self.mf_image.clear()
            self.mf.setTitle(NO_CENTRE, size=TITLE_SIZE)
            return
        image, levels = _log_image(mf.power)
        self.mf_image.setImage(image, levels=levels)
        df = float(mf.frequency[1] - mf.frequency[0])
        m0 = float(mf.m[0])
        self.mf_image.setRect(QRectF(-df / 2, m0 - 0.5, df * mf.frequency.size, float(mf.m.size)))
        x, y = waves.centre or (math.nan, math.nan)
        self.mf.setTitle(f"(m, f) at ({x * 1e3:.3g}, {y * 1e3:.3g}) mm", size=TITLE_SIZE)
