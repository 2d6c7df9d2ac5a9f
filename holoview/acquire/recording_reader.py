"""The reader of holoview recordings, also of one still being written (SWMR).

The layout is :mod:`holoview.acquire.recording`'s; a reader accepts every minor version
of the major versions it knows and follows a growing file with
:meth:`RecordingReader.refresh`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import Any, Self

import h5py
import numpy as np

from holoview.acquire.durability import (
    open_hdf5_for_reading,
)
from holoview.acquire.frame_times import FrameClock, choose_clock
from holoview.acquire.hdf5_attributes import plain_value, read_attributes
from holoview.acquire.hdf5_members import open_member
from holoview.acquire.hdf5_refresh import refresh_datasets
from holoview.acquire.recording import FORMAT_NAME, SUPPORTED_MAJOR_VERSIONS
from holoview.errors import InputError


def _is_number(dataset: h5py.Dataset) -> bool:
    return dataset.dtype.kind in "iuf"


def _layout(dataset: h5py.Dataset) -> str:
    return f"{dataset.name} is {dataset.dtype} of shape {dataset.shape}"


class RecordingReader:
    """Read a holoview recording, also one that is still being written (SWMR).

    ``len(reader)`` is the frame count as of the last :meth:`refresh`; ``reader[i]``
    and ``reader[a:b]`` return frames as arrays (``(rows, cols)`` or
    ``(n, rows, cols)``); iterating yields each frame in order.

    Parameters
    ----------
    path : str or Path
        A file written by :class:`~holoview.acquire.recording_writer.RecordingWriter`.

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
