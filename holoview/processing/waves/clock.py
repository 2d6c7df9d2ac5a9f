"""Frame times: the nominal interval, the gaps left by lost frames, the segments between them.

Every wave analysis takes the true time of each map. Maps are evenly spaced in time
except where frames were lost: a step between two frames longer than
``(1 + GAP_TOLERANCE)`` nominal intervals is a **gap**. Gaps are never closed:

- Spectra (omega-k, E(omega), the (m, f) spectrum) average segments of consecutive
  frames that do not span a gap (Welch's method); frames of a run shorter than a
  segment are not used, and the analyses say how many frames that left out.
- Lock-in maps, radial profiles and ringdown fits are least-squares estimates on the
  true times, which need no even spacing; the ringdown's band-pass filter runs within
  each gap-free run.

Within a run the frames are taken to be evenly spaced at the nominal interval (the
median step); the largest departure from it is reported (:attr:`FrameClock.jitter`).
A frame rate that changes within the maps is refused, where it changes: its frames
would be analysed at the nominal rate, their frequencies scaled. (Halving the rate
cannot be told from losing every other frame: such steps are gaps.)
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from holoview.errors import InputError
from holoview.processing.series.frame_gaps import GAP_TOLERANCE, spans

__all__ = ["GAP_TOLERANCE", "FrameClock", "frame_clock"]

#: Steps over which the local rate is taken: their mean, the time they span over their
#: number, in which a clock's jitter of each time stamp falls as ``1 / RATE_STEPS``.
RATE_STEPS = 64
#: Largest departure of the local interval from the nominal one, as a share of it, before
#: the frame rate is taken to have changed.
RATE_CHANGE = 0.05


@dataclass(frozen=True)
class FrameClock:
    """The timing of a sequence of maps.

    Attributes
    ----------
    times : ndarray of float, shape (N,)
        The frame times, s.
    interval : float
        Nominal time between frames, s (the median step).
    runs : tuple of (int, int)
        ``[start, stop)`` frame indices of the gap-free runs, in order.
    lost : int
        Frames missing in the gaps (each gap's step in intervals, less one, rounded).
    jitter : float
        Largest departure of a step within a run from the nominal interval, s.
    """

    times: np.ndarray
    interval: float
    runs: tuple[tuple[int, int], ...]
    lost: int
    jitter: float

    @property
    def frames(self) -> int:
        """Number of frames."""
        return int(self.times.size)

    @property
    def gaps(self) -> int:
        """Number of gaps (runs less one)."""
        return len(self.runs) - 1

    @property
    def rate(self) -> float:
        """Nominal frame rate, frames/s."""
        return 1.0 / self.interval

    @property
    def duration(self) -> float:
        """Time from the first frame to the last, s."""
        return float(self.times[-1] - self.times[0])

    @property
    def nyquist(self) -> float:
        """Highest frequency the maps resolve, Hz (half the nominal rate)."""
        return 0.5 / self.interval

    def check_resolved(self, frequency: float, what: str) -> None:
        """Refuse a ``frequency`` (Hz) the maps cannot resolve: above :attr:`nyquist`.

        A wave above it is sampled as one at its alias, which the message names.

        Raises
        ------
        InputError
            ``what`` at ``frequency`` lies above the Nyquist frequency.

        Examples
        --------
        >>> frame_clock([0.0, 0.01, 0.02]).check_resolved(60.0, "the drive")
        Traceback (most recent call last):
        ...
        holoview.errors.InputError: the drive at 60 Hz is above the maps' Nyquist frequency \
50 Hz (half of 100 maps/s): a wave there is sampled as one at 40 Hz
        """
        if frequency > self.nyquist * (1 + 1e-9):
            rate = self.rate
            alias = abs(frequency - rate * round(frequency / rate))
            seen = f"one at {alias:.4g} Hz" if alias > 1e-9 * rate else "a steady level (0 Hz)"
            raise InputError(
                f"{what} at {frequency:.4g} Hz is above the maps' Nyquist frequency "
                f"{self.nyquist:.4g} Hz (half of {rate:.4g} maps/s): a wave there is sampled "
                f"as {seen}"
            )


def frame_clock(times: ArrayLike) -> FrameClock:
    """Return the clock of maps taken at ``times`` (s).

    Parameters
    ----------
    times : array_like of float, shape (N,)
        Time of each map, s, strictly increasing (N >= 2).

    Returns
    -------
    FrameClock

    Raises
    ------
    InputError
        Fewer than two times, a time that is not finite, times that do not increase, or
        a frame rate that changes: the mean of :data:`RATE_STEPS` steps (a gap counted
        as the intervals it spans) departs from the nominal interval by more than
        :data:`RATE_CHANGE` of it (the message names the first such frame). A run at
        another rate would be analysed as if at the nominal one, its frequencies scaled.

    Examples
    --------
    >>> clock = frame_clock([0.0, 0.01, 0.02, 0.05, 0.06])
    >>> clock.runs, clock.lost
    (((0, 3), (3, 5)), 2)
    """
    t = np.asarray(times, dtype=np.float64).ravel()
    if t.size < 2:
        raise InputError(f"the maps need at least two frame times, got {t.size}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise InputError(f"the time of frame {int(bad[0])} is not finite ({t[bad[0]]})")
    steps = np.diff(t)
    back = np.flatnonzero(steps <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise InputError(
            f"frame times must increase: frame {i} at {float(t[i])!r} s follows "
            f"{float(t[i - 1])!r} s"
        )
    interval = float(np.median(steps))
    intervals = spans(steps, interval)
    gap = intervals > 1
    cuts = np.flatnonzero(gap) + 1
    edges = [0, *cuts.tolist(), t.size]
    runs = tuple((int(a), int(b)) for a, b in itertools.pairwise(edges))
    lost = int(np.sum(intervals - 1))
    _check_rate(steps, intervals, interval)
    inside = steps[~gap]
    jitter = float(np.max(np.abs(inside - interval))) if inside.size else 0.0
    return FrameClock(t, interval, runs, lost, jitter)


def _check_rate(steps: np.ndarray, intervals: np.ndarray, interval: float) -> None:
    """Refuse ``steps`` whose local mean, over the nominal ``intervals`` each spans (more
    than one across a gap), departs from ``interval`` (:func:`frame_clock`)."""
    if steps.size < RATE_STEPS:
        return
    time, count = (np.concatenate([[0.0], np.cumsum(v)]) for v in (steps, intervals))
    local = (time[RATE_STEPS:] - time[:-RATE_STEPS]) / (count[RATE_STEPS:] - count[:-RATE_STEPS])
    off = np.flatnonzero(np.abs(local - interval) > RATE_CHANGE * interval)
    if off.size:
        # where it changed: the first window nearly all past it (the next windows'
        # largest departure, nine tenths of it)
        ahead = np.abs(local[off[0] : off[0] + RATE_STEPS] - interval)
        start = int(off[0]) + int(np.argmax(ahead >= 0.9 * ahead.max()))
        after = float(np.median(steps[start : start + RATE_STEPS]))
        raise InputError(
            f"the frame rate changes: around frame {start + 1} the maps come every "
            f"{after * 1e3:.4g} ms, most of them every {interval * 1e3:.4g} ms; "
            "analyse each rate apart (a time range)"
        )
