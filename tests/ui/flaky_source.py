"""A test source with an ROI locked while streaming, that can vanish mid-stream."""

from __future__ import annotations

import time

import numpy as np

from holoview.acquire.source import (
    ROI,
    CameraDisconnectedError,
    Frame,
    FrameMeta,
    Setting,
    Source,
)

from .holograms import hologram_stack


class FlakySource(Source):
    """Synthetic holograms at about 50 frames/s; gone after ``fail_after`` frames if given."""

    def __init__(self, fail_after: int | None = None) -> None:
        super().__init__("flaky")
        self.fail_after = fail_after
        self._frames = hologram_stack(4, (256, 256))
        self._roi = ROI(0, 0, 256, 256)
        self._count = 0
        self.add_setting(
            Setting(
                "roi",
                "roi",
                lambda: self._roi,
                self._set_roi,
                unit="pixel",
                locked_while_streaming=True,
            )
        )

    def _set_roi(self, roi: ROI) -> None:
        self._roi = ROI(*roi)

    @property
    def frame_shape(self) -> tuple[int, int]:
        return (self._roi.height, self._roi.width)

    @property
    def dtype(self) -> np.dtype:
        return np.dtype(np.uint16)

    def _do_open(self) -> None:
        self._count = 0

    def _do_close(self) -> None:
        pass

    def _do_start(self) -> None:
        pass

    def _do_stop(self) -> None:
        pass

    def _do_fetch(self, timeout: float | None) -> Frame | None:
        time.sleep(0.02)
        if self.fail_after is not None and self._count >= self.fail_after:
            raise CameraDisconnectedError("flaky: the camera stopped answering")
        left, top, width, height = self._roi
        data = self._frames[self._count % 4, top : top + height, left : left + width].copy()
        self._count += 1
        return Frame(data, FrameMeta(self._count, float("nan"), time.time()))
