"""Steer a replay from a window: the Qt-free half of the transport bar.

A :class:`ReplayControl` wraps a :class:`~holoview.acquire.replay.ReplaySource` that
streams on the camera thread: play and pause, a step either way, a seek, the speed
(:data:`SPEED_STEPS` times the recorded pace, or as fast as frames can be read) and
looping. Every call returns at once; the frame asked for reaches the ring, the maps
and the series like any other (a seek or a jump opens a new segment, see
:mod:`holoview.live.continuity`). :meth:`ReplayControl.state` is what a transport bar
draws: the frame shown, the file's length, the recording's time of the frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from holoview.acquire.replay import ReplayClock, ReplaySource
from holoview.acquire.source import Source

__all__ = ["FASTEST", "SPEED_STEPS", "ReplayControl", "ReplayState", "speed_text"]

#: The speed meaning "as fast as frames can be read".
FASTEST = math.inf
#: The speeds offered, times the recorded pace (slowest first).
SPEED_STEPS: tuple[float, ...] = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, FASTEST)


def speed_text(speed: float) -> str:
    """A speed in words: ``"0.25x"``, ``"1x"``, ``"fastest"``."""
    return "fastest" if math.isinf(speed) else f"{speed:g}x"


@dataclass(frozen=True)
class ReplayState:
    """Where a replay stands.

    Attributes
    ----------
    index : int
        Index of the frame shown, from 0 (-1 before the first).
    n_frames : int
        Frames in the file.
    time_s : float
        The recording's time of that frame since its first frame, seconds (NaN before one).
    paused : bool
        No frame comes but on a step or a seek.
    held : bool
        Paused on the last frame at the end (no loop).
    speed : float
        Times the recorded pace; :data:`FASTEST` for as fast as frames can be read.
    loop : bool
        The replay starts over at its end.
    segment : int
        Segment of the frame shown (:mod:`holoview.live.continuity`): the frames
        delivered after a seek or a step back are of a higher one.
    """

    index: int
    n_frames: int
    time_s: float
    paused: bool
    held: bool
    speed: float
    loop: bool
    segment: int = 0

    @property
    def text(self) -> str:
        """``"frame 120 / 299 · 4.000 s"``: the index shown, the last index, the time."""
        last = self.n_frames - 1
        if self.index < 0:
            return f"frame - / {last}"
        time = "" if not math.isfinite(self.time_s) else f" · {self.time_s:.3f} s"
        return f"frame {self.index} / {last}{time}"


class ReplayControl:
    """Play, pause, step, seek, speed and loop of a streaming replay; safe from any thread.

    Parameters
    ----------
    source : ReplaySource
        An open replay (streaming or about to).

    Examples
    --------
    A replay of 300 frames at 60 frames/s, steered (a window's transport bar does this):

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from holoview.acquire.recording_writer import RecordingWriter
    >>> path = Path(tempfile.mkdtemp()) / "run.h5"
    >>> with RecordingWriter(path, (8, 8), np.uint8) as writer:
    ...     for i in range(300):
    ...         writer.append(np.full((8, 8), i % 256, np.uint8), i, i / 60, i / 60)
    >>> with ReplaySource(path, hold=True) as source:
    ...     source.start()
    ...     control = ReplayControl.of(source)
    ...     _ = control.pause(), control.seek(120), control.step(-1), source.fetch(1.0)
    ...     control.state().text
    'frame 119 / 299 · 1.983 s'
    """

    def __init__(self, source: ReplaySource) -> None:
        self.source = source

    @classmethod
    def of(cls, source: Source) -> ReplayControl | None:
        """A control for ``source`` if it is a replay, else None (a camera is not steered)."""
        return cls(source) if isinstance(source, ReplaySource) else None

    @property
    def path(self) -> Path:
        """The file replayed."""
        return self.source.path

    def clock(self) -> ReplayClock:
        """What times the frames (:meth:`~holoview.acquire.replay.ReplaySource.clock`)."""
        return self.source.clock()

    def state(self) -> ReplayState:
        """Where the replay stands now."""
        source = self.source
        index = source.shown
        return ReplayState(
            index=index,
            n_frames=source.n_frames,
            time_s=source.frame_time_s(index) if index >= 0 else math.nan,
            paused=source.paused,
            held=source.held,
            speed=self.speed,
            loop=source.loop,
            segment=source.segment,
        )

    # ---- play and pause ----------------------------------------------------
    def play(self) -> None:
        """Play on from the frame shown (from the first when held at the end)."""
        if self.source.get("speed") == "step":
            self.source.set("speed", "recorded")
        self.source.resume()

    def pause(self) -> None:
        """Hold the frame shown."""
        self.source.pause()

    def toggle(self) -> bool:
        """Play when paused, pause when playing; return True when it now plays."""
        if self.source.paused:
            self.play()
            return True
        self.pause()
        return False

    # ---- moving ------------------------------------------------------------
    def step(self, n: int = 1) -> int:
        """Pause and show the frame ``n`` after the one shown (clamped); return its index."""
        return self.source.step(n)

    def seek(self, index: int) -> int:
        """Show frame ``index`` next (play goes on after it when playing); return it.

        The frame opens a new segment: its relative maps start from it, wherever play
        had stopped.

        Raises
        ------
        InputError
            ``index`` outside the file (one line, with the file's range).
        """
        return self.source.seek(index)

    def show_again(self) -> None:
        """Paused on a frame: deliver it once more (the maps follow new settings); else nothing."""
        state = self.state()
        if state.paused and state.index >= 0:
            self.source.seek(state.index)

    def to_start(self) -> int:
        """Show the first frame; return its index."""
        return self.source.seek(0)

    def to_end(self) -> int:
        """Show the last frame; return its index."""
        return self.source.seek(self.source.n_frames - 1)

    # ---- speed and loop ----------------------------------------------------
    @property
    def speed(self) -> float:
        """Times the recorded pace, or :data:`FASTEST`."""
        if self.source.get("speed") == "fast":
            return FASTEST
        return float(self.source.speed_factor)

    def set_speed(self, speed: float) -> float:
        """Play at ``speed`` times the recorded pace (:data:`FASTEST`: as fast as it reads).

        Returns the speed read back.

        Raises
        ------
        InputError
            A factor outside 0.25 to 8 (other than :data:`FASTEST`).
        """
        if math.isinf(speed):
            self.source.set("speed", "fast")
        else:
            self.source.set("speed_factor", speed)
            if self.source.get("speed") != "step":
                self.source.set("speed", "recorded")
        return self.speed

    def faster(self) -> float:
        """Go to the next speed of :data:`SPEED_STEPS` up; return the speed now."""
        higher = [s for s in SPEED_STEPS if s > self.speed]
        return self.set_speed(higher[0]) if higher else self.speed

    def slower(self) -> float:
        """Go to the next speed of :data:`SPEED_STEPS` down; return the speed now."""
        lower = [s for s in SPEED_STEPS if s < self.speed]
        return self.set_speed(lower[-1]) if lower else self.speed

    def set_loop(self, on: bool) -> None:
        """Start over at the end (on), or hold on the last frame (off)."""
        self.source.set("loop", bool(on))
