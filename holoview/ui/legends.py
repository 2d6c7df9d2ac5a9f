"""A legend beside a plot's data area, so that no entry covers a curve."""

from __future__ import annotations

import pyqtgraph as pg

#: Row and column of the view box in a PlotItem's grid layout; the legend goes
#: one column right of the right axis.
_VIEW_ROW = 2
_LEGEND_COLUMN = 3


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
