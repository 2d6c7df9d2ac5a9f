"""GenICam cameras (GigE Vision, USB3 Vision) through Aravis 0.8 and PyGObject.

Discovery is :func:`list_cameras`; :class:`AravisSource` opens a camera by its
Aravis id (``Aravis-Fake-GV01``, ``Basler-21234567``), serial number or IP
address, or the first camera found. Settings use the ``ArvCamera`` helpers, which
know the name variations between vendors, and are read back after every set:
``roi`` and ``pixel_format`` (locked while streaming), ``exposure_s``, ``gain``
(the camera's unit, dB on most), ``frame_rate_hz``, ``trigger`` (``off``,
``software`` or a line such as ``Line0``; locked while streaming); software
triggers go through :meth:`AravisSource.software_trigger`.

The stream runs on a pool of preallocated buffers. A buffer that arrives
incomplete (missing packets, timeout, size mismatch) is counted by its status in
``incomplete`` and requeued, never handed on as a frame; gaps in the 16-bit frame
ids (which wrap from 65535 to 1) are counted in ``lost``; Aravis's own stream
statistics are passed through in :meth:`AravisSource.stats` under ``aravis_*``.
A camera that stops answering (unplugged, powered off) raises
:class:`~holoview.acquire.source.CameraDisconnectedError` from ``fetch``: Aravis's
``control-lost`` signal, or a register read that fails after frames stopped.

Aravis's in-process ``Fake`` interface is enabled for ids starting ``Fake``
(``aravis:Fake_1``).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any

import numpy as np

from holoview.acquire.pixel_formats import PIXEL_FORMATS, pixel_format, unpack
from holoview.acquire.source import (
    ROI,
    AcquisitionError,
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

#: Buffers in the stream's pool.
DEFAULT_N_BUFFERS = 16
#: Seconds without a frame after which ``fetch`` checks that the camera still answers.
SILENCE_CHECK_S = 2.0
#: Frame ids of GigE Vision 1.x are 16-bit and skip 0: they run 1..65535, then 1 again.
FRAME_ID_PERIOD = 65535


def import_aravis() -> Any:
    """Return the ``Aravis`` 0.8 module from PyGObject.

    Raises
    ------
    AcquisitionError
        PyGObject or the Aravis 0.8 typelib is missing (the message says what to install).
    """
    try:
        import gi
    except ImportError as exc:
        raise AcquisitionError(
            "GenICam cameras need PyGObject (pip install 'holoview[genicam]')"
        ) from exc
    try:
        gi.require_version("Aravis", "0.8")
        from gi.repository import Aravis
    except (ImportError, ValueError) as exc:
        raise AcquisitionError(
            f"GenICam cameras need Aravis 0.8 (apt install gir1.2-aravis-0.8): {exc}"
        ) from exc
    return Aravis


def _glib_error() -> type[BaseException]:
    from gi.repository import GLib

    return GLib.Error


def list_cameras(*, fake: bool = False) -> list[dict[str, str]]:
    """Return every camera Aravis finds: ``id``, ``address``, ``serial``, ``model``, ``protocol``.

    Parameters
    ----------
    fake : bool
        Also list Aravis's in-process ``Fake`` camera.
    """
    aravis = import_aravis()
    if fake:
        aravis.enable_interface("Fake")
    aravis.update_device_list()
    return [
        {
            "id": aravis.get_device_id(i) or "",
            "address": aravis.get_device_address(i) or "",
            "serial": aravis.get_device_serial_nbr(i) or "",
            "model": aravis.get_device_model(i) or "",
            "protocol": aravis.get_device_protocol(i) or "",
        }
        for i in range(aravis.get_n_devices())
    ]


def find_camera_id(cameras: list[dict[str, str]], wanted: str | None) -> str:
    """Return the Aravis id of the camera ``wanted`` names (id, serial or address).

    Raises
    ------
    CameraNotFoundError
        None matches (the message lists the cameras found), or none was found at all.
    """
    if not cameras:
        raise CameraNotFoundError("no GenICam camera found (is it powered, on this subnet?)")
    if wanted is None:
        return cameras[0]["id"]
    for camera in cameras:
        if wanted in (camera["id"], camera["serial"], camera["address"]):
            return camera["id"]
    found = ", ".join(f"{c['id']} ({c['address']})" for c in cameras)
    raise CameraNotFoundError(f"no GenICam camera {wanted!r}; found: {found}")


class FrameIdUnwrapper:
    """Turn 16-bit wrapping frame ids into a growing count, counting the ids skipped."""

    def __init__(self, period: int = FRAME_ID_PERIOD) -> None:
        self.period = period
        self._last: int | None = None
        self._total = 0
        #: Frames whose ids were skipped (lost before the host saw them).
        self.skipped = 0

    def __call__(self, frame_id: int) -> int:
        """Return the unwrapped id of the next frame delivered, whose raw id is ``frame_id``."""
        if self._last is None:
            self._total = frame_id
        else:
            step = (frame_id - self._last) % self.period or self.period
            self.skipped += step - 1
            self._total += step
        self._last = frame_id
        return self._total


class AravisSource(Source):
    """A GenICam camera through Aravis.

    Parameters
    ----------
    camera_id : str, optional
        Aravis id, serial number or IP address; None takes the first camera found.
    n_buffers : int
        Buffers in the stream's pool.
    """

    def __init__(self, camera_id: str | None = None, *, n_buffers: int = DEFAULT_N_BUFFERS):
        super().__init__(f"aravis:{camera_id or 'first'}")
        if n_buffers < 2:
            raise InputError(f"the Aravis buffer pool needs at least 2 buffers, got {n_buffers}")
        self.camera_id = camera_id
        self.n_buffers = n_buffers
        self._aravis: Any = None
        self._camera: Any = None
        self._stream: Any = None
        self._shape = (0, 0)
        self._format = "Mono8"
        self._trigger = "off"
        self._control_lost = threading.Event()
        self._last_frame_at = 0.0
        self._ids = FrameIdUnwrapper()
        self._meta_values = {"exposure_s": math.nan, "gain": math.nan}
        self.counters.update({"incomplete": 0})

    # -- open / close --------------------------------------------------------------
    def _do_open(self) -> None:
        aravis = import_aravis()
        glib_error = _glib_error()
        fake = bool(self.camera_id and self.camera_id.startswith("Fake"))
        cameras = list_cameras(fake=fake)
        device_id = find_camera_id(cameras, self.camera_id)
        try:
            camera = aravis.Camera.new(device_id)
        except glib_error as exc:
            raise CameraNotFoundError(f"cannot open GenICam camera {device_id}: {exc}") from exc
        self._aravis = aravis
        self._camera = camera
        self.name = f"aravis:{device_id}"
        self._control_lost.clear()
        camera.get_device().connect("control-lost", self._on_control_lost)
        formats = [f for f in camera.dup_available_pixel_formats_as_strings() if f in PIXEL_FORMATS]
        if not formats:
            raise UnsupportedFeatureError(
                f"{device_id} offers no monochrome pixel format holoview reads "
                f"({', '.join(camera.dup_available_pixel_formats_as_strings())})"
            )
        if camera.get_pixel_format_as_string() not in formats:
            self._call(camera.set_pixel_format_from_string, formats[0])
        self._read_format()
        self._register_settings(camera, formats)
        self._remember_exposure_gain()
        logger.info(
            "%s: %s %s, %s", self.name, camera.get_vendor_name(), camera.get_model_name(), formats
        )

    def _do_close(self) -> None:
        self._stream = None
        self._camera = None

    def _on_control_lost(self, *_: object) -> None:
        logger.error("%s: control lost", self.name)
        self._control_lost.set()

    def _call(self, function: Any, *args: Any) -> Any:
        """Call an Aravis function; its GLib errors become holoview errors."""
        try:
            return function(*args)
        except _glib_error() as exc:
            if self._control_lost.is_set():
                raise CameraDisconnectedError(f"{self.name} stopped answering: {exc}") from exc
            raise UnsupportedFeatureError(f"{self.name}: {getattr(exc, 'message', exc)}") from exc

    def _read_format(self) -> None:
        region = self._camera.get_region()
        self._shape = (int(region[3]), int(region[2]))
        self._format = self._camera.get_pixel_format_as_string()

    @property
    def frame_shape(self) -> tuple[int, int]:
        return self._shape

    @property
    def dtype(self) -> np.dtype:
        return pixel_format(self._format).dtype

    # -- settings ----------------------------------------------------------------
    def _register_settings(self, camera: Any, formats: list[str]) -> None:
        def bounds(getter: Any, scale: float = 1.0) -> tuple[float, float]:
            b = getter()
            return b[0] * scale, b[1] * scale

        self.add_setting(
            Setting(
                "roi",
                "roi",
                self._get_roi,
                self._set_roi,
                unit="pixel",
                locked_while_streaming=True,
                doc="(left, top, width, height) on the sensor",
            )
        )
        self.add_setting(
            Setting(
                "pixel_format",
                "enum",
                camera.get_pixel_format_as_string,
                self._set_pixel_format,
                choices=tuple(formats),
                locked_while_streaming=True,
            )
        )
        if camera.is_exposure_time_available():
            self.add_setting(
                Setting(
                    "exposure_s",
                    "float",
                    lambda: camera.get_exposure_time() * 1e-6,
                    lambda v: self._call(camera.set_exposure_time, v * 1e6),
                    unit="s",
                    limits=lambda: bounds(camera.get_exposure_time_bounds, 1e-6),
                    increment=1e-6,
                )
            )
        if camera.is_gain_available():
            self.add_setting(
                Setting(
                    "gain",
                    "float",
                    camera.get_gain,
                    lambda v: self._call(camera.set_gain, v),
                    limits=lambda: bounds(camera.get_gain_bounds),
                    doc="the camera's gain (dB on most cameras)",
                )
            )
        if camera.is_frame_rate_available():
            self.add_setting(
                Setting(
                    "frame_rate_hz",
                    "float",
                    camera.get_frame_rate,
                    lambda v: self._call(camera.set_frame_rate, v),
                    unit="Hz",
                    limits=lambda: bounds(camera.get_frame_rate_bounds),
                )
            )
        triggers = ["off"]
        if camera.is_software_trigger_supported():
            triggers.append("software")
        triggers += [s for s in camera.dup_available_trigger_sources() if s != "Software"]
        self.add_setting(
            Setting(
                "trigger",
                "enum",
                lambda: self._trigger,
                self._set_trigger,
                choices=tuple(triggers),
                locked_while_streaming=True,
                doc="off (free running), software, or a hardware line",
            )
        )
        self.add_setting(
            Setting("model", "str", lambda: f"{camera.get_vendor_name()} {camera.get_model_name()}")
        )

    def _get_roi(self) -> ROI:
        x, y, w, h = self._camera.get_region()
        return ROI(int(x), int(y), int(w), int(h))

    def _set_roi(self, roi: ROI) -> None:
        camera = self._camera
        sensor_w, sensor_h = camera.get_sensor_size()
        if roi.left + roi.width > sensor_w or roi.top + roi.height > sensor_h:
            raise InputError(f"roi {tuple(roi)} does not fit the {sensor_w} x {sensor_h} sensor")

        def snap(value: int, increment: int) -> int:
            return value - value % max(1, increment)

        left = snap(roi.left, camera.get_x_offset_increment())
        top = snap(roi.top, camera.get_y_offset_increment())
        width = max(camera.get_width_increment(), snap(roi.width, camera.get_width_increment()))
        height = max(camera.get_height_increment(), snap(roi.height, camera.get_height_increment()))
        self._call(camera.set_region, left, top, width, height)
        self._read_format()

    def _set_pixel_format(self, name: str) -> None:
        self._call(self._camera.set_pixel_format_from_string, name)
        self._read_format()

    def _set_trigger(self, trigger: str) -> None:
        camera = self._camera
        if trigger == "off":
            self._call(camera.clear_triggers)
        else:
            self._call(camera.set_trigger, "Software" if trigger == "software" else trigger)
        self._trigger = trigger

    def software_trigger(self) -> None:
        """Fire one software trigger (the ``trigger`` setting must be ``software``)."""
        if self._trigger != "software":
            raise AcquisitionError(f"{self.name}: set trigger to 'software' first")
        self._call(self._camera.software_trigger)

    # -- streaming ---------------------------------------------------------------
    def _do_start(self) -> None:
        aravis, camera = self._aravis, self._camera
        self._read_format()
        stream = self._call(camera.create_stream, None, None)
        if stream is None:
            raise AcquisitionError(f"{self.name}: Aravis could not create a stream")
        payload = self._call(camera.get_payload)
        for _ in range(self.n_buffers):
            stream.push_buffer(aravis.Buffer.new_allocate(payload))
        self._stream = stream
        self._ids = FrameIdUnwrapper()
        self._last_frame_at = time.monotonic()
        self._call(camera.start_acquisition)

    def _do_stop(self) -> None:
        camera = self._camera
        try:
            if camera is not None and not self._control_lost.is_set():
                camera.stop_acquisition()
        except _glib_error() as exc:
            logger.warning("%s: stop_acquisition failed: %s", self.name, exc)
        finally:
            self._pass_statistics()
            self._stream = None

    def _do_fetch(self, timeout: float | None) -> Frame | None:
        if self._control_lost.is_set():
            raise CameraDisconnectedError(f"{self.name} stopped answering (control lost)")
        stream = self._stream
        wait_us = int(1e6 * (1.0 if timeout is None else max(timeout, 0.0)))
        buffer = stream.timeout_pop_buffer(wait_us)
        if buffer is None:
            self._check_alive()
            return None
        try:
            status = buffer.get_status()
            if status != self._aravis.BufferStatus.SUCCESS:
                name = status.value_nick.replace("-", "_")
                self.counters["incomplete"] += 1
                self.counters[f"incomplete_{name}"] = self.counters.get(f"incomplete_{name}", 0) + 1
                return None
            t_host = time.time()
            raw = buffer.get_image_data()
            width, height = buffer.get_image_width(), buffer.get_image_height()
            fmt_name = self._format
            frame_id = self._ids(buffer.get_frame_id())
            timestamp_ns = buffer.get_timestamp()
        finally:
            stream.push_buffer(buffer)
        self._last_frame_at = time.monotonic()
        self.counters["lost"] = self._ids.skipped
        data = unpack(raw, fmt_name, (height, width))
        t_device = timestamp_ns * 1e-9 if timestamp_ns else math.nan
        meta = FrameMeta(
            frame_id=frame_id,
            t_device=t_device,
            t_host=t_host,
            exposure_s=self._meta_values["exposure_s"],
            gain=self._meta_values["gain"],
            pixel_format=fmt_name,
        )
        return Frame(data, meta)

    def set(self, name: str, value: Any) -> Any:
        """Set a setting as :meth:`Source.set` does; keep exposure and gain for frame metadata."""
        readback = super().set(name, value)
        self._remember_exposure_gain()
        return readback

    def _remember_exposure_gain(self) -> None:
        """Read exposure and gain once, so frames carry them without a camera round trip."""
        for name in ("exposure_s", "gain"):
            setting = self._settings.get(name)
            self._meta_values[name] = float(setting.get()) if setting is not None else math.nan

    def _check_alive(self) -> None:
        if self._control_lost.is_set():
            raise CameraDisconnectedError(f"{self.name} stopped answering (control lost)")
        if time.monotonic() - self._last_frame_at < SILENCE_CHECK_S:
            return
        try:
            self._camera.get_region()
        except _glib_error() as exc:
            raise CameraDisconnectedError(f"{self.name} stopped answering: {exc}") from exc
        self._last_frame_at = time.monotonic()

    def _pass_statistics(self) -> None:
        stream = self._stream
        if stream is None:
            return
        for i in range(stream.get_n_infos()):
            name = stream.get_info_name(i)
            if stream.get_info_type(i).name == "guint64":
                self.counters[f"aravis_{name}"] = int(stream.get_info_uint64(i))

    def stats(self) -> dict[str, int]:
        """Counters: ``delivered``, ``lost`` (id gaps), ``incomplete`` (by status), ``aravis_*``."""
        self._pass_statistics()
        return dict(self.counters)
