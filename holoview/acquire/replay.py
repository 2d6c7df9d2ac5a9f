"""Replay: a recording, TIFF stack, image folder or video played as a camera.

Three speeds (the ``speed`` setting):

- ``"recorded"``: a holoview recording at the pace of its timestamps (the clock
  rule of :mod:`holoview.acquire.frame_times`: the camera's clock where it is finite,
  forward and free of jumps, else host arrival times); other files at
  ``rate_hz`` (default: the video's own rate, or 30 frames/s for images); the
  ``speed_factor`` setting plays faster or slower than that (0.25 to 8 times);
- ``"fast"``: as fast as frames can be read;
- ``"step"``: frames only on :meth:`ReplaySource.step` and :meth:`ReplaySource.seek`.

The replay can be steered while it streams, from any thread (a transport bar):
:meth:`~ReplaySource.pause` and :meth:`~ReplaySource.resume`,
:meth:`~ReplaySource.step` (one frame either way, pausing), :meth:`~ReplaySource.seek`
(a frame index; one past the end is a one-line :class:`~holoview.errors.InputError`).
Each frame's :class:`~holoview.acquire.source.FrameMeta` carries its ``file_index`` in
the file and its ``segment``: a frame sought (:meth:`~ReplaySource.seek`, even to the
frame after the one shown) and a frame that is not the one after the previous frame
delivered (a step back, the loop starting over) open a new segment, so processing never
pairs frames across a jump, and a frame sought is where its relative maps start, wherever
play had stopped.

Each frame is stamped (``FrameMeta.t_device``) with its time in the recording, so that
what the frames measure over time (a rate) is the same at every speed: the file's own
clock where it has a usable one (the one rule of :mod:`holoview.acquire.frame_times`:
a recording's camera clock, else its host's; a video's frame rate), else the index over
the frame rate given (``rate_hz``), else over :data:`DEFAULT_RATE_HZ`, assumed; a rate
given replaces the file's clock, as ``holoview process --fps`` does.
:meth:`ReplaySource.clock` says which, in words.

With ``loop`` the file starts over at its end (frame ids keep increasing, device
times too); otherwise, with ``hold``, the replay pauses on the last frame (a
window keeps showing it; resuming plays from the start again); otherwise
:meth:`~holoview.acquire.source.Source.fetch` raises
:class:`~holoview.acquire.source.EndOfStream` after the last frame. A holoview
recording still being written is followed: at its end the replay refreshes it
and goes on with the frames flushed since. Before each frame is read the file is
checked (:meth:`~holoview.acquire.frame_file.FrameFile.check`): a file that
disappeared or shrank since it was opened ends the stream with a one-line error
naming it and the frame.
"""

from __future__ import annotations

import bisect
import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from holoview.acquire.frame_file import FrameFile
from holoview.acquire.frame_times import CLOCK_NAMES, FrameClock
from holoview.acquire.replay_files import HDF5File, open_frame_file
from holoview.acquire.source import (
    AcquisitionError,
    EndOfStream,
    Frame,
    FrameMeta,
    Setting,
    Source,
)
from holoview.errors import InputError

#: Playback rate for files that carry none (TIFF stacks, image folders), frames per second.
DEFAULT_RATE_HZ = 30.0
#: The replay speeds.
SPEEDS = ("recorded", "fast", "step")
#: Slowest and fastest ``speed_factor`` against the recorded pace.
SPEED_FACTOR_LIMITS = (0.25, 8.0)


@dataclass(frozen=True)
class ReplayClock:
    """What times a replay's frames (the module docstring's rule).

    Attributes
    ----------
    origin : {"file", "given", "assumed"}
        The file's own clock; a frame rate given; :data:`DEFAULT_RATE_HZ` assumed for a
        file without times.
    rate_hz : float or None
        The frame rate that times the frames, frames per second (None: the file's clock).
    text : str
        Which, in words (``"10 frames/s, given"``).
    """

    origin: str
    rate_hz: float | None
    text: str


