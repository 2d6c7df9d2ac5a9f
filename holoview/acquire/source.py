"""The camera source interface: one template every source (sim, Aravis, V4L2, replay) fills in.

The pattern is python-microscope's (``microscope/abc.py``): public methods check the
state, validate, log and read values back; drivers fill in small protected hooks
(``_do_open``, ``_do_close``, ``_do_start``, ``_do_stop``, ``_do_fetch``) and register
their settings with :meth:`Source.add_setting`.

Life cycle::

    source.open()            # find and connect the device (CameraNotFoundError)
    source.set("exposure_s", 2e-3)   # returns the value read back, snapped
    source.start()           # stream; settings locked while streaming refuse to change
    frame = source.fetch(timeout=1.0)  # a Frame, None on timeout, EndOfStream at the end
    source.stop(); source.close()

A :class:`Frame` owns its pixels (sources copy out of driver buffers before returning
them), so it can be kept after the next fetch. Sources are used from one thread at a
time (the camera thread while streaming).
"""

from __future__ import annotations

import logging
import math
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import Any, NamedTuple, Self

import numpy as np

from holoview.errors import HoloviewError, InputError, finite_number

logger = logging.getLogger(__name__)


class AcquisitionError(HoloviewError):
    """A camera or source problem the user can act on."""


class CameraNotFoundError(AcquisitionError):
    """No device answers to the requested id, address or index, or the file is missing."""


class UnsupportedFeatureError(AcquisitionError):
    """The source has no such setting, or cannot honour the requested value."""


class FeatureLockedError(AcquisitionError):
    """The setting is read-only, or cannot change while the source is streaming."""


class CameraDisconnectedError(AcquisitionError):
    """The device stopped answering while streaming (unplugged, powered off, killed)."""


class EndOfStream(Exception):  # noqa: N818 (a signal, like StopIteration, not an error)
    """A finite source (replay without looping) has delivered its last frame."""


class ROI(NamedTuple):
    """A region of interest on the sensor, pixels: ``(left, top, width, height)``."""

    left: int
    top: int
    width: int
    height: int


class FrameMeta(NamedTuple):
    """What is known about one frame besides its pixels.

    Attributes
    ----------
    frame_id : int
        The device's frame counter (Aravis GigE ids are 16-bit and wrap); gaps are
        frames lost before the host saw them.
    t_device : float
        The device's timestamp, seconds on its own clock (NaN when it has none).
    t_host : float
        When the host received the frame, seconds since the UNIX epoch.
    exposure_s : float
        Exposure time, seconds (NaN when unknown).
    gain : float
        Gain in the unit of the source's ``gain`` setting (NaN when unknown).
    pixel_format : str
        GenICam pixel format name of the raw values (``Mono8``, ``Mono12``, ...).
    file_index : int
        The frame's index in the file a replay plays (-1 for a camera).
    segment : int
        Which unbroken run of frames the frame belongs to: a replay starts a new
        segment at each seek (even to the frame after the one shown) and each jump (a
        step back, a loop back to the start), so the frames of one segment follow each
        other in the file; a camera keeps 0.
    """

    frame_id: int
    t_device: float
    t_host: float
    exposure_s: float = math.nan
    gain: float = math.nan
    pixel_format: str = "Mono16"
    file_index: int = -1
    segment: int = 0


class Frame(NamedTuple):
    """One frame: its raw pixels ``(rows, cols)`` and its :class:`FrameMeta`."""

    data: np.ndarray
    meta: FrameMeta


