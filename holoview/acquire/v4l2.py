"""V4L2 cameras (``/dev/videoN``) through OpenCV, with the V4L2 backend forced.

OpenCV reports most failures by return values, not exceptions, so every call's
result is checked: ``isOpened()`` after opening (a missing device is a
:class:`~holoview.acquire.source.CameraNotFoundError` at once, no retries),
``set()`` and the value read back after every setting (a value the driver did
not take is an :class:`~holoview.acquire.source.UnsupportedFeatureError`), and
``read()`` for every frame (a run of failed reads is a camera gone:
:class:`~holoview.acquire.source.CameraDisconnectedError`).

At open, each control is probed: one the driver reports as absent (``get``
returns -1) or refuses to be written with its own value is not offered as a
setting, so a GUI never shows a control that does nothing. Controls:
``exposure_s`` (V4L2 ``exposure_absolute``, 100 us units, with auto exposure
switched to manual), ``gain`` (driver units), ``frame_rate_hz``, and ``roi``
(the capture size; V4L2 has no offset, so left and top stay 0).
Colour frames are converted to grey (OpenCV's luma weights); 16-bit grey
(``Y16``) stays raw with ``CONVERT_RGB`` off.
"""

from __future__ import annotations

import functools
import logging
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from holoview.acquire.source import (
    ROI,
    CameraDisconnectedError,
    CameraNotFoundError,
    Frame,
    FrameMeta,
    Setting,
    Source,
    UnsupportedFeatureError,
)
from holoview.errors import InputError

logger = logging.getLogger(__name__)

#: Consecutive failed reads after which the camera counts as gone.
MAX_FAILED_READS = 10
#: V4L2's exposure_absolute unit, seconds.
EXPOSURE_UNIT_S = 100e-6
#: OpenCV's V4L2 value for manual exposure in CAP_PROP_AUTO_EXPOSURE.
MANUAL_EXPOSURE = 1


def _default_capture(index: int) -> Any:
    import cv2

    return cv2.VideoCapture(index, cv2.CAP_V4L2)


def probe_control(capture: Any, prop: int) -> bool:
    """Return True when the driver has control ``prop`` and accepts its own value back."""
    value = capture.get(prop)
    if value is None or value == -1 or not math.isfinite(value):
        return False
    return bool(capture.set(prop, value))


def set_checked(capture: Any, prop: int, value: float, what: str, tolerance: float) -> float:
    """Set ``prop``, check the return value and the value read back; return the read-back.

    Raises
    ------
    UnsupportedFeatureError
        ``set`` returned False, or the driver kept a value further than ``tolerance``.
    """
    if not capture.set(prop, value):
        raise UnsupportedFeatureError(f"the V4L2 driver refused {what} = {value:g}")
    readback = float(capture.get(prop))
    if abs(readback - value) > tolerance:
        raise UnsupportedFeatureError(
            f"the V4L2 driver did not honour {what} = {value:g} (it reads back {readback:g})"
        )
    return readback


def _get_scaled(capture: Any, prop: int, scale: float) -> float:
    """A control's value in SI units: the driver's value times ``scale``."""
    return float(capture.get(prop)) * scale


def _set_scaled(capture: Any, prop: int, scale: float, what: str, value: float) -> None:
    """Set a control from SI units (``value / scale`` in the driver's), checked."""
    set_checked(capture, prop, value / scale, what, tolerance=0.5)


