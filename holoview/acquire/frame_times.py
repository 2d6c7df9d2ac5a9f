"""Which clock times a recording's frames: the one rule, its checks, and what it says.

A holoview recording carries two clocks (:mod:`holoview.acquire.recording`): the
camera's (``t_device_s``, when the camera took each frame; NaN where it has none) and
the host's (``t_host_s``, when each frame arrived or was written, seconds since the
UNIX epoch). A clock is usable over a run of frames when every time is finite, every
step is positive, and no step is implausible: none longer than :data:`JUMP_FACTOR`
times the median step times the frames the camera's counter says passed (a lost frame
doubles a step honestly; a clock reset or a damaged stamp jumps by thousands), nor any
under :data:`MIN_JUMP_S`.
:func:`choose_clock` takes the camera's clock where usable, else the host's, else none,
and says which and why in one sentence (:attr:`FrameClock.note`): the replay's pace, a
recording's frame rate and ``holoview process`` (which then needs ``--fps``) all follow it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["JUMP_FACTOR", "FrameClock", "choose_clock", "clock_problem"]

#: Longest plausible step of a clock, in median steps per frame the counter says passed.
JUMP_FACTOR = 100.0

#: Steps up to this many seconds are plausible whatever the median (host arrival times
#: come in bursts: a median step of microseconds beside the frame period).
MIN_JUMP_S = 1.0

#: What each clock is called in notes.
CLOCK_NAMES = {
    "camera": "the camera's clock (t_device_s)",
    "host": "the host's arrival times (t_host_s)",
}


def _frame_span(frames: range) -> str:
    if len(frames) == 1:
        return f"frame {frames[0]}"
    return f"frames {frames[0]}..{frames[-1]}"


def clock_problem(
    times: NDArray[np.float64], frames: range, ids: NDArray[np.int64] | None = None
) -> str | None:
    """Why ``times`` cannot time ``frames``, or None when they can.

    Parameters
    ----------
    times : ndarray, shape (n,)
        One time per frame, seconds.
    frames : range
        The frames' indices in the file (for messages), ``n`` of them.
    ids : ndarray of int, optional
        The camera's frame counter: a step over a gap of ``k`` frames may be ``k`` times
        longer.
    """
    n = len(times)
    bad = np.flatnonzero(~np.isfinite(times))
    if bad.size == n:
        return "it holds no time"
    if bad.size:
        return f"{bad.size} of its {n} times are not finite (the first at frame {frames[bad[0]]})"
    if n < 2:
        return None
    steps = np.diff(times)
    back = np.flatnonzero(steps <= 0)
    if back.size == steps.size:
        still = bool(np.all(steps == 0))
        return "it stands still (every time equal)" if still else "it runs backwards"
    if back.size:
        k = int(back[0])
        return (
            f"it steps by {steps[k]:.3g} s at frame {frames[k + 1]} "
            f"({back.size} of its {steps.size} steps are not forward)"
        )
    median = float(np.median(steps))
    passed = np.ones_like(steps)
    if ids is not None and len(ids) == n:
        passed = np.maximum(np.diff(ids.astype(np.float64)), 1.0)
    jumps = np.flatnonzero(steps > np.maximum(JUMP_FACTOR * median * passed, MIN_JUMP_S))
    if jumps.size:
        k = int(jumps[0])
        return (
            f"it jumps by {steps[k]:.3g} s at frame {frames[k + 1]} "
            f"(the median step is {median:.3g} s)"
        )
    return None


@dataclass(frozen=True)
class FrameClock:
    """The clock chosen for a run of frames, and why.

    Attributes
    ----------
    times : ndarray
        Per frame, seconds on the chosen clock (NaN everywhere when none is usable).
    source : {"camera", "host", "none"}
        The clock used.
    frames : range
        The frames' indices in the file.
    camera_problem, host_problem : str or None
        Why each clock was not usable (None: usable, or not looked at).
    camera_name : str
        What the camera's clock is called in the note (a video's: its frame rate).
    camera_rate_hz : float or None
        Where the camera's clock was not used: the rate of its median forward step,
        frames per second (a hint for ``--fps``), where it has one.
    """

    times: NDArray[np.float64]
    source: str
    frames: range
    camera_problem: str | None = None
    host_problem: str | None = None
    camera_name: str = CLOCK_NAMES["camera"]
    camera_rate_hz: float | None = None

    @property
    def usable(self) -> bool:
        """Whether a clock times the frames."""
        return self.source != "none"

    @property
    def fallback(self) -> bool:
        """True when the camera had a clock that was not usable (its times are damaged)."""
        return self.source != "camera" and self.camera_problem not in (None, "it holds no time")

    @property
    def note(self) -> str:
        """One sentence: which clock times which frames, and why not the camera's."""
        span = _frame_span(self.frames)
        if self.source == "camera":
            return f"frame times of {span}: {self.camera_name}"
        camera = f"{self.camera_name} is not used: {self.camera_problem}"
        if self.camera_rate_hz is not None:
            camera += f"; its median step gives {self.camera_rate_hz:.6g} frames/s (--fps)"
        if self.source == "host":
            return (
                f"frame times of {span}: {CLOCK_NAMES['host']}, which time when the frames "
                f"arrived, not when they were taken ({camera})"
            )
        host = "" if self.host_problem is None else f"; the host's: {self.host_problem}"
        return f"{span} have no usable times ({camera}{host})"


def choose_clock(
    t_device: NDArray[np.float64],
    t_host: NDArray[np.float64] | None,
    frames: range,
    ids: NDArray[np.int64] | None = None,
    *,
    unusable: dict[str, str] | None = None,
    camera_name: str = CLOCK_NAMES["camera"],
) -> FrameClock:
    """The camera's clock where usable, else the host's, else none (see the module).

    Parameters
    ----------
    t_device : ndarray, shape (n,)
        The camera's times of the frames, seconds (NaN where none).
    t_host : ndarray, shape (n,), or None
        The host's, seconds (None for files without them).
    frames : range
        The frames' indices in the file, ``n`` of them (for messages).
    ids : ndarray of int, optional
        The camera's frame counter of the frames.
    unusable : dict, optional
        ``"camera"`` or ``"host"`` to why that clock is known to be unusable (a column
        of the wrong layout in the file).
    camera_name : str
        What the camera's clock is called in the note.
    """
    known = unusable or {}
    camera = known.get("camera") or clock_problem(t_device, frames, ids)
    if camera is None:
        return FrameClock(t_device, "camera", frames, camera_name=camera_name)
    rate = None if "camera" in known else _median_rate(t_device)
    none = np.full(len(frames), math.nan)
    host = None
    if t_host is not None:
        host = known.get("host") or clock_problem(t_host, frames, ids)
        if host is None:
            return FrameClock(t_host, "host", frames, camera, None, camera_name, rate)
    return FrameClock(none, "none", frames, camera, host, camera_name, rate)


def _median_rate(times: NDArray[np.float64]) -> float | None:
    """The rate of a clock's median finite forward step, frames per second (None: none)."""
    steps = np.diff(times)
    forward = steps[np.isfinite(steps) & (steps > 0)]
    if forward.size == 0:
        return None
    return float(1.0 / np.median(forward))