@dataclass(frozen=True, slots=True)
class SettingInfo:
    """How a setting describes itself (what a GUI needs to draw an editor for it).

    Attributes
    ----------
    name : str
        The setting's name, with its unit as a suffix where it has one (``exposure_s``).
    kind : str
        ``"float"``, ``"int"``, ``"bool"``, ``"enum"``, ``"str"`` or ``"roi"``.
    unit : str
        SI unit (``"s"``, ``"Hz"``, ``"dB"``, ``"pixel"``), ``""`` when none.
    limits : tuple of float, optional
        Inclusive ``(low, high)`` for numbers.
    increment : float, optional
        Step values snap to, counted from the low limit (from 0 without limits).
    choices : tuple of str, optional
        The allowed values of an enum.
    read_only : bool
        No value can be set.
    locked_while_streaming : bool
        The value can only change while the source is not streaming.
    doc : str
        One line for a tooltip.
    """

    name: str
    kind: str
    unit: str = ""
    limits: tuple[float, float] | None = None
    increment: float | None = None
    choices: tuple[str, ...] | None = None
    read_only: bool = False
    locked_while_streaming: bool = False
    doc: str = ""


_KINDS = ("float", "int", "bool", "enum", "str", "roi")


class Setting:
    """A setting of a source: how to read and write it, and how it describes itself.

    Parameters
    ----------
    name, kind, unit, doc, locked_while_streaming
        As in :class:`SettingInfo`.
    get : callable
        Returns the current value, read from the device.
    set : callable, optional
        Writes a validated value to the device; ``None`` makes the setting read-only.
    limits, increment, choices : optional
        Static values, or callables that return them (limits of a camera change with
        other settings, e.g. the exposure range with the frame rate).
    """

    def __init__(
        self,
        name: str,
        kind: str,
        get: Callable[[], Any],
        set: Callable[[Any], None] | None = None,
        *,
        unit: str = "",
        limits: tuple[float, float] | Callable[[], tuple[float, float] | None] | None = None,
        increment: float | Callable[[], float | None] | None = None,
        choices: tuple[str, ...] | Callable[[], tuple[str, ...]] | None = None,
        locked_while_streaming: bool = False,
        doc: str = "",
    ) -> None:
        if kind not in _KINDS:
            raise ValueError(f"setting kind must be one of {_KINDS}, got {kind!r}")
        self.name = name
        self.kind = kind
        self._get = get
        self._set = set
        self.unit = unit
        self._limits = limits
        self._increment = increment
        self._choices = choices
        self.locked_while_streaming = locked_while_streaming
        self.doc = doc

    @property
    def read_only(self) -> bool:
        """True when the setting cannot be written."""
        return self._set is None

    def limits(self) -> tuple[float, float] | None:
        """The current inclusive ``(low, high)``, or None."""
        value = self._limits() if callable(self._limits) else self._limits
        return None if value is None else (value[0], value[1])

    def increment(self) -> float | None:
        """The current step, or None."""
        value = self._increment() if callable(self._increment) else self._increment
        return None if value is None or value <= 0 else value

    def choices(self) -> tuple[str, ...] | None:
        """The allowed values of an enum, or None."""
        value = self._choices() if callable(self._choices) else self._choices
        return None if value is None else tuple(value)

    def describe(self) -> SettingInfo:
        """Return the setting's :class:`SettingInfo` as of now."""
        return SettingInfo(
            name=self.name,
            kind=self.kind,
            unit=self.unit,
            limits=self.limits(),
            increment=self.increment(),
            choices=self.choices(),
            read_only=self.read_only,
            locked_while_streaming=self.locked_while_streaming,
            doc=self.doc,
        )

    def get(self) -> Any:
        """Read the value from the device."""
        return self._get()

    def validate(self, value: Any) -> Any:
        """Return ``value`` converted to the setting's kind and snapped to its increment.

        Raises
        ------
        InputError
            The value has the wrong type, is outside the limits or not a choice.
        """
        name = self.name
        if self.kind == "bool":
            if not isinstance(value, bool | np.bool_ | int) or value not in (0, 1):
                raise InputError(f"{name} must be true or false, got {value!r}")
            return bool(value)
        if self.kind in ("enum", "str"):
            text = str(value)
            choices = self.choices()
            if choices is not None and text not in choices:
                raise InputError(f"{name} must be one of {', '.join(choices)}; got {text!r}")
            return text
        if self.kind == "roi":
            try:
                roi = ROI(*(int(v) for v in value))
            except (TypeError, ValueError) as exc:
                raise InputError(
                    f"{name} must be (left, top, width, height), got {value!r}"
                ) from exc
            if roi.left < 0 or roi.top < 0 or roi.width < 1 or roi.height < 1:
                raise InputError(
                    f"{name} {tuple(roi)} must have left, top >= 0 and a positive size"
                )
            return roi
        number = finite_number(name, value)
        limits = self.limits()
        low = limits[0] if limits else 0.0
        step = self.increment()
        if step is not None:
            number = low + round((number - low) / step) * step
        if limits is not None:
            tolerance = 1e-9 * max(abs(limits[0]), abs(limits[1]), 1e-300)
            if not limits[0] - tolerance <= number <= limits[1] + tolerance:
                raise InputError(
                    f"{name} {value!r} {self.unit} is outside [{limits[0]:g}, {limits[1]:g}]"
                    f" {self.unit}".rstrip()
                )
            number = min(max(number, limits[0]), limits[1])
        return round(number) if self.kind == "int" else number

    def write(self, value: Any) -> None:
        """Write an already validated value to the device."""
        if self._set is None:
            raise FeatureLockedError(f"{self.name} is read-only")
        self._set(value)


