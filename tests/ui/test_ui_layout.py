"""Layout of the views: legends beside the data, maps filling their cells, spectrum range."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pyqtgraph")

from holoview.ui.trends_view import TrendsView

pytestmark = [
    pytest.mark.gui,
    pytest.mark.qt_log_ignore(r"This plugin does not support propagateSizeHints\(\)"),
]

NAMES = ("RB1", "FB1", "RF", "RB2", "FB2", "fused")


def _show(qtbot, widget, width: int, height: int) -> None:
    qtbot.addWidget(widget)
    widget.resize(width, height)
    widget.show()
    qtbot.waitExposed(widget)


def test_trends_legend_lists_every_series_beside_the_data(qtbot) -> None:
    view = TrendsView()
    times = np.linspace(0.0, 10.0, 50)
    view.set_series(times, {n: -times * (1 + i) * 1e-8 for i, n in enumerate(NAMES)})
    _show(qtbot, view, 680, 280)
    qtbot.wait(50)
    assert [label.text for _, label in view.legend.items] == list(NAMES)
    data_area = view.plot.getPlotItem().vb.sceneBoundingRect()
    # right of the data area (to within the pixel its border pen takes)
    assert view.legend.sceneBoundingRect().left() >= data_area.right() - 1.0
