"""A minimal Source for tests of the ring, threads and settings: frame i is filled with i."""

from __future__ import annotations

import math
import time

import numpy as np

from holoview.acquire.source import (
    CameraDisconnectedError,
    EndOfStream,
    Frame,
    FrameMeta,
    Setting,
    Source,
)


class CountingSource(Source):
    """Frames of ``shape`` uint16 whose every pixel is the frame id, at ``rate_hz``.

    ``n_frames`` ends the stream (EndOfStream) after that many; ``fail_after`` raises
    CameraDisconnectedError after that many; ``lose_every`` reports one transport loss
    (and skips an id) every that many frames.
    """

    def __init__(
        self,
        shape: tuple[int, int] = (16, 24),
        rate_hz: float = 0.0,
        n_frames: int | None = None,
        fail_after: int | None = None,
        lose_every: int | None = None,
    ) -> None:
        super().__init__("counting")
        self.shape = shape
        self.rate_hz = rate_hz
        self.n_frames = n_frames
        self.fail_after = fail_after
        self.lose_every = lose_every
        self._id = 0
        self._sent = 0
        self._exposure = 1e-3
        self.add_setting(
            Setting(
                "exposure_s",
                "float",
                lambda: self._exposure,
                self._set_exposure,
                unit="s",
                limits=(1e-5, 1.0),
                increment=1e-5,
            )
        )
        self.add_setting(
            Setting(
                "roi",
                "roi",
                lambda: (0, 0, shape[1], shape[0]),
                lambda roi: None,
                locked_while_streaming=True,
            )
        )
        self.add_setting(Setting("sensor_temperature_k", "float", lambda: 300.0, unit="K"))

    def _set_exposure(self, value: float) -> None:
        self._exposure = value

    @property
    def frame_shape(self) -> tuple[int, int]:
        return self.shape

    @property
    def dtype(self) -> np.dtype:
        return np.dtype(np.uint16)

    def _do_open(self) -> None:
        pass

    def _do_close(self) -> None:
        pass

    def _do_start(self) -> None:
        self._t0 = time.monotonic()

    def _do_stop(self) -> None:
        pass

    def _do_fetch(self, timeout: float | None) -> Frame | None:
        if self.n_frames is not None and self._sent >= self.n_frames:
            raise EndOfStream
        if self.fail_after is not None and self._sent >= self.fail_after:
            raise CameraDisconnectedError("counting source unplugged")
        if self.rate_hz > 0:
            due = self._t0 + self._sent / self.rate_hz
            wait = due - time.monotonic()
            if timeout is not None and wait > timeout:
                time.sleep(timeout)
                return None
            if wait > 0:
                time.sleep(wait)
        if self.lose_every and self._id % self.lose_every == self.lose_every - 1:
            self._id += 1
            self.counters["lost"] += 1
        frame_id = self._id
        self._id += 1
        self._sent += 1
        data = np.full(self.shape, frame_id % 65536, np.uint16)
        return Frame(data, FrameMeta(frame_id, math.nan, time.time(), self._exposure))
