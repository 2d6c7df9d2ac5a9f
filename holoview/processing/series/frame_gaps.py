"""Lost frames in a series: how many frame intervals a step between two frames spans.

A camera that loses frames (a full buffer, a dropped packet) leaves steps between the
frames kept that span several intervals; the phase of every peak moves over all of
them. On a clock that times when the frames were taken, a step longer than
``1 + GAP_TOLERANCE`` times the nominal interval (the median step) is a **gap**,
spanning ``round(step / nominal)`` intervals. The same rule cuts wave maps into runs
(:mod:`holoview.processing.waves.clock`) and steps the joint estimate over lost frames
(:mod:`.joint_estimation`); where only host arrival times are known, the camera's
frame counter says instead (``holoview.headless.inputs.frame_intervals``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["GAP_TOLERANCE", "intervals_of", "lost_between", "spans"]

#: A step longer than ``1 + GAP_TOLERANCE`` nominal intervals is a gap (lost frames).
GAP_TOLERANCE = 0.5


def spans(steps: NDArray[np.float64], nominal: float) -> NDArray[np.float64]:
    """Return the frame intervals each step (s) spans: 1, or ``round(step / nominal)``
    for a gap (a step over ``1 + GAP_TOLERANCE`` times ``nominal``, s).

    Examples
    --------
    >>> spans(np.array([0.05, 0.06, 0.55]), 0.05)
    array([ 1.,  1., 11.])
    """
    gap = steps > (1.0 + GAP_TOLERANCE) * nominal
    return np.where(gap, np.rint(steps / nominal), 1.0)


def intervals_of(times: NDArray[np.float64]) -> NDArray[np.int64]:
    """Per frame, the frame intervals since the one before (1 for the first), by
    :func:`spans` of the steps of ``times`` (s) over their median; with fewer than three
    frames, every step is one interval.

    Examples
    --------
    >>> intervals_of(np.array([0.0, 0.05, 0.1, 0.6]))
    array([ 1,  1,  1, 10])
    """
    out = np.ones(len(times), dtype=np.int64)
    if len(times) >= 3:
        steps = np.diff(times)
        out[1:] = spans(steps, float(np.median(steps)))
    return out


def lost_between(intervals: NDArray[np.int64]) -> tuple[int, NDArray[np.intp]]:
    """The frames lost between a series' frames, and the frames each gap ends at.

    ``intervals``: per frame, the frame intervals since the one before (as
    :func:`intervals_of` gives them); the first frame's own are not between two frames.

    Examples
    --------
    >>> lost_between(np.array([1, 1, 3, 1, 2]))
    (3, array([2, 4]))
    """
    steps = np.asarray(intervals[1:])
    return int(np.sum(steps - 1)), np.flatnonzero(steps > 1) + 1
