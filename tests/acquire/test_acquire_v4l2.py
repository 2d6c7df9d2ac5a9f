"""V4L2 through OpenCV: fails fast here (no /dev/video), and its checks on a stand-in capture."""

from __future__ import annotations

import time

import cv2
import numpy as np
import pytest

from holoview.acquire import open_source
from holoview.acquire.source import (
    CameraDisconnectedError,
    CameraNotFoundError,
    UnsupportedFeatureError,
)
from holoview.acquire.v4l2 import MAX_FAILED_READS, V4L2Source


class StandInCapture:
    """What ``cv2.VideoCapture`` does, scripted: which controls exist, what reads return."""

    def __init__(
        self,
        *,
        opened: bool = True,
        controls: dict[int, float] | None = None,
        honours: set[int] | None = None,
        frames: list[np.ndarray | None] | None = None,
    ) -> None:
        self.opened = opened
        self.values = {
            cv2.CAP_PROP_FRAME_WIDTH: 8.0,
            cv2.CAP_PROP_FRAME_HEIGHT: 6.0,
            cv2.CAP_PROP_POS_MSEC: 0.0,
            **(controls or {}),
        }
        self.honours = honours if honours is not None else set(self.values)
        self.frames = frames if frames is not None else []
        self.released = False

    def isOpened(self) -> bool:
        return self.opened

    def release(self) -> None:
        self.released = True

    def get(self, prop: int) -> float:
        return self.values.get(prop, -1.0)

    def set(self, prop: int, value: float) -> bool:
        if prop in (cv2.CAP_PROP_CONVERT_RGB, cv2.CAP_PROP_AUTO_EXPOSURE):
            return True
        if prop not in self.honours:
            return False
        if prop == cv2.CAP_PROP_GAIN:
            value = min(value, 10.0)  # a driver that clamps silently
        self.values[prop] = float(value)
        return True

    def read(self) -> tuple[bool, np.ndarray | None]:
        if not self.frames:
            return False, None
        frame = self.frames.pop(0)
        self.values[cv2.CAP_PROP_POS_MSEC] += 40.0
        return frame is not None, frame


def grey(value: int, dtype: type = np.uint8) -> np.ndarray:
    return np.full((6, 8), value, dtype)


def test_missing_device_fails_fast_and_cleanly() -> None:
    t0 = time.monotonic()
    with pytest.raises(CameraNotFoundError, match=r"no V4L2 camera at /dev/video7") as info:
        open_source("v4l2:7")
    assert time.monotonic() - t0 < 10
    assert "\n" not in str(info.value)


def test_stand_in_not_opened_is_camera_not_found() -> None:
    capture = StandInCapture(opened=False)
    with pytest.raises(CameraNotFoundError):
        V4L2Source(0, capture_factory=lambda i: capture).open()
    assert capture.released


def test_controls_the_driver_cannot_honour_are_not_offered() -> None:
    capture = StandInCapture(
        controls={cv2.CAP_PROP_EXPOSURE: 100.0, cv2.CAP_PROP_GAIN: 2.0},
        honours={cv2.CAP_PROP_GAIN, cv2.CAP_PROP_FRAME_WIDTH, cv2.CAP_PROP_FRAME_HEIGHT},
        frames=[grey(1)],
    )
    with V4L2Source(0, capture_factory=lambda i: capture) as source:
        settings = source.describe_settings()
        assert "gain" in settings
        assert "exposure_s" not in settings  # present but refuses its own value
        assert "frame_rate_hz" not in settings  # get() says -1: absent
        with pytest.raises(UnsupportedFeatureError, match="no setting 'exposure_s'"):
            source.set("exposure_s", 1e-3)


def test_values_are_checked_after_set() -> None:
    capture = StandInCapture(
        controls={cv2.CAP_PROP_EXPOSURE: 100.0, cv2.CAP_PROP_GAIN: 2.0}, frames=[grey(1)]
    )
    with V4L2Source(0, capture_factory=lambda i: capture) as source:
        assert source.set("exposure_s", 0.02) == pytest.approx(0.02)  # 200 x 100 us
        assert capture.values[cv2.CAP_PROP_EXPOSURE] == pytest.approx(200.0)
        assert source.set("gain", 5.0) == pytest.approx(5.0)
        with pytest.raises(UnsupportedFeatureError, match="did not honour gain = 50"):
            source.set("gain", 50.0)
        with pytest.raises(UnsupportedFeatureError, match="no ROI offset"):
            source.set("roi", (2, 0, 4, 4))


def test_frames_grey_ids_and_timestamps() -> None:
    colour = np.zeros((6, 8, 3), np.uint8)
    colour[..., 1] = 200
    capture = StandInCapture(frames=[grey(1, np.uint16), grey(2, np.uint16), colour])
    with V4L2Source(0, capture_factory=lambda i: capture) as source:
        assert source.dtype == np.uint16  # learnt from the first frame, before streaming
        source.start()
        frame = source.fetch()
        assert frame.meta.frame_id == 0
        assert frame.meta.pixel_format == "Mono16"
        assert frame.meta.t_device == pytest.approx(0.08)
        with pytest.raises(CameraDisconnectedError, match="changed its frames"):
            source.fetch()  # a colour uint8 frame mid-stream of uint16


def test_a_run_of_failed_reads_is_a_camera_gone() -> None:
    capture = StandInCapture(frames=[grey(1), grey(2)])
    with V4L2Source(3, capture_factory=lambda i: capture) as source:
        source.start()
        assert source.fetch() is not None
        for _ in range(MAX_FAILED_READS - 1):
            assert source.fetch() is None
        with pytest.raises(CameraDisconnectedError, match="v4l2:3"):
            source.fetch()
