"""The writer of holoview recordings: frames, ids and times into a new HDF5 file (SWMR).

The layout is :mod:`holoview.acquire.recording`'s. The file is created with every
attribute, then switched to SWMR mode so that a reader can follow it; appends are
flushed at most ``flush_interval_s`` after they come; a full disk or a failed write ends
the recording cleanly (:class:`DiskFullError`, :class:`RecordingWriteError`) with every
frame written before kept.
"""

from __future__ import annotations

import datetime as _dt
import logging
import os
import time
import uuid as _uuid
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import Self

import h5py
import numpy as np

from holoview import __version__
from holoview.acquire.durability import (
    CLOSE_MARGIN_BYTES,
    DiskReserve,
    free_bytes,
)
from holoview.acquire.hdf5_attributes import write_attributes
from holoview.acquire.recording import FORMAT_NAME, FORMAT_VERSION, LIBVER
from holoview.errors import InputError, OutputError, os_error_text

logger = logging.getLogger(__name__)

#: Pixel format assumed for a dtype when the writer is given none.
_DEFAULT_PIXEL_FORMAT = {np.dtype(np.uint8): ("Mono8", 8), np.dtype(np.uint16): ("Mono16", 16)}


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
        frame it holds from
        (:meth:`~holoview.acquire.recording_reader.RecordingReader.experiments`).
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
