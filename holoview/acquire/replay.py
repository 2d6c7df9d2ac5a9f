"""Replay: a recording, TIFF stack, image folder or video played as a camera.

Three speeds (the ``speed`` setting):

- ``"recorded"``: a holoview recording at the pace of its timestamps (device
  clock where every frame has one, else host arrival times); other files at
  ``rate_hz`` (default: the video's own rate, or 30 frames/s for images);
- ``"fast"``: as fast as frames can be read;
- ``"step"``: one frame per :meth:`ReplaySource.step` call (a GUI's "next" button).

With ``loop`` the file starts over at its end (frame ids keep increasing, device
times too), otherwise :meth:`~holoview.acquire.source.Source.fetch` raises
:class:`~holoview.acquire.source.EndOfStream` after the last frame. A holoview
recording still being written is followed: at its end the replay refreshes it
and goes on with the frames flushed since.
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from holoview.acquire.replay_files import FrameFile, HDF5File, open_frame_file
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
    """

    def __init__(
        self,
        path: str | Path,
        *,
        speed: str = "recorded",
        rate_hz: float | None = None,
        loop: bool = False,
    ) -> None:
        super().__init__(f"replay:{path}")
        self.path = Path(path)
        self._file: FrameFile | None = None
        self._speed = speed
        self._rate_hz = rate_hz
        self._loop = bool(loop)
        self._position = 0
        self._loops = 0
        self._permits = 0
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
            Setting(
                "position",
                "int",
                lambda: self._position,
                self._seek,
                limits=lambda: (0, max(0, self.n_frames - 1)),
                increment=1,
                doc="index of the next frame played",
            )
        )
        self.add_setting(
            Setting("n_frames", "int", lambda: self.n_frames, doc="frames in the file")
        )
        self.add_setting(Setting("pixel_format", "enum", lambda: self._require_file().pixel_format))
        if speed not in SPEEDS:
            raise InputError(f"replay speed must be one of {', '.join(SPEEDS)}, got {speed!r}")

    # -- Source hooks ------------------------------------------------------------
    def _do_open(self) -> None:
        self._file = open_frame_file(self.path)
        self._position = 0
        self._loops = 0

    def _do_close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def _do_start(self) -> None:
        self._due = time.monotonic()
        with self._cond:
            self._permits = 0

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

    def step(self, n: int = 1) -> None:
        """Release ``n`` more frames in ``"step"`` speed."""
        with self._cond:
            self._permits += max(0, int(n))
            self._cond.notify_all()

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

    def _set_rate(self, rate: float) -> None:
        self._rate_hz = float(rate)

    def _set_loop(self, loop: bool) -> None:
        self._loop = bool(loop)

    def _seek(self, index: int) -> None:
        self._position = int(index)

    def _interval(self, file: FrameFile, index: int) -> float:
        if isinstance(file, HDF5File) and self._rate_hz is None:
            dt = file.interval_s(index)
            if dt is not None:
                return dt
        return 1.0 / self._effective_rate()

    def _wait_turn(self, file: FrameFile, timeout: float | None) -> bool:
        """Wait until the next frame may go; False when ``timeout`` seconds pass first."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            while self._streaming:
                if self._speed == "fast":
                    return True
                now = time.monotonic()
                if self._speed == "step":
                    if self._permits > 0:
                        self._permits -= 1
                        return True
                    wake = deadline
                else:
                    if now >= self._due:
                        self._due = max(self._due, now - 1.0) + self._interval(
                            file, self._position + 1
                        )
                        return True
                    wake = self._due if deadline is None else min(self._due, deadline)
                if deadline is not None and now >= deadline:
                    return False
                self._cond.wait(None if wake is None else max(0.0, wake - now))
        return False

    def _do_fetch(self, timeout: float | None) -> Frame | None:
        file = self._require_file()
        if self._position >= len(file) and file.refresh() <= self._position:
            if not self._loop:
                raise EndOfStream
            self._loops += 1
            self._position = 0
        if not self._wait_turn(file, timeout):
            return None
        index = self._position
        data = file.read(index)
        self._position = index + 1
        id_offset, t_offset = self._loop_offsets(file)
        meta = FrameMeta(
            frame_id=id_offset + file.frame_id(index),
            t_device=file.t_device(index) + t_offset,
            t_host=time.time(),
            pixel_format=file.pixel_format,
        )
        return Frame(data, meta)

    def _loop_offsets(self, file: FrameFile) -> tuple[int, float]:
        """Frame-id and device-time (seconds) offsets that keep both growing over loops."""
        if self._loops == 0:
            return 0, 0.0
        n = len(file)
        rate = self._effective_rate()
        t_span = file.t_device(n - 1) - file.t_device(0)
        period = t_span + 1.0 / rate if math.isfinite(t_span) else n / rate
        return self._loops * (file.frame_id(n - 1) + 1), self._loops * period
