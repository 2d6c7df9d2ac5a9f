"""Frames from a numpy array file (``.npy``, or one array of an ``.npz``), a frame at a time."""

from __future__ import annotations

import math
import zipfile
from pathlib import Path
from typing import IO

import numpy as np

from holoview.acquire.frame_file import FrameFile
from holoview.errors import InputError


class NumpyFile(FrameFile):
    """A numpy array: ``.npy``, or the one array (or ``frames``) of an ``.npz``.

    A 2-D array is one frame, a 3-D array ``(frames, rows, cols)`` a stack; integer
    or real values. Frames are read one at a time from the file (a member of an
    ``.npz`` is read as a stream), never the whole array at once.
    """

    kind = "numpy"

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self._zip: zipfile.ZipFile | None = None
        try:
            self._stream, size = self._open_stream(path)
        except (OSError, zipfile.BadZipFile, ValueError) as exc:
            self.close()
            raise InputError(f"{path}: not a readable numpy file ({exc})") from exc
        try:
            shape, dtype = self._read_header(path, size)
        except BaseException:
            self.close()
            raise
        self._count = shape[0] if len(shape) == 3 else 1
        self._stored_dtype = dtype
        self._set_format(shape[-2:], dtype.newbyteorder("="))
        self._frame_bytes = shape[-2] * shape[-1] * dtype.itemsize

    def _open_stream(self, path: Path) -> tuple[IO[bytes], int]:
        """Open the array's bytes; return the stream and its size in bytes."""
        if path.suffix.lower() == ".npy":
            return open(path, "rb"), path.stat().st_size
        self._zip = zipfile.ZipFile(path)
        members = [m for m in self._zip.infolist() if m.filename.endswith(".npy")]
        named = [m for m in members if m.filename == "frames.npy"]
        if len(members) != 1 and not named:
            names = ", ".join(m.filename[:-4] for m in members) or "none"
            raise ValueError(
                f"it holds {len(members)} arrays ({names}): keep one, or name it frames"
            )
        member = (named or members)[0]
        return self._zip.open(member), member.file_size

    def _read_header(self, path: Path, size: int) -> tuple[tuple[int, ...], np.dtype]:
        """Read and check the array's header; return its shape and stored dtype."""
        from numpy.lib import format as npy

        try:
            version = npy.read_magic(self._stream)
            if version == (1, 0):
                shape, fortran, dtype = npy.read_array_header_1_0(self._stream)
            elif version == (2, 0):
                shape, fortran, dtype = npy.read_array_header_2_0(self._stream)
            else:
                raise ValueError(f"npy format version {version} is not supported")
        except (ValueError, OSError, EOFError) as exc:
            raise InputError(f"{path}: not a readable numpy array ({exc})") from exc
        self._offset = self._stream.tell()
        self._fortran = bool(fortran)
        where = f"{path}: the array of shape {shape} and dtype {dtype}"
        if dtype.kind not in "uif" or dtype.fields is not None:
            hint = "; a complex field is not a hologram: give the intensity" * (dtype.kind == "c")
            raise InputError(f"{where} does not hold pixel values (integers or reals{hint})")
        if len(shape) == 3 and shape[-1] in (3, 4) and shape[0] >= 16:
            raise InputError(f"{where} looks like a colour image: give grey frames")
        if len(shape) not in (2, 3) or min(shape) < 1:
            raise InputError(f"{where}: frames are 2-D (rows, cols) or 3-D (frames, rows, cols)")
        if self._fortran and len(shape) == 3:
            raise InputError(f"{where} is in Fortran order: save numpy.ascontiguousarray of it")
        needed = self._offset + math.prod(shape) * dtype.itemsize
        if size < needed:
            raise InputError(
                f"{path}: truncated: the array needs {needed} bytes, the file holds {size}"
            )
        return tuple(int(n) for n in shape), dtype

    def __len__(self) -> int:
        return self._count

    def read(self, index: int) -> np.ndarray:
        if not 0 <= index < self._count:
            raise InputError(f"{self.path}: frame {index} out of range (0..{self._count - 1})")
        try:
            self._stream.seek(self._offset + index * self._frame_bytes)
            data = self._stream.read(self._frame_bytes)
        except (OSError, zipfile.BadZipFile, EOFError) as exc:
            raise InputError(f"{self.path}: frame {index} is unreadable ({exc})") from exc
        if len(data) != self._frame_bytes:
            raise InputError(f"{self.path}: frame {index} is cut short")
        frame = np.frombuffer(data, self._stored_dtype).reshape(
            self.frame_shape, order="F" if self._fortran else "C"
        )
        return frame.astype(self.dtype, order="C", copy=True)

    def close(self) -> None:
        stream = getattr(self, "_stream", None)
        if stream is not None:
            stream.close()
        if self._zip is not None:
            self._zip.close()
