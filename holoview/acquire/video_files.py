"""Frames from a video decoded by OpenCV's FFmpeg backend (FFV1 grey, 8 or 16 bits, kept raw)."""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from holoview.acquire.frame_file import FrameFile, grey
from holoview.errors import InputError

logger = logging.getLogger(__name__)

#: Video codecs (FourCC, lower case) whose grey frames OpenCV hands over raw (16-bit kept);
#: the others (MJPG, H.264, MPEG-4) are decoded to BGR and converted to grey.
RAW_FOURCCS = frozenset({"ffv1", "y800", "grey", "y8  ", "y16 "})


def _quiet_opencv(cv2: Any) -> None:
    """Keep OpenCV's and FFmpeg's log lines (a warning per frame for MJPG) off stderr."""
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # read when FFmpeg starts
    logging_module = getattr(getattr(cv2, "utils", None), "logging", None)
    if logging_module is not None:
        logging_module.setLogLevel(logging_module.LOG_LEVEL_ERROR)


class VideoFile(FrameFile):
    """A video file decoded by OpenCV's FFmpeg backend (FFV1 grey 8/16-bit kept raw)."""

    kind = "video"

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        import cv2

        _quiet_opencv(cv2)
        self._cv2 = cv2
        self._capture = self._open_capture(raw=True)
        fourcc = int(self._capture.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little")
        self._raw = fourcc.decode("latin-1").lower() in RAW_FOURCCS
        if not self._raw:
            self._capture.release()
            self._capture = self._open_capture(raw=False)
        ok, frame = self._capture.read()
        if self._raw and ok and frame is not None and frame.ndim != 2:
            self._capture.release()
            self._raw = False
            self._capture = self._open_capture(raw=False)
            ok, frame = self._capture.read()
        if not ok or frame is None:
            self._capture.release()
            raise InputError(f"{path}: the video holds no frame OpenCV can decode")
        frame = self._convert(frame)
        self._set_format(frame.shape, frame.dtype)
        self._position = 1
        count = int(self._capture.get(cv2.CAP_PROP_FRAME_COUNT))
        self._count = count if count > 0 else self._count_by_reading()
        fps = float(self._capture.get(cv2.CAP_PROP_FPS))
        self.rate_hz = fps if math.isfinite(fps) and fps > 0 else None

    def _open_capture(self, *, raw: bool) -> Any:
        cv2 = self._cv2
        capture = cv2.VideoCapture(str(self.path), cv2.CAP_FFMPEG)
        if not capture.isOpened():
            capture.release()
            raise InputError(
                f"{self.path}: OpenCV cannot open the video (unknown codec or damaged)"
            )
        if raw and not capture.set(cv2.CAP_PROP_CONVERT_RGB, 0):
            logger.debug("%s: the backend ignores CONVERT_RGB=0", self.path)
        return capture

    def _convert(self, frame: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(grey(frame, str(self.path)))

    def _count_by_reading(self) -> int:
        n = 1
        while self._capture.grab():
            n += 1
        self._seek(0)
        return n

    def _seek(self, index: int) -> None:
        self._capture.set(self._cv2.CAP_PROP_POS_FRAMES, index)
        self._position = index

    def __len__(self) -> int:
        return self._count

    def read(self, index: int) -> np.ndarray:
        if index != self._position:
            self._seek(index)
        ok, frame = self._capture.read()
        if not ok or frame is None:
            raise InputError(f"{self.path}: frame {index} cannot be decoded")
        self._position = index + 1
        frame = self._convert(frame)
        if frame.shape != self.frame_shape or frame.dtype != self.dtype:
            raise InputError(f"{self.path}: frame {index} is {frame.shape} {frame.dtype}")
        return frame

    def t_device(self, index: int) -> float:
        return index / self.rate_hz if self.rate_hz else math.nan

    @property
    def clock_name(self) -> str:
        return f"the video's frame rate ({self.rate_hz or math.nan:g} frames/s)"

    def close(self) -> None:
        self._capture.release()
