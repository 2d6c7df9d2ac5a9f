"""The GUI's views on plain arrays: levels, snapping and labels, maps, profiles, trends."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("pyqtgraph")

from holoview.processing.series.rate_fits import format_rate
from holoview.ui.colour_index import colour_indices, colour_table
from holoview.ui.hologram_view import HologramView
from holoview.ui.label_layout import PeakLabel, place_labels
from holoview.ui.map_ranges import colour_range
from holoview.ui.spectrum_view import CLEAR, SpectrumView
from holoview.ui.surface_view import FUSED, SurfaceView, sample_line
from holoview.ui.trends_view import TrendsView

pytestmark = pytest.mark.gui


def test_hologram_levels_persist_until_auto_levels(qtbot) -> None:
    view = HologramView()
    qtbot.addWidget(view)
    rng = np.random.default_rng(1)
    first = rng.integers(100, 200, (64, 80), dtype=np.uint16)
    view.set_frame(first)
    levels = view.levels
    assert levels is not None and 100 <= levels[0] < levels[1] <= 200
    view.set_frame(first * 10)  # a much brighter frame: no flicker, the levels stay
    assert view.levels == levels
    view.auto_levels()
    low, high = view.levels
    assert low >= 1000 and high == pytest.approx(np.percentile(first * 10, 99.5), rel=0.02)


def test_hologram_saturation_and_readout(qtbot) -> None:
    view = HologramView()
    qtbot.addWidget(view)
    frame = np.zeros((10, 12), np.uint16)
    frame[2:4, 5] = 4095
    view.set_saturation_value(4095)
    view.set_frame(frame)
    assert view.saturated_count() == 2
    assert view.overlay.image is not None and view.overlay.image[2, 5, 0] == 255
    assert view.readout_at(5.5, 3.2) == "row 3, column 5: 4095"
    assert view.readout_at(-1, 0).startswith("outside")


def _spectrum_view(qtbot) -> tuple[SpectrumView, list]:
    view = SpectrumView()
    qtbot.addWidget(view)
    view.set_spectrum(np.random.default_rng(0).random((64, 64)).astype(np.float32))
    view.set_peaks([(0.2, 0.1), (-0.1, 0.25)], (256, 256))
    events: list = []
    view.peakLabelled.connect(lambda *a: events.append(("label", *a)))
    view.labelCleared.connect(lambda a: events.append(("clear", a)))
    view.message.connect(lambda m: events.append(("message", m)))
    view.radiusChanged.connect(lambda r: events.append(("radius", r)))
    return view, events


def test_click_near_peak_snaps_and_labels(qtbot) -> None:
    view, events = _spectrum_view(qtbot)
    offered = []
    view.choose_label = lambda carrier, current: offered.append(carrier) or "RB1"
    view.click_at(0.21, 0.09)
    assert offered == [(0.2, 0.1)]
    assert events == [("label", "RB1", 0.2, 0.1)]


def test_click_with_no_peak_says_so(qtbot) -> None:
    view, events = _spectrum_view(qtbot)
    view.choose_label = lambda carrier, current: pytest.fail("no menu without a peak")
    view.click_at(0.45, -0.45)
    assert (
        len(events) == 1
        and events[0][0] == "message"
        and "no peak within 12 FFT bins" in events[0][1]
    )


def test_clear_label_from_the_menu(qtbot) -> None:
    view, events = _spectrum_view(qtbot)
    view.set_model({"FB1": (0.2, 0.1)}, {}, 0.05)
    view.choose_label = lambda carrier, current: CLEAR if current == "FB1" else None
    view.click_at(0.2, 0.1)
    assert events == [("clear", "FB1")]


def test_model_draws_windows_predictions_and_warnings(qtbot) -> None:
    view, _ = _spectrum_view(qtbot)
    view.set_model({"RB1": (0.2, 0.1), "FB1": (-0.1, 0.25)}, {"RF": (0.3, -0.15)}, 0.04)
    assert set(view._circles) == {"RB1", "FB1"}
    centre = view._circles["RB1"].pos() + view._circles["RB1"].size() / 2
    assert (centre.x(), centre.y()) == pytest.approx((0.2, 0.1))
    assert len(view.predicted_markers.data) == 1
    assert view.warnings == []
    view.set_model({"RB1": (0.2, 0.1), "FB1": (0.22, 0.12)}, {"RB2": (0.6, 0.0)}, 0.04)
    assert any("overlap" in w for w in view.warnings)
    assert any("aliased" in w for w in view.warnings)


def test_radius_that_swallows_a_neighbour_is_used_with_a_warning(qtbot) -> None:
    view, events = _spectrum_view(qtbot)
    view.set_peaks([(0.2, 0.1), (0.3, 0.15)], (256, 256))
    view.set_model({"RB1": (0.2, 0.1)}, {}, 0.04)
    distance = math.dist((0.2, 0.1), (0.3, 0.15))
    assert view.request_radius("RB1", distance + 0.01)
    assert view.radius == pytest.approx(distance + 0.01)
    assert any(
        e[0] == "message" and "swallows the peak at (+0.300, +0.150)" in e[1] for e in events
    )
    assert events[-1] == ("radius", pytest.approx(distance + 0.01))
    # zero frequency is refused
    assert not view.request_radius("RB1", 0.3)
    assert events[-1][0] == "message" and "zero frequency" in events[-1][1]
    assert view.request_radius("RB1", 0.06)
    assert view.radius == 0.06 and events[-1] == ("radius", 0.06)


def test_dragging_a_circle_requests_the_radius(qtbot) -> None:
    view, events = _spectrum_view(qtbot)
    view.set_model({"RB1": (0.2, 0.1)}, {}, 0.04)
    circle = view._circles["RB1"]
    circle.setSize([0.1, 0.1], center=(0.5, 0.5), finish=True)
    assert events[-1] == ("radius", pytest.approx(0.05))


def test_sample_line_on_maps_of_different_shapes() -> None:
    small = np.arange(16, dtype=float).reshape(4, 4)
    big = np.kron(small, np.ones((2, 2)))
    line = ((0.0, 0.5), (0.99, 0.5))
    assert np.array_equal(sample_line(small, *line, 4), small[2])
    assert np.array_equal(sample_line(big, *line, 8)[::2], small[2])


def test_surface_maps_in_nm_profiles_and_cyclic_phase(qtbot) -> None:
    view = SurfaceView()
    qtbot.addWidget(view)
    x = np.linspace(-1, 1, 48)
    bump = np.exp(-(x[None, :] ** 2 + x[:, None] ** 2) * 4) * 30e-9
    heights = {"RB1": bump, "FB1": bump * 0.9}
    view.set_maps(heights, fused_m=bump * 0.95)
    assert view.names == ["RB1", "FB1", FUSED]
    assert view.map_data("RB1").max() == pytest.approx(bump.max() * 1e9, rel=1e-5)
    curves = view.profile_curves()
    assert set(curves) == {"RB1", "FB1", FUSED}
    _, rb1 = curves["RB1"]
    assert rb1.max() == pytest.approx(view.map_data("RB1")[24].max(), rel=0.05)
    assert rb1.max() > 25 and rb1[0] < 5  # a diameter across the bump
    view.mode_box.setCurrentIndex(1)
    view.set_maps(heights, bump, phases_rad={"RB1": bump * 1e8, "FB1": bump * 1e8})
    assert view.mode == "phase"
    assert view.levels == pytest.approx((-np.pi, np.pi))
    drawn = view.images["RB1"].image  # RGBA, coloured on [-pi, pi]
    table = colour_table("CET-C6")
    assert np.array_equal(drawn, table[colour_indices(bump * 1e8, -np.pi, np.pi)])
    top = round(1 + (bump.max() * 1e8 + np.pi) / (2 * np.pi) * 254)
    assert np.array_equal(drawn[24, 24], table[top])
    assert view.colour_bar.colorMap().name == "CET-C6"
    assert view.colour_bar.getAxis("left").labelText == "phase (rad)"


def test_the_profile_line_follows_maps_of_a_new_shape(qtbot) -> None:
    """Maps that shrink (windows matched again) take the line with them: it once stayed at
    the larger maps' pixels and stretched the first map's view, drawn small in its cell."""
    view = SurfaceView()
    qtbot.addWidget(view)
    view.set_maps({"RB1": np.zeros((64, 64)), "FB1": np.zeros((64, 64))})
    view.set_maps({"RB1": np.zeros((16, 16)), "FB1": np.zeros((16, 16))})
    assert view.line_roi is not None
    ends = [view.line_roi.mapToParent(h.pos()) for h in view.line_roi.getHandles()]
    assert all(0 <= p.x() <= 16 and 0 <= p.y() <= 16 for p in ends), ends


def test_colour_indices_clip_round_and_keep_zero_for_no_value() -> None:
    values = np.array([[-5.0, 0.0, 1.0, 2.0], [np.nan, np.inf, -np.inf, 0.5]], dtype=np.float32)
    indices = colour_indices(values, 0.0, 2.0)
    assert indices.dtype == np.uint8
    assert indices.tolist() == [[1, 1, 128, 255], [0, 0, 0, 65]]
    table = colour_table("viridis")
    assert table.shape == (256, 4) and table[0, 3] == 0 and (table[1:, 3] == 255).all()


def test_surface_maps_keep_their_no_value_border_transparent(qtbot) -> None:
    view = SurfaceView()
    qtbot.addWidget(view)
    height = np.full((32, 32), np.nan)
    height[4:-4, 4:-4] = np.linspace(0, 10e-9, 24)[None, :]
    view.set_maps({"RB1": height})
    alpha = view.images["RB1"].image[..., 3]
    assert (alpha[:4] == 0).all() and (alpha[4:-4, 4:-4] == 255).all()
    low, high = view.levels
    assert 0.0 <= low < high <= 10.0  # the 1-99 percentiles of the finite values, nm
    view.colour_bar.setLevels((0.0, 20.0))
    view._bar_levels_changed()  # what dragging the bar's handles does
    assert view.levels == (0.0, 20.0)
    middle = colour_table("viridis")[colour_indices(np.array([10.0]), 0.0, 20.0)[0]]
    assert np.array_equal(view.images["RB1"].image[10, -5], middle)


def test_fused_title_and_tooltips_tell_the_co_registration(qtbot) -> None:
    view = SurfaceView()
    qtbot.addWidget(view)
    maps = {"RB1": np.zeros((16, 16)), "RF": np.ones((16, 16)) * 1e-9}
    view.set_maps(maps, maps["RB1"])
    assert view.plots[FUSED].titleLabel.text == FUSED
    assert view.plots["RF"].toolTip() == "displacement not measured yet"
    view.set_maps(
        maps, maps["RB1"], shifts_px={"RB1": (0.0, 0.0), "RF": (1.25, -0.5)}, grid_of="RB1"
    )
    assert view.plots[FUSED].titleLabel.text == "fused (on RB1's grid)"
    assert "dy +1.25, dx -0.50 camera pixels" in view.plots["RF"].toolTip()


def test_trends_show_rate_in_um_per_min(qtbot) -> None:
    view = TrendsView()
    qtbot.addWidget(view)
    t = np.arange(10.0)
    view.set_series(t, {"RB1": -t * 1e-8, FUSED: -t * 1e-8})
    assert set(view.curves) == {"RB1", FUSED}
    assert view.curves["RB1"].yData[-1] == pytest.approx(-90.0)
    view.set_rate(-1.36e-8, 2e-11, ([0, 9], [0, -1.2e-7]))
    assert format_rate(-1.36e-8, 2e-11) in view.rate_label.text()
    assert format_rate(-1.36e-8, 2e-11) == "-0.8160 ± 0.0012 µm/min"
    view.set_pca(0.9994, {"RB1": 0.333})
    assert "99.94 %" in view.pca_label.text()


@pytest.mark.qt_log_ignore(r"This plugin does not support propagateSizeHints\(\)")
def test_a_short_trends_plot_keeps_its_time_axis(qtbot) -> None:
    """Seven curves' legend in one column needs about 150 pixels: a shorter plot (a
    trends dock at 1366 x 768) takes more columns instead of losing its bottom."""
    view = TrendsView()
    qtbot.addWidget(view)
    view.resize(560, 400)
    view.show()
    times = np.linspace(0.0, 2.0, 50)
    names = ("RB1", "RF", "RB2", "FB1", "RB3", "FB2", "fused")
    view.set_series(times, {name: -times * 1e-8 for name in names})
    item = view.plot.getPlotItem()

    def fits() -> bool:
        return item.layout.minimumHeight() <= view.plot.viewport().height()

    qtbot.waitUntil(fits)
    assert view.legend.columnCount == 1
    view.resize(560, 190)
    qtbot.waitUntil(lambda: view.legend.columnCount > 1 and fits())
    assert item.size().height() <= view.plot.viewport().height() + 1  # nothing cut off
    view.resize(560, 400)
    qtbot.waitUntil(lambda: view.legend.columnCount == 1)


@pytest.mark.qt_log_ignore(r"This plugin does not support propagateSizeHints\(\)")
def test_trends_that_grow_are_painted_once_per_update(qtbot) -> None:
    """The time axis takes its new range before the paint: one paint per update (two when
    pyqtgraph ranged the view as the paint started; 21 ms each at 1920 x 1080)."""
    view = TrendsView()
    qtbot.addWidget(view)
    view.resize(560, 300)
    view.show()
    qtbot.waitExposed(view)
    times = np.linspace(0.0, 2.0, 50)
    view.set_series(times, {"RB1": -times * 1e-8})
    qtbot.wait(200)
    paints: list[int] = []
    plain = type(view.plot).paintEvent

    def counted(event) -> None:
        paints.append(1)
        plain(view.plot, event)

    view.plot.paintEvent = counted
    for step in range(1, 4):
        longer = np.linspace(0.0, 2.0 + step, 50 + 10 * step)
        view.set_series(longer, {"RB1": -longer * 1e-8})
        qtbot.wait(150)
    assert len(paints) == 3


@pytest.mark.qt_log_ignore(r"This plugin does not support propagateSizeHints\(\)")
def test_hologram_subsampled_to_the_screen_keeps_saturation(qtbot) -> None:
    view = HologramView()
    qtbot.addWidget(view)
    view.resize(300, 300)
    view.show()
    frame = np.full((1024, 1024), 100, np.uint16)
    frame[501, 733] = 4095  # one saturated pixel, off the subsampling grid
    view.set_saturation_value(4095)
    view.set_frame(frame)
    view.set_frame(frame)  # the second frame uses the view's scale
    step = view.display_step()
    assert step >= 2
    assert view.image.image.shape == (1024 // step, 1024 // step)
    assert view.overlay.image[501 // step, 733 // step, 0] == 255
    assert view.readout_at(733.5, 501.5) == "row 501, column 733: 4095"


@pytest.mark.qt_log_ignore(r"This plugin does not support propagateSizeHints\(\)")
@pytest.mark.parametrize("shape", [(1024, 1024), (600, 1000), (1000, 601)])
def test_hologram_shows_the_whole_frame_at_every_display_step(qtbot, shape) -> None:
    """After frames at a display step > 1, image and overlay cover the frame's extent."""
    view = HologramView()
    qtbot.addWidget(view)
    view.resize(300, 300)
    view.show()
    frame = np.full(shape, 100, np.uint16)
    frame[-1, -1] = 4095  # a saturated pixel in the last corner
    view.set_saturation_value(4095)
    for _ in range(3):
        view.set_frame(frame)
    step = view.display_step()
    assert step >= 2
    rows, cols = (shape[0] // step) * step, (shape[1] // step) * step
    for item in (view.image, view.overlay):
        extent = item.mapRectToParent(item.boundingRect())  # in data coordinates
        assert (extent.left(), extent.top()) == (0, 0)
        assert (extent.width(), extent.height()) == pytest.approx((cols, rows))


def test_the_colour_range_is_the_trusted_surface_not_a_noisy_peak_or_wild_pixels() -> None:
    """A 10 nm wave field fills the colour scale (issue 27): untrusted pixels are NaN and
    left out, a noisy peak's map and a few wild pixels do not set the range."""
    y, x = np.mgrid[0:128, 0:128]
    waves = 10.0 * np.sin(2 * np.pi * x / 32) * np.cos(2 * np.pi * y / 40)  # nm
    rng = np.random.default_rng(1)
    good = waves + rng.normal(0, 0.5, waves.shape)
    good[:20, :20] = np.nan  # outside the aperture: untrusted
    noisy = waves + rng.normal(0, 60.0, waves.shape)  # a weak peak
    wild = good.copy()
    wild[60:62, 60:62] = 5000.0  # four wild pixels
    low, high = colour_range({"RB1": good, "RB3": noisy, "FB1": wild, FUSED: good})
    finite = good[np.isfinite(good)]
    assert (low, high) == pytest.approx(tuple(np.percentile(finite, (1, 99))), abs=0.5)
    assert -12 < low < -7 and 7 < high < 12  # the waves fill the scale
    # no fused map: the median of the maps' own ranges, not their union
    low, high = colour_range({"RB1": good, "RB3": noisy, "FB1": wild})
    assert -12 < low < -7 and 7 < high < 12
    assert colour_range({"RB1": np.full((4, 4), np.nan)}) is None
    assert colour_range({"RB1": np.zeros((4, 4)), FUSED: np.zeros((4, 4))}) is None


def test_a_reference_frame_s_zero_maps_leave_the_range_to_the_next_maps(qtbot) -> None:
    """Paused on a frame after a jump, its maps are zero (relative reference); the next
    frame's maps, even within the follow interval, set the range."""
    view = SurfaceView()
    qtbot.addWidget(view)
    view.set_maps({"RB1": np.zeros((32, 32))})
    assert view.levels == (-1.0, 1.0)  # nothing to take a range from
    waves = 10e-9 * np.sin(np.linspace(0, 20, 32 * 32)).reshape(32, 32)
    view.set_maps({"RB1": waves})
    low, high = view.levels
    assert -10.5 < low < -9 and 9 < high < 10.5


def test_follow_ranges_the_last_maps_even_when_no_more_come(qtbot) -> None:
    """Maps that arrive within the follow interval of the last range (a replay stepped or
    paused right after an update) are ranged once it has passed, with no maps after them
    (before: the range of the frame before stayed, every map one colour)."""
    view = SurfaceView()
    qtbot.addWidget(view)
    waves = 10e-9 * np.sin(np.linspace(0, 20, 32 * 32)).reshape(32, 32)
    view.set_maps({"RB1": waves - 150e-9})
    assert view.levels[1] < -130.0
    view.set_maps({"RB1": waves})  # within the interval: not ranged yet
    qtbot.waitUntil(lambda: -10.5 < view.levels[0] < -9 and 9 < view.levels[1] < 10.5, timeout=3000)


#: Carriers of six labelled peaks crowded as the simulator's are (one quadrant of the
#: spectrum, 0.1-0.15 cycles/px apart), and a predicted one.
CROWDED = {
    "RB1": (-0.19, 0.07),
    "FB1": (-0.06, 0.16),
    "RF": (0.15, 0.09),
    "RB2": (-0.24, 0.2),
    "FB2": (-0.09, 0.29),
    "RB3": (-0.29, 0.36),
}


@pytest.mark.qt_log_ignore(r"This plugin does not support propagateSizeHints\(\)")
def test_crowded_peak_labels_cover_no_other_label_or_peak(qtbot) -> None:
    from PyQt6.QtCore import QPointF

    view, _ = _spectrum_view(qtbot)
    view.resize(460, 260)  # the spectrum panel's size in the window at 1366x768
    view.show()
    qtbot.waitExposed(view)
    view.set_model(CROWDED, {"FB3": (-0.13, 0.45)}, 0.08)
    qtbot.waitUntil(lambda: view.plot.getViewBox().width() > 100)
    boxes = view.label_boxes
    assert set(boxes) == {*CROWDED, "FB3?"}
    names = sorted(boxes)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            assert not boxes[a].intersects(boxes[b]), (a, b)
    box = view.plot.getViewBox()
    for name, box_rect in boxes.items():
        for other, (fx, fy) in CROWDED.items():
            if other != name:
                centre = box.mapViewToScene(QPointF(fx, fy))
                assert not box_rect.contains(centre), (name, other)


def test_a_label_goes_where_the_others_leave_room() -> None:
    labels = [PeakLabel("RB1", 0.0, 0.0), PeakLabel("RB2", 0.05, -0.02)]
    spots = place_labels(labels, char_size=(0.01, 0.02), view=(-0.5, -0.5, 0.5, 0.5), marker=0.01)
    # the first takes the preferred side (up and to the right of its peak) ...
    assert spots[0].anchor == (0.0, 1.0)
    assert spots[0].pos == pytest.approx((0.01, -0.01))
    # ... which the second peak's marker and label would cover: it takes another
    first = (0.01, -0.03, 0.04, -0.01)
    x, y = spots[1].pos
    left, top = x - spots[1].anchor[0] * 0.03, y - spots[1].anchor[1] * 0.02
    assert left >= first[2] or left + 0.03 <= first[0] or top >= first[3] or top + 0.02 <= first[1]
    # a label at the view's corner turns inwards
    view = (-0.5, -0.5, 0.5, 0.5)
    (edge,) = place_labels([PeakLabel("RB3", 0.49, -0.49)], (0.01, 0.02), view, 0.01)
    left, top = edge.pos[0] - edge.anchor[0] * 0.03, edge.pos[1] - edge.anchor[1] * 0.02
    assert left >= -0.5 and left + 0.03 <= 0.5 and top >= -0.5 and top + 0.02 <= 0.5


def test_the_maps_caption_ends_in_an_ellipsis_where_it_has_no_room(qtbot) -> None:
    view = SurfaceView()
    qtbot.addWidget(view)
    label = view.stats_label
    label.setText("maps of frame 38 (10 behind)")
    label.resize(90, 20)
    shown = label.elided()
    # the start is what is shown (the frame), the rest elided, never cut mid-text
    assert shown.startswith("maps of") and shown.endswith("…")
    assert label.toolTip() == "maps of frame 38 (10 behind)"
    label.resize(400, 20)
    assert label.elided() == "maps of frame 38 (10 behind)"
    assert label.sizePolicy().horizontalPolicy().name == "Ignored"


def test_follow_keeps_the_range_through_small_changes_and_takes_large_ones(qtbot) -> None:
    """The colours hold still while the maps' range moves by a few per cent (the colour
    bar is not redrawn every half second); a larger move, or Auto range, is taken."""
    view = SurfaceView()
    qtbot.addWidget(view)
    waves = 10e-9 * np.sin(np.linspace(0, 20, 32 * 32)).reshape(32, 32)
    view.set_maps({"RB1": waves})
    shown = view.levels
    view._range_at = -math.inf  # the follow interval has passed
    view.set_maps({"RB1": waves * 1.03})
    assert view.levels == shown
    view._range_at = -math.inf
    view.set_maps({"RB1": waves * 1.3})
    assert view.levels[1] == pytest.approx(1.3 * shown[1], rel=0.02)
    view.set_maps({"RB1": waves * 1.31})
    view.auto_range()  # the operator asks: taken as it is
    assert view.levels[1] == pytest.approx(1.31 * shown[1], rel=0.005)
