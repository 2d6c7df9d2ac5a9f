"""The ranges of the maps shown: their colours' and their profile's (plain functions).

The height colour range is :func:`colour_range`: percentiles of the trusted pixels, of
the fused map where there is one; :func:`left_range` says when the maps have left the
range shown between two of its updates (most of them one colour), :func:`settled` when a
new range is too close to the one shown to be worth taking; the profile's value
range (:func:`profile_range`) follows its curves without regenerating its axis every
frame.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from holoview.ui.legends import FUSED

__all__ = [
    "FOLLOW_TOLERANCE",
    "MEDIAN_SAMPLES",
    "PROFILE_MARGIN",
    "PROFILE_SLACK",
    "RANGE_PERCENTILES",
    "RANGE_SAMPLES",
    "colour_range",
    "left_range",
    "profile_range",
    "settled",
]

#: Percentiles of the trusted pixels that set the height range (:func:`colour_range`).
RANGE_PERCENTILES = (1.0, 99.0)
#: Pixels of a map sampled for its range, at most about.
RANGE_SAMPLES = 16384
#: Pixels of a map sampled for its median (:func:`left_range`: checked at every draw).
MEDIAN_SAMPLES = 1024
#: While following, a new colour range within this fraction of the span shown from it at
#: both ends is not taken: the colours hold still (the 1-99 percentiles of a noisy map
#: move by a few per cent from frame to frame), and the colour bar's axis is not drawn
#: again every half second.
FOLLOW_TOLERANCE = 0.05
#: Margin of the profile's value range beyond its curves, fraction of their span.
PROFILE_MARGIN = 0.1
#: The profile's value range is taken again when it is more than this many times wider
#: than its curves need (and whenever a curve leaves it): it follows the maps without
#: regenerating its axis every frame.
PROFILE_SLACK = 3.0


def colour_range(
    maps: Mapping[str, np.ndarray], percentiles: tuple[float, float] = RANGE_PERCENTILES
) -> tuple[float, float] | None:
    """The colour range of height maps: percentiles of their finite (trusted) values.

    The fused map's where there is one (the peaks' noise-weighted mean: the surface
    best seen); else the median, over the maps, of each map's percentiles, so that one
    noisy peak does not set the range of all. None without a finite value, or where
    the values are all equal (a reference frame's zero maps say nothing of the range).

    Parameters
    ----------
    maps : mapping of str to ndarray
        Maps by name (``"fused"`` for the fused one), any unit; NaN where untrusted.
    percentiles : (float, float)
        The low and high percentiles, in [0, 100].
    """
    fused = _percentiles(maps[FUSED], percentiles) if FUSED in maps else None
    if fused is not None:  # the others' are not needed (a sixth of a draw's time)
        chosen = [fused]
    else:
        ranges = (_percentiles(data, percentiles) for data in maps.values())
        chosen = [r for r in ranges if r is not None]
    if not chosen:
        return None
    low, high = (float(v) for v in np.median(np.array(chosen), axis=0))
    return (low, high) if high > low else None


def profile_range(
    current: tuple[float, float] | None, values: np.ndarray
) -> tuple[float, float] | None:
    """The profile's value range for curves holding ``values``: ``current`` while it fits.

    ``current`` is kept while every finite value lies inside it and it is at most
    :data:`PROFILE_SLACK` times the curves' span (plus margins); else the curves' span
    with a :data:`PROFILE_MARGIN` on each side. None (keep what is shown) without a
    finite value.

    Examples
    --------
    >>> profile_range(None, np.array([0.0, 10.0]))
    (-1.0, 11.0)
    >>> profile_range((-1.0, 11.0), np.array([2.0, 9.0]))
    (-1.0, 11.0)
    >>> profile_range((-1.0, 11.0), np.array([0.0, 1.0]))
    (-0.1, 1.1)
    """
    finite = values[np.isfinite(values)]
    if not finite.size:
        return current
    low, high = float(finite.min()), float(finite.max())
    span = high - low if high > low else max(abs(high), 1e-3)
    wanted = (low - PROFILE_MARGIN * span, high + PROFILE_MARGIN * span)
    if current is not None:
        inside = current[0] <= low and high <= current[1]
        if inside and current[1] - current[0] <= PROFILE_SLACK * (wanted[1] - wanted[0]):
            return current
    return wanted


def settled(
    shown: tuple[float, float], new: tuple[float, float], tolerance: float = FOLLOW_TOLERANCE
) -> bool:
    """Whether the range ``new`` is within ``tolerance`` of the span of ``shown`` at both ends.

    Examples
    --------
    >>> settled((0.0, 10.0), (0.3, 10.4)), settled((0.0, 10.0), (0.0, 11.0))
    (True, False)
    """
    slack = tolerance * (shown[1] - shown[0])
    return abs(new[0] - shown[0]) <= slack and abs(new[1] - shown[1]) <= slack


def left_range(maps: Mapping[str, np.ndarray], levels: tuple[float, float]) -> bool:
    """Whether the maps' median lies outside ``levels``: most of the maps one colour.

    The fused map's median where there is one, else the median of the maps' medians
    (as :func:`colour_range`). A level that moves faster than the follow interval
    (evaporation seen against an old reference) leaves the range between two updates.

    Examples
    --------
    >>> flat = np.full((8, 8), 5.0)
    >>> left_range({"RB1": flat}, (0.0, 10.0)), left_range({"RB1": flat + 20}, (0.0, 10.0))
    (False, True)
    """
    fused = maps.get(FUSED)
    chosen = [fused] if fused is not None and np.isfinite(fused).any() else list(maps.values())
    medians = [_percentiles(d, (50.0, 50.0), MEDIAN_SAMPLES) for d in chosen]
    known = [float(m[0]) for m in medians if m is not None]
    if not known:
        return False
    middle = float(np.median(known))
    return not levels[0] <= middle <= levels[1]


def _percentiles(
    data: np.ndarray, percentiles: tuple[float, float], samples: int = RANGE_SAMPLES
) -> np.ndarray | None:
    """The percentiles of the finite values of ``data`` (about ``samples`` of them)."""
    step = max(1, int(math.sqrt(data.size / samples)))
    values = data[::step, ::step]
    values = values[np.isfinite(values)]
    return np.percentile(values, percentiles) if values.size else None