class ReplaySource(Source):
    """Play a frame file as a camera.

    Parameters
    ----------
    path : str or Path
        A holoview recording (``.h5``), a TIFF stack, a folder of TIFF/PNG images,
        or a video (``.avi``, ``.mkv``, ``.mp4``, ``.mov``).
    speed : {"recorded", "fast", "step"}
        See the module docstring.
    rate_hz : float, optional
        Playback rate, frames per second, for files without timestamps.
    loop : bool
        Start over at the end instead of ending the stream.
    hold : bool
        Without ``loop``: pause on the last frame instead of ending the stream.
    speed_factor : float
        Times the recorded pace (``"recorded"`` speed), within :data:`SPEED_FACTOR_LIMITS`.

    Examples
    --------
    A recording of 200 frames, then its replay steered by hand:

    >>> import tempfile
    >>> from holoview.acquire.recording_writer import RecordingWriter
    >>> path = Path(tempfile.mkdtemp()) / "run.h5"
    >>> with RecordingWriter(path, (8, 8), np.uint8) as writer:
    ...     for i in range(200):
    ...         writer.append(np.full((8, 8), i, np.uint8), i, i / 60, i / 60)
    >>> with ReplaySource(path, hold=True) as source:
    ...     source.start()
    ...     source.pause()
    ...     (source.seek(120), source.step(-1), source.fetch(1.0).meta.file_index)
    (120, 119, 119)
    """

    def __init__(
        self,
        path: str | Path,
        *,
        speed: str = "recorded",
        rate_hz: float | None = None,
        loop: bool = False,
        hold: bool = False,
        speed_factor: float = 1.0,
    ) -> None:
        super().__init__(f"replay:{path}")
        self.path = Path(path)
        self._file: FrameFile | None = None
        self._file_clock: FrameClock | None = None
        self._speed = speed
        self._rate_hz = rate_hz
        self._loop = bool(loop)
        self._hold = bool(hold)
        self._factor = 1.0
        self._position = 0  # the next frame to play
        self._shown = -1  # the last frame delivered
        self._jump: int | None = None  # a frame to deliver at once (seek, step)
        self._sought = False  # the jump comes from a seek: it opens a segment
        self._paused = False
        self._held = False
        self._segment = 0
        self._loops = 0
        self._due = 0.0
        self._cond = threading.Condition()
        self.add_setting(
            Setting(
                "speed",
                "enum",
                lambda: self._speed,
                self._set_speed,
                choices=SPEEDS,
                doc="recorded pace, as fast as possible, or one frame per step",
            )
        )
        self.add_setting(
            Setting(
                "speed_factor",
                "float",
                lambda: self._factor,
                self._set_factor,
                limits=SPEED_FACTOR_LIMITS,
                doc="times the recorded pace (0.25 to 8)",
            )
        )
        self.add_setting(
            Setting(
                "rate_hz",
                "float",
                self._effective_rate,
                self._set_rate,
                unit="Hz",
                limits=(0.01, 10000.0),
                doc="playback rate for files without timestamps",
            )
        )
        self.add_setting(
            Setting("loop", "bool", lambda: self._loop, self._set_loop, doc="start over at the end")
        )
        self.add_setting(
            Setting("n_frames", "int", lambda: self.n_frames, doc="frames in the file")
        )
        self.add_setting(Setting("pixel_format", "enum", lambda: self._require_file().pixel_format))
        if speed not in SPEEDS:
            raise InputError(f"replay speed must be one of {', '.join(SPEEDS)}, got {speed!r}")
        self._set_factor(self._settings["speed_factor"].validate(speed_factor))

    # -- Source hooks ------------------------------------------------------------
    def _do_open(self) -> None:
        self._file = open_frame_file(self.path)
        with self._cond:
            self._position, self._shown, self._jump, self._sought = 0, -1, None, False
            self._loops, self._segment, self._held = 0, 0, False

    def _do_close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
        self._file_clock = None

    def _do_start(self) -> None:
        with self._cond:
            self._due = time.monotonic()

    def _do_stop(self) -> None:
        with self._cond:
            self._cond.notify_all()

    @property
    def frame_shape(self) -> tuple[int, int]:
        return self._require_file().frame_shape

    @property
    def dtype(self) -> np.dtype:
        return self._require_file().dtype

    # -- replay specifics --------------------------------------------------------
    @property
    def n_frames(self) -> int:
        """Frames in the file (as of the last refresh for a growing recording)."""
        return len(self._file) if self._file is not None else 0

    @property
    def kind(self) -> str:
        """``"hdf5"``, ``"tiff"``, ``"folder"`` or ``"video"``."""
        return self._require_file().kind

    @property
    def setup(self) -> dict[str, Any]:
        """The optical setup stored in the file (holoview recordings), else empty."""
        return dict(self._require_file().setup)

    @property
    def shown(self) -> int:
        """Index of the last frame delivered (-1 before the first)."""
        with self._cond:
            return self._shown

    @property
    def segment(self) -> int:
        """Segment of the last frame delivered (0 before the first)."""
        with self._cond:
            return self._segment

    @property
    def paused(self) -> bool:
        """True while frames come only on :meth:`step` and :meth:`seek`."""
        with self._cond:
            return self._paused or self._speed == "step"

    @property
    def held(self) -> bool:
        """True while the replay holds on its last frame (the end, without ``loop``)."""
        with self._cond:
            return self._held

    @property
    def loop(self) -> bool:
        """Whether the replay starts over at its end."""
        return self._loop

    @property
    def speed_factor(self) -> float:
        """Times the recorded pace."""
        return self._factor

    def clock(self) -> ReplayClock:
        """What times the frames: the file's clock, or a frame rate given or assumed."""
        file = self._require_file()
        if self._rate_hz is not None:
            return ReplayClock("given", self._rate_hz, f"{self._rate_hz:g} frames/s, given")
        own = self._clock_of(file)
        if own.usable:
            name = own.camera_name if own.source == "camera" else CLOCK_NAMES[own.source]
            return ReplayClock("file", None, name)
        rate = self._effective_rate()
        return ReplayClock(
            "assumed",
            rate,
            f"{rate:g} frames/s, assumed: {self.path.name} carries no frame times; "
            "give its rate (rate_hz)",
        )

    @property
    def experiment_problem(self) -> str | None:
        """Why the file's stored experiment is not carried (damaged), else None."""
        return self._require_file().experiment_problem

    def carried_experiment(self, index: int) -> str | None:
        """The file's experiment (JSON text) in force at frame ``index``; None before any."""
        experiments = self._require_file().experiments
        starts = [start for start, _ in experiments]
        k = bisect.bisect_right(starts, index)
        return experiments[k - 1][1] if k else None

    def frame_time_s(self, index: int) -> float:
        """Time of frame ``index`` in the recording since its first frame, seconds.

        By :meth:`clock`: the file's times, else ``index`` over the frame rate.
        """
        file = self._require_file()
        if self._rate_hz is None and 0 <= index < len(file):
            own = self._clock_of(file)
            if own.usable:
                return float(own.times[index] - own.times[0])
        return index / self._effective_rate()

    def _stamp(self, file: FrameFile, index: int) -> float:
        """The time frame ``index`` is stamped with, s: on the file's clock as recorded
        (the camera's, or the host's), else :meth:`frame_time_s`."""
        if self._rate_hz is None:
            own = self._clock_of(file)
            if own.usable and index < len(own.times):
                return float(own.times[index])
        return self.frame_time_s(index)

    def _clock_of(self, file: FrameFile) -> FrameClock:
        """The file's own clock (the one rule), found again when a growing file grew."""
        own = self._file_clock
        if own is None or len(own.times) != len(file):
            own = self._file_clock = file.clock(range(len(file)))
        return own

    def pause(self) -> None:
        """Stop delivering frames until :meth:`resume` (steps and seeks still do)."""
        with self._cond:
            self._paused = True

    def resume(self) -> None:
        """Play on from the frame after the one shown (from the start when held at the end)."""
        with self._cond:
            if self._held:
                self._position = 0
            self._paused = self._held = False
            self._due = time.monotonic()
            self._cond.notify_all()

    def seek(self, index: int) -> int:
        """Deliver frame ``index`` next (at once, paused or not); play goes on after it.

        The frame opens a new segment (unless it is the replay's first), even when it is
        the one after the frame shown: the operator placed the replay there.

        Returns
        -------
        int
            The index sought.

        Raises
        ------
        InputError
            ``index`` is negative or past the last frame (one line, with the range).
        """
        with self._cond:
            n = len(self._require_file())
            if not 0 <= int(index) < n:
                raise InputError(
                    f"frame {index} is outside {self.path.name}: it has {n} frames, 0 to {n - 1}"
                )
            self._jump, self._sought = int(index), True
            self._held = False
            self._cond.notify_all()
            return self._jump

    def step(self, n: int = 1) -> int:
        """Pause and show the frame ``n`` after the one shown (before it for negative ``n``).

        The frame is clamped to the file's first and last; it opens a new segment when it
        is not the one after the frame delivered before it. Returns its index.
        """
        with self._cond:
            last = len(self._require_file()) - 1
            base = self._jump if self._jump is not None else self._position - 1
            target = min(max(base + int(n), 0), last)
            self._jump, self._sought = target, False
            self._paused = True
            self._held = False
            self._cond.notify_all()
            return target

    def _require_file(self) -> FrameFile:
        if self._file is None:
            raise AcquisitionError(f"{self.name} is not open; call open() first")
        return self._file

    def _effective_rate(self) -> float:
        if self._rate_hz is not None:
            return self._rate_hz
        rate = self._file.rate_hz if self._file is not None else None
        return rate or DEFAULT_RATE_HZ

    def _set_speed(self, speed: str) -> None:
        with self._cond:
            self._speed = speed
            self._due = time.monotonic()
            self._cond.notify_all()

    def _set_factor(self, factor: float) -> None:
        with self._cond:
            self._factor = float(factor)
            self._due = time.monotonic()
            self._cond.notify_all()

    def _set_rate(self, rate: float) -> None:
        self._rate_hz = float(rate)

    def _set_loop(self, loop: bool) -> None:
        with self._cond:
            self._loop = bool(loop)
            self._cond.notify_all()

    def _interval(self, file: FrameFile, index: int) -> float:
        if isinstance(file, HDF5File) and self._rate_hz is None:
            dt = file.interval_s(index)
            if dt is not None:
                return dt / self._factor
        return 1.0 / (self._effective_rate() * self._factor)

    def _take_turn(self, file: FrameFile, timeout: float | None) -> tuple[int, bool] | None:
        """Wait until a frame may go; None when ``timeout`` s pass first.

        Returns the frame's index and whether a seek asked for it.

        Raises
        ------
        EndOfStream
            The last frame has gone, without ``loop`` or ``hold``.
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            while self._streaming:
                now = time.monotonic()
                if self._jump is not None:
                    index, sought = self._jump, self._sought
                    self._jump, self._sought = None, False
                    self._position = index + 1
                    self._due = now + self._interval(file, index + 1)
                    return index, sought
                wake = deadline
                if not self._paused and self._speed != "step":
                    if self._position >= len(file) and file.refresh() <= self._position:
                        if self._loop:
                            self._loops += 1
                            self._position = 0
                        elif self._hold:
                            self._paused = self._held = True
                            continue
                        else:
                            raise EndOfStream
                    if self._speed == "fast" or now >= self._due:
                        self._due = max(self._due, now - 1.0) + self._interval(
                            file, self._position + 1
                        )
                        self._position += 1
                        return self._position - 1, False
                    wake = self._due if deadline is None else min(self._due, deadline)
                if deadline is not None and now >= deadline:
                    return None
                self._cond.wait(None if wake is None else max(0.0, wake - now))
        return None

    def _do_fetch(self, timeout: float | None) -> Frame | None:
        file = self._require_file()
        turn = self._take_turn(file, timeout)
        if turn is None:
            return None
        index, sought = turn
        file.check(index)
        data = file.read(index)
        with self._cond:
            if self._shown >= 0 and (sought or index != self._shown + 1):
                self._segment += 1
            self._shown = index
            segment = self._segment
        id_offset, t_offset = self._loop_offsets(file)
        meta = FrameMeta(
            frame_id=id_offset + file.frame_id(index),
            t_device=self._stamp(file, index) + t_offset,
            t_host=time.time(),
            pixel_format=file.pixel_format,
            file_index=index,
            segment=segment,
        )
        return Frame(data, meta)

    def _loop_offsets(self, file: FrameFile) -> tuple[int, float]:
        """Frame-id and device-time (seconds) offsets that keep both growing over loops."""
        if self._loops == 0:
            return 0, 0.0
        n = len(file)
        rate = self._effective_rate()
        t_span = self._stamp(file, n - 1) - self._stamp(file, 0)
        period = t_span + 1.0 / rate if math.isfinite(t_span) else n / rate
        return self._loops * (file.frame_id(n - 1) + 1), self._loops * period
