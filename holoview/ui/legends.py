"""Curves of several maps: their pens, and a legend beside the plot's data area."""

from __future__ import annotations

import pyqtgraph as pg

#: Colours of the per-map curves, in label order; the fused curve is white and thicker.
CURVE_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2")
#: Name of the fused map's curve.
FUSED = "fused"

#: Row and column of the view box in a PlotItem's grid layout; the legend goes
#: one column right of the right axis.
_VIEW_ROW = 2
_LEGEND_COLUMN = 3


def curve_pen(name: str, index: int) -> pg.QtGui.QPen:
    """The pen of map ``name``'s curve, the ``index``-th curve of its plot.

    Solid pens only, one pixel wide but for the fused curve's two: Qt draws those
    polylines several times faster than dashed or fractional-width ones (a trends
    plot of 7 curves x 1800 points: 17 ms per paint dashed, 11 ms solid).
    """
    if name == FUSED:
        return pg.mkPen("w", width=2)
    return pg.mkPen(CURVE_COLOURS[index % len(CURVE_COLOURS)], width=1)


def side_legend(plot: pg.PlotItem, columns: int = 1) -> pg.LegendItem:
    """Give ``plot`` a legend to the right of its data area and return it.

    Curves later added with a ``name`` (``plot.plot(..., name=...)``) get an entry,
    as with :meth:`pyqtgraph.PlotItem.addLegend`, but the legend lives in the plot's
    layout instead of over the view box, with a semi-opaque background.

    Parameters
    ----------
    plot : pyqtgraph.PlotItem
        The plot; its legend must not exist yet.
    columns : int
        Number of entry columns (more columns: a shorter legend, for short plots).
    """
    legend = pg.LegendItem(
        offset=None,
        colCount=columns,
        brush=pg.mkBrush(0, 0, 0, 160),
        pen=pg.mkPen(128, 128, 128, 160),
        verSpacing=-4,
    )
    plot.layout.addItem(legend, _VIEW_ROW, _LEGEND_COLUMN)
    plot.legend = legend
    return legend


def fit_legend(plot: pg.PlotItem, legend: pg.LegendItem, height_px: float, most: int = 4) -> int:
    """Give ``legend`` the fewest columns (up to ``most``) with which ``plot`` fits its view.

    A side legend of one column sets the plot's least height (seven curves: about
    150 pixels); a shorter view (a trends dock on a 1366 x 768 screen) would cut the
    plot's bottom off, its time axis with it. More columns make the legend shorter.

    Parameters
    ----------
    plot : pyqtgraph.PlotItem
        The plot the legend is beside (:func:`side_legend`).
    legend : pyqtgraph.LegendItem
        Its legend.
    height_px : float
        The height the plot is shown in, pixels.
    most : int
        The most columns.

    Returns
    -------
    int
        The columns chosen.
    """
    for columns in range(1, most + 1):
        legend.setColumnCount(columns)
        if plot.layout.minimumHeight() <= height_px:
            break
    return columns
