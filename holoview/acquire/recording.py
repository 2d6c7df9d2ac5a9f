"""holoview's HDF5 recording format: a writer (SWMR, followable live) and a reader.

File layout, format ``holoview-recording`` version ``1.1``
----------------------------------------------------------
Everything is created before the writer switches the file to SWMR mode, so a
reader can open the file while it is being written and follow it with
:meth:`RecordingReader.refresh`. The file is opened with
``libver=('v110', 'latest')``: HDF5 1.10 tools can read it, SWMR works.

``/`` (root) attributes
    ``format`` (str, always ``"holoview-recording"``), ``format_version`` (str,
    ``"MAJOR.MINOR"``; readers accept any minor version of a major version they
    know), ``uuid`` (str, RFC 4122, unique per recording), ``created_utc`` (str,
    ISO 8601 start time in UTC), ``source`` (str, the source specification or
    camera name the frames came from), ``holoview_version`` (str).
``/frames`` dataset, shape ``(n_frames, rows, cols)``
    The raw camera values in the camera's own dtype (``uint8`` or ``uint16``;
    Mono10/12/16 stay unscaled in 16-bit containers). Chunked one frame per chunk,
    uncompressed, growing along axis 0. Attributes: ``pixel_format`` (str, e.g.
    ``"Mono12"``) and ``significant_bits`` (int).
``/frame_id`` dataset, ``int64``, shape ``(n_frames,)``
    The camera's frame counter (gaps mean frames the camera or transport lost).
``/t_device_s`` dataset, ``float64``, shape ``(n_frames,)``, seconds
    The camera's timestamp, on the camera's clock (``NaN`` where it has none).
``/t_host_s`` dataset, ``float64``, shape ``(n_frames,)``, seconds
    When the host received the frame, seconds since the UNIX epoch (``time.time()``).
``/setup`` group
    The optical setup as attributes: ``wavelength_m`` (m), ``pixel_pitch_m`` (m),
    ``n1`` and ``n2`` (refractive indices of the media above and below the surface,
    dimensionless), and anything else the writer was given. The unit of each
    attribute is the attribute of the same name on ``/setup/units`` (``""`` for
    dimensionless).
``/settings`` group
    Every camera setting at the start of the recording as attributes (for example
    ``exposure_s``, ``gain_db``, ``frame_rate_hz``, ``roi`` as
    ``(left, top, width, height)`` pixels), units on ``/settings/units`` the same way.
``/experiment`` group (since 1.1; absent when the writer was given none)
    The experiment in force (optics, labelled peaks, window, reference: the JSON of
    :mod:`holoview.engine.experiment`) and every change during the run. ``json`` is a
    ``uint8`` dataset holding the UTF-8 texts one after another; ``changes`` an
    ``int64`` dataset of shape ``(n_changes, 3)``: per change, the frame index it holds
    from, and the offset and length of its text in ``json``. Both grow while the file
    is written (SWMR has no variable-length strings).

A setting or setup value of ``None`` is not written. Names ending in a unit suffix
(``_m``, ``_s``, ``_hz``, ``_db``, ``_px``, ``_k``) get that unit unless one is
given explicitly. Other groups (for example ``/truth``, which the simulator adds by
reopening a closed recording with ``h5py.File(path, "a")``) are ignored by readers.

Durability: the writer flushes at most ``flush_interval_s`` (default 0.5 s) after
an append, and :meth:`RecordingWriter.flush_if_due` lets an idle recorder keep that
promise; a writer killed at any moment leaves a file that opens with every frame
up to its last flush. A full disk ends a recording cleanly: the writer checks the
free space before each frame and raises :class:`DiskFullError` while a frame and
the room to close the file still fit; when a write fails anyway (another program
filled the disk, an I/O error) it raises :class:`RecordingWriteError`, and
:meth:`RecordingWriter.close` gives back the reserve it keeps beside the file
(:mod:`holoview.acquire.durability`), trims the datasets to the frames fully
written and closes the file, which plain h5py and HDF5 tools then open.
Readers refuse a truncated file at once instead of retrying (same module).
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
import os
import time
import uuid as _uuid
from collections.abc import Iterator, Mapping
from pathlib import Path
from types import TracebackType
from typing import Any, Self

import h5py
import numpy as np

from holoview import __version__
from holoview.acquire.durability import (
    CLOSE_MARGIN_BYTES,
    DiskReserve,
    free_bytes,
    open_hdf5_for_reading,
)
from holoview.acquire.frame_times import FrameClock, choose_clock
from holoview.acquire.hdf5_attributes import plain_value, read_attributes, write_attributes
from holoview.acquire.hdf5_members import open_member
from holoview.acquire.hdf5_refresh import refresh_datasets
from holoview.errors import InputError, OutputError, os_error_text

logger = logging.getLogger(__name__)

#: The value of the root ``format`` attribute.
FORMAT_NAME = "holoview-recording"
#: The format version this module writes.
FORMAT_VERSION = "1.1"
#: Format major versions this module reads.
SUPPORTED_MAJOR_VERSIONS = (1,)
#: HDF5 library version bounds: readable by HDF5 1.10, SWMR-capable.
LIBVER = ("v110", "latest")

#: Pixel format assumed for a dtype when the writer is given none.
_DEFAULT_PIXEL_FORMAT = {np.dtype(np.uint8): ("Mono8", 8), np.dtype(np.uint16): ("Mono16", 16)}


def _is_number(dataset: h5py.Dataset) -> bool:
    return dataset.dtype.kind in "iuf"


def _layout(dataset: h5py.Dataset) -> str:
    return f"{dataset.name} is {dataset.dtype} of shape {dataset.shape}"


class RecordingWriteError(OutputError):
    """Writing the recording failed (disk full, I/O error); the frames written are kept."""


class DiskFullError(RecordingWriteError):
    """The disk has no room for the next frame; the recording stopped before it."""


class RecordingWriter:
    """Write frames with their ids and timestamps to a new holoview recording.

    The file is created at once, with every attribute written, then switched to
    SWMR mode (when ``swmr``) so readers can follow it while it grows.

    Parameters
    ----------
    path : str or Path
        The file to create; an existing file is an error (nothing is overwritten).
    frame_shape : tuple of int
        ``(rows, cols)`` of every frame, pixels.
    dtype : numpy dtype
        Dtype of every frame (``uint8`` or ``uint16`` for camera data; any integer or
        float dtype is accepted).
    setup : mapping, optional
        The optical setup: ``wavelength_m`` (m), ``pixel_pitch_m`` (m), ``n1``, ``n2``
        and any other value; a value may be a ``(value, unit)`` pair.
    settings : mapping, optional
        Every camera setting, same conventions (``exposure_s``, ``gain_db``, ...).
    source : str
        What the frames came from (a source specification or camera name).
    swmr : bool
        Switch to SWMR mode so readers can open the file while it is written.
    pixel_format : str, optional
        GenICam pixel format name (default: ``Mono8`` for uint8, ``Mono16`` for uint16).
    significant_bits : int, optional
        Bits that carry data in each value (default: the pixel format's, or the
        dtype's size).
    flush_interval_s : float
        Longest time, seconds, an appended frame waits before it is flushed to disk.
    experiment : str, optional
        The experiment in force from the first frame, as JSON text (later changes:
        :meth:`note_experiment`).

    Raises
    ------
    InputError
        The file exists, its folder does not, or a shape, dtype or setting is invalid.
    OutputError
        The disk has no room for the file and its reserve, or the file cannot be created.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        frame_shape: tuple[int, int],
        dtype: np.typing.DTypeLike,
        *,
        setup: Mapping[str, object] | None = None,
        settings: Mapping[str, object] | None = None,
        source: str = "",
        swmr: bool = True,
        pixel_format: str | None = None,
        significant_bits: int | None = None,
        flush_interval_s: float = 0.5,
        experiment: str | None = None,
    ) -> None:
        self.path = Path(path)
        shape = tuple(int(n) for n in frame_shape)
        if len(shape) != 2 or min(shape) < 1:
            raise InputError(
                f"frame shape must be (rows, cols) of positive ints, got {frame_shape}"
            )
        self.frame_shape: tuple[int, int] = (shape[0], shape[1])
        self.dtype = np.dtype(dtype).newbyteorder("=")
        if self.dtype.kind not in "iuf":
            raise InputError(f"frames must be integer or float, got dtype {self.dtype}")
        if not flush_interval_s > 0:
            raise InputError(f"flush interval must be positive, got {flush_interval_s} s")
        if self.path.exists():
            raise InputError(f"{self.path} exists; holoview does not overwrite recordings")
        if not self.path.parent.is_dir():
            raise InputError(f"folder {self.path.parent} does not exist")
        default_format, default_bits = _DEFAULT_PIXEL_FORMAT.get(
            self.dtype, ("", self.dtype.itemsize * 8)
        )
        self.pixel_format = pixel_format or default_format
        self.significant_bits = int(significant_bits or default_bits)
        self.flush_interval_s = float(flush_interval_s)
        self.uuid = str(_uuid.uuid4())
        self._n = 0
        self._broken = False  # a write failed: the datasets may be longer than _n
        self._unflushed_since: float | None = None
        self._frame_bytes = self.frame_shape[0] * self.frame_shape[1] * self.dtype.itemsize
        self._reserve = DiskReserve(self.path)
        try:
            self._file = h5py.File(self.path, "w-", libver=LIBVER)
        except OSError as exc:
            self._reserve.release()
            raise OutputError(f"cannot create {self.path}: {os_error_text(exc)}") from exc
        try:
            self._create_layout(setup, settings, source)
            if experiment is not None:
                self.note_experiment(experiment)
            if swmr:
                self._file.swmr_mode = True
            self._file.flush()
        except BaseException as exc:
            self._file.close()
            self.path.unlink(missing_ok=True)
            self._reserve.release()
            if isinstance(exc, OSError | RuntimeError):
                raise OutputError(f"cannot create {self.path}: {os_error_text(exc)}") from exc
            raise
        logger.info(
            "recording %s: %s frames %s, uuid %s",
            self.path,
            self.dtype,
            self.frame_shape,
            self.uuid,
        )

    def _create_layout(
        self,
        setup: Mapping[str, object] | None,
        settings: Mapping[str, object] | None,
        source: str,
    ) -> None:
        f = self._file
        f.attrs["format"] = FORMAT_NAME
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["uuid"] = self.uuid
        f.attrs["created_utc"] = _dt.datetime.now(_dt.UTC).isoformat()
        f.attrs["source"] = str(source)
        f.attrs["holoview_version"] = __version__
        rows, cols = self.frame_shape
        frames = f.create_dataset(
            "frames",
            shape=(0, rows, cols),
            maxshape=(None, rows, cols),
            dtype=self.dtype,
            chunks=(1, rows, cols),
        )
        frames.attrs["pixel_format"] = self.pixel_format
        frames.attrs["significant_bits"] = self.significant_bits
        chunk = (4096,)
        f.create_dataset("frame_id", shape=(0,), maxshape=(None,), dtype=np.int64, chunks=chunk)
        for name in ("t_device_s", "t_host_s"):
            f.create_dataset(name, shape=(0,), maxshape=(None,), dtype=np.float64, chunks=chunk)
            f[name].attrs["unit"] = "s"
        f["t_host_s"].attrs["clock"] = "seconds since the UNIX epoch (host time.time())"
        f["t_device_s"].attrs["clock"] = "the camera's clock; NaN where it has none"
        write_attributes(f.create_group("setup"), setup)
        write_attributes(f.create_group("settings"), settings)
        group = f.create_group("experiment")
        group.create_dataset("json", shape=(0,), maxshape=(None,), dtype=np.uint8, chunks=(4096,))
        group.create_dataset(
            "changes", shape=(0, 3), maxshape=(None, 3), dtype=np.int64, chunks=(64, 3)
        )
        group["changes"].attrs["columns"] = "from_frame, offset, length"
        self._frames = frames
        self._ids = f["frame_id"]
        self._t_device = f["t_device_s"]
        self._t_host = f["t_host_s"]

    def __len__(self) -> int:
        """Return the number of frames appended so far."""
        return self._n

    @property
    def closed(self) -> bool:
        """True once :meth:`close` has run."""
        return not self._file.id.valid

    def append(self, frame: np.ndarray, frame_id: int, t_device: float, t_host: float) -> None:
        """Append one frame with its id and timestamps.

        Parameters
        ----------
        frame : ndarray
            ``(rows, cols)`` of the writer's dtype; it is not modified.
        frame_id : int
            The camera's frame counter.
        t_device : float
            The camera's timestamp, seconds (``NaN`` when unknown).
        t_host : float
            Host arrival time, seconds since the UNIX epoch.

        Raises
        ------
        InputError
            The frame's shape or dtype differs from the writer's.
        DiskFullError
            The frame and the room to close the file do not fit on the disk; nothing
            was written.
        RecordingWriteError
            The write failed; :meth:`close` keeps the frames appended before.
        """
        if self.closed:
            raise InputError(f"recording {self.path} is closed")
        if self._broken:
            raise RecordingWriteError(f"{self.path}: an earlier write failed; close the file")
        array = np.asarray(frame)
        if array.shape != self.frame_shape:
            raise InputError(
                f"frame shape {array.shape} differs from the recording's {self.frame_shape}"
            )
        if array.dtype != self.dtype:
            raise InputError(f"frame dtype {array.dtype} differs from the recording's {self.dtype}")
        n = self._n
        free = free_bytes(self.path.parent)
        if free is not None and free < self._frame_bytes + CLOSE_MARGIN_BYTES:
            raise DiskFullError(
                f"{self.path}: the disk is full ({free / 1e6:.1f} MB free): "
                f"recording stopped after {n} frames"
            )
        try:
            self._frames.resize(n + 1, axis=0)
            # One frame is exactly one uncompressed chunk: write its bytes directly.
            self._frames.id.write_direct_chunk((n, 0, 0), np.ascontiguousarray(array).data)
            for dataset, value in (
                (self._ids, frame_id),
                (self._t_device, t_device),
                (self._t_host, t_host),
            ):
                dataset.resize(n + 1, axis=0)
                dataset[n] = value
        except (OSError, RuntimeError) as exc:
            self._broken = True
            raise self._write_error(exc) from exc
        self._n = n + 1
        now = time.monotonic()
        if self._unflushed_since is None:
            self._unflushed_since = now
        if now - self._unflushed_since >= self.flush_interval_s:
            self.flush()

    def note_experiment(self, text: str) -> None:
        """Store the experiment (JSON text) in force from the next frame appended.

        A change before any frame replaces nothing: each change is kept, with the
        frame it holds from (:meth:`RecordingReader.experiments`).
        """
        if self.closed:
            raise InputError(f"recording {self.path} is closed")
        data = np.frombuffer(text.encode("utf-8"), dtype=np.uint8)
        group = self._file["experiment"]
        blob, changes = group["json"], group["changes"]
        offset, k = blob.shape[0], changes.shape[0]
        try:
            blob.resize(offset + data.size, axis=0)
            blob[offset:] = data
            changes.resize(k + 1, axis=0)
            changes[k] = (self._n, offset, data.size)
        except (OSError, RuntimeError) as exc:
            self._broken = True
            raise self._write_error(exc) from exc
        if self._unflushed_since is None:
            self._unflushed_since = time.monotonic()

    def flush_if_due(self) -> bool:
        """Flush when frames have waited ``flush_interval_s`` or longer; return whether it did."""
        if self._unflushed_since is None or self.closed:
            return False
        if time.monotonic() - self._unflushed_since < self.flush_interval_s:
            return False
        self.flush()
        return True

    def flush(self) -> None:
        """Write every appended frame to disk now (SWMR readers see them after refresh).

        Raises
        ------
        RecordingWriteError
            The flush failed (a full disk); :meth:`close` still tries to keep every frame.
        """
        if self.closed:
            return
        try:
            self._file.flush()
        except (OSError, RuntimeError) as exc:
            self._broken = True
            raise self._write_error(exc) from exc
        self._unflushed_since = None

    def _write_error(self, exc: BaseException) -> RecordingWriteError:
        return RecordingWriteError(
            f"writing {self.path} failed: {os_error_text(exc)}; "
            f"recording stopped after {self._n} frames"
        )

    def close(self) -> None:
        """Flush and close the file; calling it again does nothing.

        The reserve beside the file is given back first, so that a disk that filled
        up still has the room for the file's index; after a failed write the datasets
        are trimmed to the frames appended completely.

        Raises
        ------
        RecordingWriteError
            The file could not be flushed or closed cleanly (it is closed all the same;
            holoview's reader still opens it with the frames of its last flush).
        """
        if self.closed:
            return
        self._reserve.release()
        error: RecordingWriteError | None = None
        try:
            if self._broken:
                for dataset in (self._frames, self._ids, self._t_device, self._t_host):
                    if dataset.shape[0] != self._n:
                        dataset.resize(self._n, axis=0)
            self._file.flush()
        except (OSError, RuntimeError) as exc:
            error = RecordingWriteError(
                f"closing {self.path} failed: {os_error_text(exc)}; holoview still reads "
                "the frames of its last flush"
            )
        finally:
            try:
                self._file.close()
            except (OSError, RuntimeError) as exc:
                error = error or RecordingWriteError(
                    f"closing {self.path} failed: {os_error_text(exc)}"
                )
        logger.info("recording %s closed with %d frames", self.path, self._n)
        if error is not None:
            raise error

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class RecordingReader:
    """Read a holoview recording, also one that is still being written (SWMR).

    ``len(reader)`` is the frame count as of the last :meth:`refresh`; ``reader[i]``
    and ``reader[a:b]`` return frames as arrays (``(rows, cols)`` or
    ``(n, rows, cols)``); iterating yields each frame in order.

    Parameters
    ----------
    path : str or Path
        A file written by :class:`RecordingWriter`.

    Attributes
    ----------
    setup : dict
        ``wavelength_m`` (m), ``pixel_pitch_m`` (m), ``n1``, ``n2``, ... as written.
    setup_units, settings_units : dict
        Unit of each entry (``""`` when dimensionless).
    settings : dict
        Camera settings as written.
    format_version, uuid, created_utc, source : str
        Root attributes.
    pixel_format : str
        GenICam pixel format name of the frames.
    significant_bits : int
        Bits that carry data in each value.

    Raises
    ------
    InputError
        The file is missing, not HDF5, not a holoview recording, of an unknown major
        version, or holds no frames dataset.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError(f"{self.path}: no such file")
        self._file = self._open(self.path)
        try:
            self._read_header()
        except BaseException:
            self._file.close()
            raise

    @staticmethod
    def _open(path: Path) -> h5py.File:
        """Open plainly, or for SWMR reading when a writer has the file open (or was killed).

        A truncated or damaged file is refused at once (:mod:`holoview.acquire.durability`).
        """
        return open_hdf5_for_reading(path)

    def _read_header(self) -> None:
        f = self._file
        name = plain_value(f.attrs.get("format", ""))
        if name != FORMAT_NAME:
            raise InputError(f"{self.path}: not a holoview recording (format attribute {name!r})")
        self.format_version = str(plain_value(f.attrs.get("format_version", "")))
        try:
            major = int(self.format_version.split(".", 1)[0])
        except ValueError:
            major = -1
        if major not in SUPPORTED_MAJOR_VERSIONS:
            raise InputError(
                f"{self.path}: recording format version {self.format_version!r} is not supported"
            )
        frames = open_member(f, "frames", h5py.Dataset, self.path)
        if frames is None or frames.ndim != 3:
            raise InputError(f"{self.path}: holds no frames dataset (/frames, 3-D)")
        columns = []
        for name in ("frame_id", "t_device_s", "t_host_s"):
            column = open_member(f, name, h5py.Dataset, self.path)
            if column is None:
                raise InputError(f"{self.path}: /{name} is missing")
            columns.append(column)
        self._frames = frames
        self._ids, self._t_device, self._t_host = columns
        if self._ids.ndim != 1 or self._ids.dtype.kind not in "iu":
            raise InputError(f"{self.path}: {_layout(self._ids)}, not one integer per frame")
        self.uuid = str(plain_value(f.attrs.get("uuid", "")))
        self.created_utc = str(plain_value(f.attrs.get("created_utc", "")))
        self.source = str(plain_value(f.attrs.get("source", "")))
        self.pixel_format = str(plain_value(frames.attrs.get("pixel_format", "")))
        self.significant_bits = int(
            plain_value(frames.attrs.get("significant_bits", frames.dtype.itemsize * 8))
        )
        self.setup, self.setup_units = self._attributes("setup")
        self.settings, self.settings_units = self._attributes("settings")
        self._n = self._complete_count()

    def _attributes(self, name: str) -> tuple[dict[str, Any], dict[str, str]]:
        """The values and units of the group ``name`` (``/setup``, ``/settings``)."""
        group = open_member(self._file, name, h5py.Group, self.path)
        units = None if group is None else open_member(group, "units", h5py.Group, self.path)
        return read_attributes(group, units)

    def experiments(self) -> list[tuple[int, str]]:
        """Every experiment the recording carries: ``(from_frame, JSON text)``, in order.

        Empty for recordings written without one (format 1.0 included). A text that
        cannot be decoded is returned as it decodes with replacement characters; the
        experiment parser then says what is wrong.

        Raises
        ------
        InputError
            ``/experiment`` is not laid out as the format says (``json`` not 1-D
            ``uint8``, ``changes`` not ``(n, 3)`` integers, a text outside ``json``) or
            lies outside the file (:func:`~holoview.acquire.hdf5_members.open_member`).
        """
        group = open_member(self._file, "experiment", h5py.Group, self.path)
        if group is None:
            return []
        blob = open_member(group, "json", h5py.Dataset, self.path)
        changes = open_member(group, "changes", h5py.Dataset, self.path)
        if blob is None or changes is None:
            return []
        where = f"{self.path}: the stored experiment"
        if blob.ndim != 1 or blob.dtype != np.uint8:
            raise InputError(
                f"{where} is damaged: /experiment/json is {blob.dtype} of shape {blob.shape}, "
                "not the 1-D uint8 texts of the format"
            )
        if changes.ndim != 2 or changes.shape[1] != 3 or changes.dtype.kind not in "iu":
            raise InputError(
                f"{where} is damaged: /experiment/changes is {changes.dtype} of shape "
                f"{changes.shape}, not (n, 3) integers"
            )
        # changes first: the texts a change names are written before it
        refresh_datasets(self._file, (changes, blob))
        rows = np.asarray(changes[()], dtype=np.int64)
        raw = blob[()].tobytes()
        out = []
        for start, offset, length in rows:
            if start < 0 or offset < 0 or length < 0 or offset + length > len(raw):
                raise InputError(
                    f"{where} is damaged: a change from frame {start} names bytes "
                    f"{offset} to {offset + length} of the {len(raw)} stored"
                )
            text = raw[offset : offset + length]
            out.append((int(start), text.decode("utf-8", errors="replace")))
        return out

    def _complete_count(self) -> int:
        """Frames whose frame data, id and both timestamps are all present.

        A time column of the wrong layout (:meth:`clock` says so) does not count.
        """
        columns = [self._frames, self._ids, self._t_device, self._t_host]
        return int(min(c.shape[0] for c in columns if c.ndim >= 1 and _is_number(c)))

    @property
    def stored_frames(self) -> int:
        """Frames ``/frames`` holds, complete or not (see :meth:`incomplete`)."""
        return int(self._frames.shape[0])

    def incomplete(self) -> str | None:
        """Why frames stored are left out (a column shorter than ``/frames``), or None."""
        if self._n >= self.stored_frames:
            return None
        short = [
            f"{c.name} holds {c.shape[0]}"
            for c in (self._ids, self._t_device, self._t_host)
            if c.ndim == 1 and c.shape[0] < self.stored_frames
        ]
        return (
            f"{self.path}: only the first {self._n} of the {self.stored_frames} frames stored "
            f"are complete ({', '.join(short)} rows); frames {self._n} and later are left out"
        )

    @property
    def being_written(self) -> bool:
        """True when a writer had the file open when it was opened (or was killed)."""
        return bool(self._file.swmr_mode)

    def refresh(self) -> int:
        """See frames a live writer has flushed since the last call; return the new count."""
        refresh_datasets(self._file, (self._frames, self._ids, self._t_device, self._t_host))
        self._n = self._complete_count()
        return self._n

    @property
    def frame_shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of every frame, pixels."""
        return int(self._frames.shape[1]), int(self._frames.shape[2])

    @property
    def dtype(self) -> np.dtype:
        """The frames' dtype."""
        return self._frames.dtype

    @property
    def frame_ids(self) -> np.ndarray:
        """The camera frame counter of every frame, int64."""
        return self._ids[: self._n]

    def _time_column(self, dataset: h5py.Dataset) -> tuple[np.ndarray, str | None]:
        """A time column's values, float64 (NaN where unusable), and why it is unusable."""
        if dataset.ndim != 1 or not _is_number(dataset):
            return np.full(self._n, math.nan), f"{_layout(dataset)}, not one number per frame"
        return np.asarray(dataset[: self._n], dtype=np.float64), None

    @property
    def t_device(self) -> np.ndarray:
        """Device timestamps, seconds on the camera's clock (NaN where unknown)."""
        return self._time_column(self._t_device)[0]

    @property
    def t_host(self) -> np.ndarray:
        """Host arrival times, seconds since the UNIX epoch (NaN where unknown)."""
        return self._time_column(self._t_host)[0]

    def clock(self, frames: range | None = None) -> FrameClock:
        """The clock that times ``frames`` (default all), by the one rule, and why.

        The camera's where it times every frame, runs forward and jumps nowhere; else
        the host's arrival times (which hold when frames arrived or were written, not
        when the camera took them); else none (:mod:`holoview.acquire.frame_times`).
        """
        chosen = range(self._n) if frames is None else frames
        index = np.asarray(chosen, dtype=np.int64)
        device, device_problem = self._time_column(self._t_device)
        host, host_problem = self._time_column(self._t_host)
        unusable = {"camera": device_problem, "host": host_problem}
        return choose_clock(
            device[index],
            host[index],
            chosen,
            np.asarray(self._ids[: self._n], dtype=np.int64)[index],
            unusable={k: v for k, v in unusable.items() if v is not None},
        )

    @property
    def times(self) -> np.ndarray:
        """The frames' times, seconds, by the one rule of :meth:`clock` (NaN: no clock)."""
        return self.clock().times

    @property
    def fps(self) -> float:
        """Mean frame rate over :attr:`times`, frames per second (NaN if unknown).

        A simulation written at 19 frames/s of a 60 frames/s camera reads 60.
        """
        t = self.times
        if len(t) < 2 or not t[-1] > t[0]:
            return math.nan
        return float((len(t) - 1) / (t[-1] - t[0]))

    def __len__(self) -> int:
        return self._n

    def frame(self, index: int) -> np.ndarray:
        """Return frame ``index`` (negative counts from the end) as a new array."""
        i = int(index)
        if i < 0:
            i += self._n
        if not 0 <= i < self._n:
            raise IndexError(f"frame {index} out of range for a recording of {self._n}")
        return self._frames[i]

    def __getitem__(self, key: int | slice) -> np.ndarray:
        if isinstance(key, slice):
            indices = range(*key.indices(self._n))
            if not indices:
                return np.empty((0, *self.frame_shape), self.dtype)
            if indices.step > 0:
                return self._frames[indices.start : indices.stop : indices.step]
            return self._frames[indices[-1] : indices[0] + 1 : -indices.step][::-1]
        return self.frame(key)

    def __iter__(self) -> Iterator[np.ndarray]:
        for i in range(self._n):
            yield self._frames[i]

    def close(self) -> None:
        """Close the file; calling it again does nothing."""
        if self._file.id.valid:
            self._file.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
