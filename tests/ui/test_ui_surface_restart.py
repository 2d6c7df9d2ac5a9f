"""The Surface panel at a restart of the maps, and its profile's range following the maps."""

from __future__ import annotations

import numpy as np

from holoview.ui.map_ranges import left_range, profile_range
from holoview.ui.surface_view import FUSED, SurfaceView


def _waves(amplitude_m: float, n: int = 32) -> np.ndarray:
    return amplitude_m * np.sin(np.linspace(0, 20, n * n)).reshape(n, n)


def _profile_fits(view: SurfaceView) -> bool:
    """Whether the profile's value range holds its curves, at most 1.5 times their span."""
    low, high = view.profile.getPlotItem().vb.viewRange()[1]
    values = np.concatenate([y for _, y in view.profile_curves().values()])
    span = float(values.max() - values.min())
    return low <= values.min() and values.max() <= high and high - low <= 1.5 * span


def test_a_restart_shows_no_zero_maps_and_ranges_the_next_at_once(qtbot) -> None:
    """Windows matched again restart the maps: the restart's frame (their new reference,
    zeros by construction) is not drawn, and the next maps set the colour range at once,
    within the follow interval (before: zeros shown on the old range, seen in the GUI)."""
    view = SurfaceView()
    qtbot.addWidget(view)
    old = _waves(100e-9)
    view.set_maps({"RB1": old, "FB1": old}, fused_m=old)
    assert view.levels[1] > 90.0
    zeros = np.zeros_like(old)
    view.set_maps({"RB1": zeros, "FB1": zeros}, fused_m=zeros, reference=True)
    assert np.nanmax(view.map_data(FUSED)) > 90.0  # the maps shown stay
    new = _waves(2e-9)
    view.set_maps({"RB1": new, "FB1": new}, fused_m=new)  # within the follow interval
    low, high = view.levels
    assert -2.1 < low < -1.8 and 1.8 < high < 2.1
    assert np.nanmax(np.abs(view.map_data(FUSED))) > 1.5
    assert _profile_fits(view)  # the profile follows the new maps


def test_the_profile_range_follows_the_maps_shown_not_the_colour_range(qtbot) -> None:
    """The profile's value range follows its curves at once, also while the colour range
    waits for the follow interval (before: the colour bar's range, behind the maps)."""
    view = SurfaceView()
    qtbot.addWidget(view)
    view.set_maps({"RB1": _waves(50e-9)})
    assert _profile_fits(view)
    view.set_maps({"RB1": _waves(5e-9) + 20e-9})  # within the follow interval and range
    assert view.levels[1] > 45.0  # the colour range has not followed yet
    assert _profile_fits(view)
    view.set_maps({"RB1": _waves(50e-9) + 200e-9})  # wider: the range grows at once
    assert _profile_fits(view)


def test_profile_range_keeps_a_range_that_fits_and_takes_one_that_does_not() -> None:
    assert profile_range(None, np.array([np.nan])) is None
    assert profile_range((0.0, 1.0), np.array([np.nan, np.inf])) == (0.0, 1.0)
    wide = profile_range(None, np.array([-10.0, 10.0]))
    assert wide == (-12.0, 12.0)
    assert profile_range(wide, np.array([-9.0, 8.0])) == wide  # fits: no new axis
    assert profile_range(wide, np.array([-1.0, 1.0])) == (-1.2, 1.2)  # far too wide
    assert profile_range(wide, np.array([0.0, 13.0])) == (-1.3, 14.3)  # a curve left it


def test_maps_that_left_the_colour_range_are_ranged_at_once(qtbot) -> None:
    """A level that moves faster than the follow interval (evaporation against an old
    reference) leaves the colour range between two updates: the maps are ranged again at
    once, not shown in one colour until the interval ends (seen in the screenshots)."""
    view = SurfaceView()
    qtbot.addWidget(view)
    level = _waves(0.2e-9)
    view.set_maps({"RB1": level}, fused_m=level)
    assert view.levels[0] < 0 < view.levels[1]
    inside = level + 0.1e-9  # moved, still mostly in range: the interval is waited for
    view.set_maps({"RB1": inside}, fused_m=inside)
    first = view.levels
    assert first[0] < 0 < first[1]
    lower = level - 30e-9  # within the follow interval, far below the range
    view.set_maps({"RB1": lower}, fused_m=lower)
    low, high = view.levels
    assert -30.3 < low < high < -29.7
    view.follow_box.setChecked(False)  # a range the operator holds is kept
    view.set_maps({"RB1": level}, fused_m=level)
    assert view.levels == (low, high)


def test_left_range_reads_the_fused_map_else_the_maps_median() -> None:
    ones = np.ones((16, 16))
    assert not left_range({"RB1": ones * 100, FUSED: ones}, (0.0, 2.0))
    assert left_range({"RB1": ones, FUSED: ones * 100}, (0.0, 2.0))
    assert left_range({"RB1": ones * 5, "FB1": ones * 6, "RF": ones}, (0.0, 2.0))
    assert not left_range({"RB1": np.full((4, 4), np.nan)}, (0.0, 2.0))
