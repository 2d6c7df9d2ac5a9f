"""Per-peak delta-h maps, the fused map, a shared colour bar and a line profile.

Heights arrive in metres and are shown in nanometres with a perceptual colour map
(viridis); phases arrive in radians and are shown with a cyclic one (CET-C6) over
[-pi, pi]. Untrusted pixels arrive as NaN and are left transparent. The height range
(the first, "Auto range", and "follow": every :data:`FOLLOW_INTERVAL_S` where it moved by
more than :data:`~holoview.ui.map_ranges.FOLLOW_TOLERANCE`, and at once when the maps
left it) is :mod:`holoview.ui.map_ranges`'s: percentiles of the trusted
pixels, of the fused map where there is one, so that a noisy peak's map or a few wild
pixels do not squeeze the surface into a few colours. A line drawn on the first map is
mirrored (dashed) on the others, and the profile below overlays every map's curve along
it (the paper's figure 4g), on a range that follows the curves it shows. When the maps
restart (new windows or peaks, a reset), the restart's own frame, their new reference
whose maps are zeros by construction, is not drawn: the maps shown stay until the next
frame's, which set the range at once.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Mapping

import numpy as np
import pyqtgraph as pg
from PyQt6.QtCore import QEvent, QObject, Qt, QTimer, pyqtSignal
from PyQt6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from holoview.engine.experiment import PEAK_LABELS
from holoview.processing.maps.demod_results import REFERENCE_MODES
from holoview.ui.colour_index import colour_indices, colour_table, rgba
from holoview.ui.elided_label import ElidedLabel
from holoview.ui.legends import FUSED, curve_pen, side_legend
from holoview.ui.map_ranges import colour_range, left_range, profile_range, settled

#: Colour map of heights (perceptual) and of phases (cyclic).
HEIGHT_CMAP = "viridis"
PHASE_CMAP = "CET-C6"
#: Seconds between colour-range updates while "follow" is on.
FOLLOW_INTERVAL_S = 0.5
#: Map titles: font size, and the height they take above a map, pixels.
TITLE_SIZE = "9pt"
TITLE_HEIGHT_PX = 22.0
#: Width the colour bar takes beside the maps before it is first laid out, pixels.
COLOUR_BAR_WIDTH_PX = 90.0
#: Entries per column of the profile's legend (more go in further columns), so
#: that the legend fits the short profile plot.
LEGEND_ROWS = 3
#: What the panel says before the first maps.
NO_MAPS = (
    "No maps yet. Label a peak in the Spectrum (click it and name it), or take the "
    "labels it suggests: a delta-h map per labelled peak and the fused map appear here."
)
#: Default line, as fractions of (width, height): a horizontal diameter.
DEFAULT_LINE = ((0.05, 0.5), (0.95, 0.5))


def sample_line(
    image: np.ndarray, start: tuple[float, float], end: tuple[float, float], n: int
) -> np.ndarray:
    """Return ``n`` nearest-pixel samples of ``image`` along a line.

    ``start`` and ``end`` are ``(x, y)`` fractions of the width and height, so the
    same line can be sampled on maps of different shapes.
    """
    rows, cols = image.shape
    x = np.clip(np.linspace(start[0], end[0], n) * cols, 0, cols - 1).astype(int)
    y = np.clip(np.linspace(start[1], end[1], n) * rows, 0, rows - 1).astype(int)
    return image[y, x]


def best_columns(n: int, width: float, height: float, title: float = 0.0) -> int:
    """Return the number of columns in which ``n`` square maps are largest.

    Parameters
    ----------
    n : int
        Number of maps (at least one).
    width, height : float
        Area the maps share, pixels.
    title : float
        Height of the title above each map, pixels.
    """
    n = max(1, n)

    def side(columns: int) -> float:
        rows = -(-n // columns)
        return min(width / columns, height / rows - title)

    return max(range(1, n + 1), key=lambda c: (side(c), -c))


def ordered_names(names: Iterable[str]) -> list[str]:
    """Map names in a stable order: the usual families first, other labels, then fused."""
    given = list(names)
    usual = [n for n in PEAK_LABELS if n in given]
    others = sorted(n for n in given if n not in PEAK_LABELS and n != FUSED)
    return usual + others + ([FUSED] if FUSED in given else [])


class SurfaceView(QWidget):
    """Maps per labelled peak and fused, with a colour bar and a line profile.

    Signals
    -------
    referenceChanged(str)
        The operator chose another reference mode (relative, absolute, synthetic).
    """

    referenceChanged = pyqtSignal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._names: list[str] = []
        self._data: dict[str, np.ndarray] = {}
        self._mode = "height"
        self._line = DEFAULT_LINE
        self._levels: tuple[float, float] | None = None
        self._table = colour_table(HEIGHT_CMAP)
        self.plots: dict[str, pg.PlotItem] = {}
        self.images: dict[str, pg.ImageItem] = {}
        self._mirrors: dict[str, pg.PlotDataItem] = {}
        self._mirrored: dict[str, tuple[list[float], list[float]]] = {}
        self.line_roi: pg.LineSegmentROI | None = None
        self._placing = False
        self._line_shape: tuple[int, ...] | None = None  # the map the line is placed on
        self._restarted = False  # the maps restarted: range the next ones at once

        self.mode_box = QComboBox()
        self.mode_box.addItems(["height (nm)", "phase (rad)"])
        self.mode_box.currentIndexChanged.connect(self._mode_changed)
        self.reference_box = QComboBox()
        self.reference_box.addItems(REFERENCE_MODES)
        self.reference_box.currentTextChanged.connect(self.referenceChanged.emit)
        self.range_button = QPushButton("Auto range")
        self.range_button.setToolTip(
            "set the colour range once from the 1-99 percentiles of the trusted pixels "
            "(of the fused map where there is one)"
        )
        self.range_button.clicked.connect(self.auto_range)
        self.follow_box = QCheckBox("follow")
        self.follow_box.setToolTip(
            f"update the colour range from the maps every {FOLLOW_INTERVAL_S:g} s"
        )
        self.follow_box.setChecked(True)
        self._range_at = -math.inf
        # "follow": the newest maps ranged once the interval has passed, even when no
        # more maps come (a replay paused or stepped right after an update)
        self._follow_timer = QTimer(self)
        self._follow_timer.setSingleShot(True)
        self._follow_timer.timeout.connect(self._follow_due)
        # what it says grows with the replay ("maps of frame 14 (55 behind)"): it takes
        # the room left, never widens the dock (a 1366-pixel window grew past its screen)
        self.stats_label = ElidedLabel()
        controls = QHBoxLayout()
        controls.addWidget(QLabel("show"))
        controls.addWidget(self.mode_box)
        controls.addWidget(QLabel("reference"))
        controls.addWidget(self.reference_box)
        controls.addWidget(self.range_button)
        controls.addWidget(self.follow_box)
        controls.addWidget(self.stats_label, 1)

        self.graphics = pg.GraphicsLayoutWidget()
        self.graphics.ci.setContentsMargins(2, 2, 2, 2)
        self.graphics.ci.setSpacing(2)
        self.graphics.installEventFilter(self)
        self._columns = 0
        self.colour_bar = pg.ColorBarItem(
            values=(-1.0, 1.0), colorMap=pg.colormap.get(HEIGHT_CMAP), label="delta h (nm)"
        )
        # the bar is the legend and the range control; the maps are coloured here
        # (colour_index), not by the bar, which would colour them through pyqtgraph's
        # float path
        self.colour_bar.sigLevelsChanged.connect(self._bar_levels_changed)
        self.profile = pg.PlotWidget()
        self.profile.setLabel("bottom", "position along the line", units="px")
        self.profile.setLabel("left", "delta h (nm)")
        self.profile.getAxis("left").enableAutoSIPrefix(False)
        self.profile.disableAutoRange()
        self._profile_ranges: tuple[tuple[float, float], tuple[float, float]] | None = None
        self.profile_legend = side_legend(self.profile.getPlotItem())
        self.curves: dict[str, pg.PlotCurveItem] = {}
        splitter = QSplitter(Qt.Orientation.Vertical)
        splitter.addWidget(self.graphics)
        splitter.addWidget(self.profile)
        splitter.setSizes([500, 200])
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        self.empty_hint = QLabel(NO_MAPS)
        self.empty_hint.setWordWrap(True)
        self.empty_hint.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.empty_hint.setStyleSheet("color: gray; font-size: 11pt; padding: 24px;")
        self.splitter = splitter
        splitter.hide()
        layout.addLayout(controls)
        layout.addWidget(self.empty_hint, 1)
        layout.addWidget(splitter, 1)

    @property
    def mode(self) -> str:
        """``height`` or ``phase``."""
        return self._mode

    @property
    def names(self) -> list[str]:
        """Names of the maps shown, labels first, then ``fused``."""
        return list(self._names)

    def set_reference(self, mode: str) -> None:
        """Show ``mode`` as the chosen reference without emitting a change."""
        self.reference_box.blockSignals(True)
        self.reference_box.setCurrentText(mode)
        self.reference_box.blockSignals(False)

    def set_maps(
        self,
        heights_m: Mapping[str, np.ndarray],
        fused_m: np.ndarray | None = None,
        phases_rad: Mapping[str, np.ndarray] | None = None,
        shifts_px: Mapping[str, tuple[float, float]] | None = None,
        grid_of: str | None = None,
        *,
        reference: bool = False,
    ) -> None:
        """Show one map per label and the fused map.

        Parameters
        ----------
        heights_m : mapping of str to ndarray
            delta-h per labelled peak, metres.
        fused_m : ndarray, optional
            The fused delta-h, metres.
        phases_rad : mapping of str to ndarray, optional
            Phase per labelled peak, radians (shown in phase mode).
        shifts_px : mapping of str to (dy, dx), optional
            Measured displacement of each map against the map ``grid_of``, camera
            pixels: in each map's tooltip; the fused map's title says it is
            co-registered.
        grid_of : str, optional
            The map whose grid the others are moved onto for the fused map.
        reference : bool
            The maps restarted at this frame: it is their new reference and its maps
            are zeros by construction. They are not drawn (the maps shown stay); the
            next maps set the colour range at once.
        """
        if reference:
            self._restarted = True
            return
        if self._mode == "phase" and phases_rad:
            data = {k: np.asarray(v, dtype=np.float32) for k, v in phases_rad.items()}
        else:
            data = {k: np.asarray(v, dtype=np.float32) * 1e9 for k, v in heights_m.items()}
            if fused_m is not None:
                data[FUSED] = np.asarray(fused_m, dtype=np.float32) * 1e9
        names = ordered_names(data)
        if names != self._names:
            self._rebuild(names)
        self._data = data
        now = time.monotonic()
        following = self.follow_box.isChecked()
        follow = following and (
            now - self._range_at >= FOLLOW_INTERVAL_S
            or (self._levels is not None and left_range(data, self._levels))
        )
        if self._mode == "height" and (self._levels is None or follow or self._restarted):
            self._range_from_maps(following=follow and not self._restarted)
        elif self._mode == "height" and following and not self._follow_timer.isActive():
            wait = FOLLOW_INTERVAL_S - (now - self._range_at)
            self._follow_timer.start(max(0, int(wait * 1000)))
        self._draw_maps()
        self._show_shifts(shifts_px or {}, grid_of)
        self._update_profile()

    def _draw_maps(self) -> None:
        """Colour the maps shown on the current range."""
        low, high = self.levels
        for name, image in self.images.items():
            if name in self._data:
                indices = colour_indices(self._data[name], low, high)
                image.setImage(rgba(self._table, indices), autoLevels=False)

    def _show_shifts(
        self, shifts_px: Mapping[str, tuple[float, float]], grid_of: str | None
    ) -> None:
        """Title the fused map by whether it is co-registered; shifts in the tooltips."""
        moved = any(v != (0.0, 0.0) for v in shifts_px.values())
        for name, plot in self.plots.items():
            if name == FUSED:
                title = f"{FUSED} (on {grid_of}'s grid)" if moved and grid_of else FUSED
                if plot.titleLabel.text != title:
                    plot.setTitle(title, size=TITLE_SIZE)
                continue
            shift = shifts_px.get(name)
            plot.setToolTip(
                "displacement not measured yet"
                if shift is None
                else f"displacement against {grid_of}: dy {shift[0]:+.2f}, dx {shift[1]:+.2f} "
                "camera pixels"
            )

    def map_data(self, name: str) -> np.ndarray:
        """Return the array shown for ``name`` (nm or rad)."""
        return self._data[name]

    @property
    def levels(self) -> tuple[float, float]:
        """The values drawn with the colour map's ends: nm (heights) or rad (phases)."""
        if self._mode == "phase":
            return (-np.pi, np.pi)
        return self._levels or (-1.0, 1.0)

    def auto_range(self) -> None:
        """Set the height colour range from the maps shown (:func:`colour_range`)."""
        self._range_from_maps()
        self._draw_maps()

    def _follow_due(self) -> None:
        """Range the maps shown now, if "follow" is still on (the timer's end)."""
        if self.follow_box.isChecked() and self._mode == "height":
            self._range_from_maps(following=True)
            self._draw_maps()

    def _range_from_maps(self, following: bool = False) -> None:
        """Take the colour range from the maps shown; ``following``: keep the range shown
        while the new one is within :data:`FOLLOW_TOLERANCE` of it (:func:`settled`)."""
        if self._mode == "phase" or not self._data:
            return
        levels = colour_range(self._data)
        if levels is None:  # no range to take: the next maps are looked at at once
            return
        self._range_at = time.monotonic()
        self._restarted = False
        if following and self._levels is not None and settled(self._levels, levels):
            return  # colours that hold still; the bar's axis is not drawn again
        self._levels = levels
        self.colour_bar.setLevels(self._levels)

    def _bar_levels_changed(self) -> None:
        if self._mode == "height":
            low, high = self.colour_bar.levels()
            self._levels = (float(low), float(high))
            self._draw_maps()

    def _rebuild(self, names: list[str]) -> None:
        """Lay out one plot per name, reusing the plots of names already shown."""
        self._clear_line_items()
        layout = self.graphics.ci
        for name in [n for n in self.plots if n not in names]:
            if self.plots[name] in layout.items:
                layout.removeItem(self.plots[name])
            del self.plots[name], self.images[name]
        for name in names:
            if name not in self.plots:
                plot = pg.PlotItem()
                plot.setTitle(name, size=TITLE_SIZE)
                plot.setAspectLocked(True)
                plot.invertY(True)
                plot.hideAxis("left")
                plot.hideAxis("bottom")
                plot.getViewBox().setDefaultPadding(0.0)
                image = pg.ImageItem(axisOrder="row-major")
                plot.addItem(image)
                self.plots[name] = plot
                self.images[name] = image
        self._columns = 0
        self._lay_out(names)
        self._apply_cmap()
        self._names = names
        self.empty_hint.setVisible(not names)
        self.splitter.setVisible(bool(names))
        self._make_line_items()
        for curve in self.curves.values():
            self.profile.removeItem(curve)
        self.curves.clear()
        self.profile_legend.setColumnCount(max(1, -(-len(names) // LEGEND_ROWS)))
        for i, name in enumerate(names):
            # a bare curve: its data set every frame cost a twelfth of a PlotDataItem's
            # (0.02 against 0.23 ms for 170 points, seven curves a frame drawn)
            curve = pg.PlotCurveItem(pen=curve_pen(name, i), name=name, connect="finite")
            self.profile.addItem(curve)
            self.curves[name] = curve

    def _lay_out(self, names: list[str]) -> None:
        """Put the maps in the number of columns that makes them largest, then the bar."""
        bar_width = self.colour_bar.width() if self._columns else COLOUR_BAR_WIDTH_PX
        columns = best_columns(
            len(names),
            max(1.0, self.graphics.width() - bar_width),
            max(1.0, self.graphics.height()),
            TITLE_HEIGHT_PX,
        )
        if columns == self._columns:
            return
        self._columns = columns
        layout = self.graphics.ci
        for item in [*self.plots.values(), self.colour_bar]:
            if item in layout.items:
                layout.removeItem(item)
        for i, name in enumerate(names):
            layout.addItem(self.plots[name], row=i // columns, col=i % columns)
        layout.addItem(
            self.colour_bar, row=0, col=columns, rowspan=max(1, -(-len(names) // columns))
        )

    def eventFilter(self, watched: QObject | None, event: QEvent | None) -> bool:
        """Re-arrange the maps when their area changes size."""
        if (
            watched is self.graphics
            and event is not None
            and event.type() == QEvent.Type.Resize
            and self._names
        ):
            self._lay_out(self._names)
        return super().eventFilter(watched, event)

    def _clear_line_items(self) -> None:
        """Take the line and its mirrors off the maps (before any map goes)."""
        if self.line_roi is not None and self._names:
            self.plots[self._names[0]].removeItem(self.line_roi)
        for name, mirror in self._mirrors.items():
            self.plots[name].removeItem(mirror)
        self._mirrors.clear()
        self._mirrored.clear()
        self.line_roi = None

    def _make_line_items(self) -> None:
        """Put the line on the first map and its dashed mirror on the others."""
        if not self._names:
            return
        self._line_shape = None
        self.line_roi = pg.LineSegmentROI([[0, 0], [1, 0]], pen=pg.mkPen("w", width=2))
        self.plots[self._names[0]].addItem(self.line_roi)
        self.line_roi.sigRegionChanged.connect(self._line_moved)
        for name in self._names[1:]:
            mirror = pg.PlotDataItem(pen=pg.mkPen("w", width=1.5, style=Qt.PenStyle.DashLine))
            self.plots[name].addItem(mirror)
            self._mirrors[name] = mirror

    def _place_line_roi(self) -> None:
        if self.line_roi is None or not self._names or self._names[0] not in self._data:
            return
        rows, cols = self._data[self._names[0]].shape
        (x0, y0), (x1, y1) = self._line
        handles = self.line_roi.getHandles()
        self._placing = True
        self.line_roi.movePoint(handles[0], pg.Point(x0 * cols, y0 * rows), finish=False)
        self.line_roi.movePoint(handles[1], pg.Point(x1 * cols, y1 * rows), finish=False)
        self._placing = False

    def _line_moved(self) -> None:
        if self._placing or self.line_roi is None:
            return
        rows, cols = self._data[self._names[0]].shape
        p0, p1 = (self.line_roi.mapToParent(h.pos()) for h in self.line_roi.getHandles())
        self._line = ((p0.x() / cols, p0.y() / rows), (p1.x() / cols, p1.y() / rows))
        self._update_profile()

    def profile_curves(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Return each map's profile along the line: (position in pixels, value)."""
        out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for name, data in self._data.items():
            rows, cols = data.shape
            (x0, y0), (x1, y1) = self._line
            length = float(np.hypot((x1 - x0) * cols, (y1 - y0) * rows))
            n = max(2, int(length) + 1)
            out[name] = (np.linspace(0.0, length, n), sample_line(data, *self._line, n))
        return out

    def _update_profile(self) -> None:
        if not self._data:
            return
        first = self._data.get(self._names[0]) if self._names else None
        if self.line_roi is not None and first is not None and first.shape != self._line_shape:
            # placed again on maps of another shape (windows matched again): left where
            # it was, the line stretched the view past a smaller map, drawn small in its cell
            self._line_shape = first.shape
            self._place_line_roi()
        length = 1.0
        values = []
        for name, (x, y) in self.profile_curves().items():
            self.curves[name].setData(x, y)
            length = max(length, float(x[-1]))
            values.append(y)
        # fixed ranges (the line's length, the curves' values with some slack) instead of
        # auto-ranging every frame: the axes are then regenerated only when these change
        if self._mode == "phase":
            shown: tuple[float, float] | None = self.levels
        else:
            previous = None if self._profile_ranges is None else self._profile_ranges[1]
            shown = profile_range(previous, np.concatenate(values)) if values else None
        ranges = ((0.0, length), shown or self.levels)
        if ranges != self._profile_ranges:
            self._profile_ranges = ranges
            self.profile.setRange(xRange=ranges[0], yRange=ranges[1], padding=0.02)
        (x0, y0), (x1, y1) = self._line
        for name, mirror in self._mirrors.items():
            rows, cols = self._data[name].shape
            ends = ([x0 * cols, x1 * cols], [y0 * rows, y1 * rows])
            if self._mirrored.get(name) != ends:  # redrawn only when the line moves
                self._mirrored[name] = ends
                mirror.setData(*ends)

    def _mode_changed(self, index: int) -> None:
        self._mode = "phase" if index == 1 else "height"
        self._profile_ranges = None  # the profile's range taken afresh in the new unit
        self._apply_cmap()
        unit = "phase (rad)" if self._mode == "phase" else "delta h (nm)"
        self.profile.setLabel("left", unit)
        self.colour_bar.getAxis("left").setLabel(unit)
        self.colour_bar.setLevels(self.levels)

    def _apply_cmap(self) -> None:
        name = PHASE_CMAP if self._mode == "phase" else HEIGHT_CMAP
        self.colour_bar.setColorMap(pg.colormap.get(name))
        self._table = colour_table(name)
        self._draw_maps()