class Source(ABC):
    """A camera, a simulator or a file played back, behind one interface.

    Subclasses fill in the ``_do_*`` hooks, register settings with
    :meth:`add_setting` (their names carry a unit suffix: ``exposure_s``,
    ``frame_rate_hz``, ``gain_db``; ``roi`` and ``pixel_format`` are plain), and keep
    :attr:`counters` up to date (``delivered`` frames handed out, ``lost`` frames the
    transport or device lost, plus source-specific counts).

    Parameters
    ----------
    name : str
        What the source is, for logs and the recording's ``source`` attribute.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self._settings: dict[str, Setting] = {}
        self._is_open = False
        self._streaming = False
        self._state_lock = threading.RLock()
        #: Counters the source keeps: ``delivered``, ``lost`` and source-specific ones.
        self.counters: dict[str, int] = {"delivered": 0, "lost": 0}

    # -- hooks a driver fills in -------------------------------------------------
    @abstractmethod
    def _do_open(self) -> None:
        """Connect to the device; raise CameraNotFoundError when it is not there."""

    @abstractmethod
    def _do_close(self) -> None:
        """Release the device."""

    @abstractmethod
    def _do_start(self) -> None:
        """Start streaming."""

    @abstractmethod
    def _do_stop(self) -> None:
        """Stop streaming; frames not fetched yet may be discarded."""

    @abstractmethod
    def _do_fetch(self, timeout: float | None) -> Frame | None:
        """Return the next frame, None after ``timeout`` seconds, or raise EndOfStream."""

    @property
    @abstractmethod
    def frame_shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the frames the source will deliver, pixels."""

    @property
    @abstractmethod
    def dtype(self) -> np.dtype:
        """Dtype of the frames (``uint8`` or ``uint16``)."""

    @property
    def setup(self) -> dict[str, Any]:
        """The optical setup the source knows, for the recording's ``/setup``.

        ``wavelength_m`` (m), ``pixel_pitch_m`` (m), ``n1``, ``n2``, ... for the
        simulator and for replayed recordings; empty for cameras (the user gives it).
        """
        return {}

    def carried_experiment(self, index: int) -> str | None:
        """The experiment (JSON text) in force at frame ``index`` of a replayed file.

        A replayed holoview recording carries the experiment its frames were taken
        with, and its changes; a recording made from the replay copies them
        (:class:`~holoview.acquire.recorder.Recorder`). None for cameras and files
        that carry none.
        """
        return None

    # -- template methods --------------------------------------------------------
    @property
    def is_open(self) -> bool:
        """True between :meth:`open` and :meth:`close`."""
        return self._is_open

    @property
    def streaming(self) -> bool:
        """True between :meth:`start` and :meth:`stop`."""
        return self._streaming

    def open(self) -> None:
        """Connect to the device (does nothing when already open).

        Raises
        ------
        CameraNotFoundError
            Nothing answers to the requested device or file.
        """
        with self._state_lock:
            if self._is_open:
                return
            self._do_open()
            self._is_open = True
            logger.info("opened %s", self.name)

    def close(self) -> None:
        """Stop streaming if needed and release the device (safe to call twice)."""
        with self._state_lock:
            if not self._is_open:
                return
            try:
                if self._streaming:
                    self.stop()
            finally:
                self._is_open = False
                self._do_close()
                logger.info("closed %s", self.name)

    def start(self) -> None:
        """Start streaming (does nothing when already streaming)."""
        with self._state_lock:
            self._require_open()
            if self._streaming:
                return
            self._do_start()
            self._streaming = True
            logger.info("%s streaming %s %s", self.name, self.frame_shape, self.dtype)

    def stop(self) -> None:
        """Stop streaming (does nothing when not streaming)."""
        with self._state_lock:
            if not self._streaming:
                return
            self._streaming = False
            self._do_stop()
            logger.info("%s stopped; counters %s", self.name, self.counters)

    def fetch(self, timeout: float | None = 1.0) -> Frame | None:
        """Return the next frame, or None when none came within ``timeout`` seconds.

        Raises
        ------
        EndOfStream
            A finite source has no more frames.
        CameraDisconnectedError
            The device stopped answering.
        """
        if not self._streaming:
            raise AcquisitionError(f"{self.name} is not streaming; call start() first")
        frame = self._do_fetch(timeout)
        if frame is not None:
            self.counters["delivered"] += 1
        return frame

    def stats(self) -> dict[str, int]:
        """Return a copy of :attr:`counters` (``delivered``, ``lost``, source-specific)."""
        return dict(self.counters)

    # -- settings ----------------------------------------------------------------
    def add_setting(self, setting: Setting) -> None:
        """Register a setting (drivers call this in ``__init__`` or ``_do_open``)."""
        self._settings[setting.name] = setting

    def describe_settings(self) -> dict[str, SettingInfo]:
        """Return every setting's :class:`SettingInfo`, by name."""
        return {name: s.describe() for name, s in self._settings.items()}

    def has_setting(self, name: str) -> bool:
        """True when the source has a setting of that name."""
        return name in self._settings

    def _setting(self, name: str) -> Setting:
        try:
            return self._settings[name]
        except KeyError:
            known = ", ".join(sorted(self._settings)) or "none"
            raise UnsupportedFeatureError(
                f"{self.name} has no setting {name!r} (it has: {known})"
            ) from None

    def get(self, name: str) -> Any:
        """Read setting ``name`` from the device."""
        self._require_open()
        return self._setting(name).get()

    def get_all(self) -> dict[str, Any]:
        """Read every setting; a value that cannot be read is left out (and logged)."""
        values = {}
        for name, setting in self._settings.items():
            try:
                values[name] = setting.get()
            except HoloviewError as exc:
                logger.warning("%s: cannot read %s: %s", self.name, name, exc)
        return values

    def set(self, name: str, value: Any) -> Any:
        """Validate, snap, write, and read back setting ``name``; return the value read back.

        Raises
        ------
        UnsupportedFeatureError
            No such setting.
        FeatureLockedError
            It is read-only, or locked while streaming and the source streams.
        InputError
            The value is of the wrong type, outside the limits, or not a choice.
        """
        with self._state_lock:
            self._require_open()
            setting = self._setting(name)
            if setting.read_only:
                raise FeatureLockedError(f"{self.name}: {name} is read-only")
            if setting.locked_while_streaming and self._streaming:
                raise FeatureLockedError(f"{self.name}: {name} cannot change while streaming")
            snapped = setting.validate(value)
            setting.write(snapped)
            readback = setting.get()
            logger.info("%s: %s <- %r (read back %r)", self.name, name, value, readback)
            return readback

    def _require_open(self) -> None:
        if not self._is_open:
            raise AcquisitionError(f"{self.name} is not open; call open() first")

    def __enter__(self) -> Self:
        self.open()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