class V4L2Source(Source):
    """A V4L2 camera through OpenCV's ``CAP_V4L2`` backend.

    Parameters
    ----------
    index : int
        The device number N of ``/dev/videoN``.
    capture_factory : callable, optional
        Makes the capture object from the index (tests pass a stand-in; the default
        is ``cv2.VideoCapture(index, cv2.CAP_V4L2)``).
    """

    def __init__(self, index: int = 0, *, capture_factory: Callable[[int], Any] | None = None):
        super().__init__(f"v4l2:{index}")
        if index < 0:
            raise InputError(f"V4L2 device index must be 0 or more, got {index}")
        self.index = index
        self._factory = capture_factory or _default_capture
        self._capture: Any = None
        self._shape = (0, 0)
        self._dtype = np.dtype(np.uint8)
        self._frame_id = 0
        self._failed_reads = 0

    def _do_open(self) -> None:
        import cv2

        capture = self._factory(self.index)
        if capture is None or not capture.isOpened():
            if capture is not None:
                capture.release()
            raise CameraNotFoundError(f"no V4L2 camera at /dev/video{self.index}")
        self._capture = capture
        capture.set(cv2.CAP_PROP_CONVERT_RGB, 0)
        self._read_size()
        first = self._read()
        if first is None:
            capture.release()
            self._capture = None
            raise CameraNotFoundError(f"/dev/video{self.index} opened but delivers no frames")
        self._dtype = first.dtype
        self._register_controls(cv2)

    def _read_size(self) -> None:
        import cv2

        width = int(self._capture.get(cv2.CAP_PROP_FRAME_WIDTH))
        height = int(self._capture.get(cv2.CAP_PROP_FRAME_HEIGHT))
        if width <= 0 or height <= 0:
            raise CameraNotFoundError(f"/dev/video{self.index} reports no frame size")
        self._shape = (height, width)

    def _register_controls(self, cv2: Any) -> None:
        capture = self._capture
        controls = {
            "exposure_s": cv2.CAP_PROP_EXPOSURE,
            "gain": cv2.CAP_PROP_GAIN,
            "frame_rate_hz": cv2.CAP_PROP_FPS,
        }
        if probe_control(capture, cv2.CAP_PROP_EXPOSURE) and not capture.set(
            cv2.CAP_PROP_AUTO_EXPOSURE, MANUAL_EXPOSURE
        ):
            logger.info("%s: auto exposure cannot be switched off; exposure disabled", self.name)
            controls.pop("exposure_s")
        for name, prop in controls.items():
            if not probe_control(capture, prop):
                logger.info("%s: the driver does not honour %s; disabled", self.name, name)
                continue
            scale = EXPOSURE_UNIT_S if name == "exposure_s" else 1.0
            self.add_setting(
                Setting(
                    name,
                    "float",
                    functools.partial(_get_scaled, capture, prop, scale),
                    functools.partial(_set_scaled, capture, prop, scale, name),
                    unit={"exposure_s": "s", "frame_rate_hz": "Hz"}.get(name, ""),
                    locked_while_streaming=name == "frame_rate_hz",
                )
            )
        self.add_setting(
            Setting(
                "roi",
                "roi",
                lambda: ROI(0, 0, self._shape[1], self._shape[0]),
                self._set_roi,
                unit="pixel",
                locked_while_streaming=True,
                doc="capture size; V4L2 has no offset",
            )
        )

    def _set_roi(self, roi: ROI) -> None:
        import cv2

        if roi.left or roi.top:
            raise UnsupportedFeatureError("V4L2 cameras have no ROI offset; use left = top = 0")
        set_checked(self._capture, cv2.CAP_PROP_FRAME_WIDTH, roi.width, "width", 0)
        set_checked(self._capture, cv2.CAP_PROP_FRAME_HEIGHT, roi.height, "height", 0)
        self._read_size()

    def _do_close(self) -> None:
        if self._capture is not None:
            self._capture.release()
            self._capture = None

    def _do_start(self) -> None:
        self._frame_id = 0
        self._failed_reads = 0

    def _do_stop(self) -> None:
        """OpenCV streams from open to release; nothing to stop."""

    @property
    def frame_shape(self) -> tuple[int, int]:
        return self._shape

    @property
    def dtype(self) -> np.dtype:
        return self._dtype

    def _read(self) -> np.ndarray | None:
        ok, frame = self._capture.read()
        if not ok or frame is None:
            return None
        if frame.ndim == 3:
            import cv2

            frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        return np.ascontiguousarray(frame)

    def _do_fetch(self, timeout: float | None) -> Frame | None:
        import cv2

        data = self._read()
        t_host = time.time()
        if data is None:
            self._failed_reads += 1
            if self._failed_reads >= MAX_FAILED_READS:
                raise CameraDisconnectedError(
                    f"{self.name}: {self._failed_reads} reads in a row failed; camera gone?"
                )
            return None
        self._failed_reads = 0
        if data.shape != self._shape or data.dtype != self._dtype:
            raise CameraDisconnectedError(
                f"{self.name} changed its frames to {data.shape} {data.dtype} mid-stream"
            )
        msec = float(self._capture.get(cv2.CAP_PROP_POS_MSEC))
        frame_id = self._frame_id
        self._frame_id += 1
        exposure = self.get("exposure_s") if self.has_setting("exposure_s") else math.nan
        meta = FrameMeta(
            frame_id=frame_id,
            t_device=msec * 1e-3 if msec > 0 else math.nan,
            t_host=t_host,
            exposure_s=exposure,
            pixel_format="Mono16" if data.dtype == np.uint16 else "Mono8",
        )
        return Frame(data, meta)
