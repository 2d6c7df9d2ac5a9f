"""Layout of the views: legends beside the data, maps filling their cells, spectrum range."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pyqtgraph")

from holoview.ui.spectrum_view import SpectrumView
from holoview.ui.surface_view import FUSED, SurfaceView, best_columns
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


def _maps(seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {n: rng.normal(size=(48, 48)) * 1e-9 for n in NAMES if n != FUSED}


def test_profile_legend_shows_every_entry_in_a_short_profile(qtbot) -> None:
    view = SurfaceView()
    maps = _maps()
    view.set_maps(maps, maps["RB1"])
    _show(qtbot, view, 680, 560)
    view.profile.resize(view.profile.width(), 110)
    qtbot.wait(50)
    legend = view.profile_legend
    assert [label.text for _, label in legend.items] == list(NAMES)
    visible = view.profile.sceneRect()
    for _, label in legend.items:
        assert visible.contains(label.sceneBoundingRect()), label.text
    data_area = view.profile.getPlotItem().vb.sceneBoundingRect()
    assert legend.sceneBoundingRect().left() >= data_area.right() - 1.0


def test_best_columns_makes_square_maps_largest() -> None:
    assert best_columns(6, 1200.0, 300.0) == 6  # one row in a wide strip
    assert best_columns(6, 300.0, 900.0) == 1  # one column in a tall strip
    assert best_columns(6, 600.0, 400.0) == 3
    assert best_columns(4, 400.0, 400.0) == 2
    assert best_columns(1, 10.0, 10.0) == 1


@pytest.mark.parametrize("size", [(680, 560), (1200, 420)])
def test_maps_fill_their_cells(qtbot, size: tuple[int, int]) -> None:
    view = SurfaceView()
    maps = _maps()
    view.set_maps(maps, maps["RB1"])
    _show(qtbot, view, *size)
    qtbot.wait(50)
    for name in NAMES:
        plot = view.plots[name]
        image = view.images[name].sceneBoundingRect()
        cell = plot.getViewBox().sceneBoundingRect()
        # aspect locked: the image spans the cell's smaller side (to within a pixel)
        assert abs(image.width() - image.height()) <= 2.0
        assert min(image.width(), image.height()) >= min(cell.width(), cell.height()) - 2.0
        assert image.width() > 0.14 * size[0]


@pytest.mark.parametrize("size", [(700, 420), (420, 700)])
def test_spectrum_shows_its_bounds_and_no_more(qtbot, size: tuple[int, int]) -> None:
    view = SpectrumView()
    rng = np.random.default_rng(2)
    view.set_spectrum(rng.normal(size=(64, 64)).astype(np.float32))
    _show(qtbot, view, *size)
    qtbot.wait(50)
    x_range, y_range = view.plot.viewRange()
    assert x_range == pytest.approx([-0.5, 0.5], abs=0.01)
    assert y_range == pytest.approx([-0.5, 0.5], abs=0.01)
