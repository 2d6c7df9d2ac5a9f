"""Recordings that survive a full disk and readers that never hang on a damaged file.

Opening (:func:`open_hdf5_for_reading`)
    HDF5's SWMR reader, which a recording being written needs, skips the library's
    end-of-file check and retries every unreadable piece of metadata up to 100 times
    with a growing wait: a truncated copy of a recording (an interrupted copy or
    download) hung ``process`` for ten minutes, deaf to Ctrl-C. So the superblock
    (:func:`read_superblock`) is read first: a file shorter than the end its header
    states is refused at once; a file closed by its writer (status flags clear) is
    opened plainly, with HDF5's own end-of-file check; only a file whose writer is
    running, or was killed, is opened for SWMR reading, with
    :data:`SWMR_READ_ATTEMPTS` attempts per piece of metadata (about 0.3 s in all
    for a piece that never reads right, instead of hours).
Writing (:class:`DiskReserve`, :func:`free_bytes`)
    A writer checks the free space before each frame and stops cleanly, with every
    frame so far flushed and the file closed, when a frame and
    :data:`CLOSE_MARGIN_BYTES` no longer fit. When the disk fills anyway (another
    program, a quota, a network drive), a reserve file of
    :data:`RESERVE_BYTES` kept beside the recording is deleted, which gives HDF5 the
    room to write its index and close the file.
"""

from __future__ import annotations

import ctypes
import logging
import os
import struct
from pathlib import Path
from typing import NamedTuple

import h5py

from holoview.atomic import hidden_sibling
from holoview.errors import InputError, OutputError, os_error_text

logger = logging.getLogger(__name__)

#: HDF5's file signature.
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"

#: Attempts to read each piece of metadata of a file opened for SWMR reading (HDF5's
#: default is 100, with a wait that doubles: hours for a truncated file). 28 bound it
#: to about 0.3 s here, and still ride out a writer's torn update.
SWMR_READ_ATTEMPTS = 28

#: Bytes kept free beside a recording, given back to HDF5 when a write fails for room.
RESERVE_BYTES = 4 << 20

#: Free bytes, besides the next frame, below which a writer stops (its index and close).
CLOSE_MARGIN_BYTES = 1 << 20


class Superblock(NamedTuple):
    """What the start of an HDF5 file says about it.

    Attributes
    ----------
    version : int
        Superblock version (0 to 3; SWMR files have 3).
    end_of_file : int
        Where the file's data end, bytes from its start (its base address added).
    open_for_writing : bool
        A writer has the file open, or was killed before it closed it (status flags).
    """

    version: int
    end_of_file: int
    open_for_writing: bool


def read_superblock(path: str | os.PathLike[str]) -> Superblock | None:
    """Return the superblock of the HDF5 file at ``path``, or None if it is not HDF5.

    The superblock sits at byte 0, 512, 1024, 2048, ... (after a user block).

    Raises
    ------
    InputError
        The file cannot be read.
    """
    p = Path(path)
    try:
        size = p.stat().st_size
        with open(p, "rb") as f:
            offset = 0
            while offset + 64 <= size:
                f.seek(offset)
                head = f.read(96)
                if head[:8] == HDF5_SIGNATURE:
                    return _parse_superblock(head, offset)
                offset = 512 if offset == 0 else offset * 2
    except OSError as exc:
        raise InputError(f"{p}: cannot be read ({os_error_text(exc)})") from exc
    return None


def _parse_superblock(head: bytes, offset: int) -> Superblock | None:
    version = head[8]
    if version in (2, 3):
        if head[9] != 8:  # size of offsets: holoview and h5py write 8
            return None
        base, _extension, end = struct.unpack_from("<QQQ", head, 12)
        return Superblock(version, base + end, bool(head[11] & 0b101))
    if version in (0, 1):
        if head[13] != 8:
            return None
        at = 24 + (4 if version == 1 else 0)
        base, _free, end = struct.unpack_from("<QQQ", head, at)
        return Superblock(version, base + end, False)
    return None


def _hdf5_library() -> ctypes.CDLL | None:
    """The HDF5 library h5py has loaded (the same copy, so its ids are valid), Linux only."""
    try:
        with open("/proc/self/maps", encoding="ascii", errors="replace") as maps:
            for line in maps:
                name = line.rsplit("/", 1)[-1].strip()
                if name.startswith("libhdf5") and not name.startswith("libhdf5_hl"):
                    return ctypes.CDLL(line[line.index("/") :].strip())
    except (OSError, ValueError):
        pass
    return None


def _bounded_swmr_access() -> h5py.h5p.PropFAID:
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5py.h5f.LIBVER_V110, h5py.h5f.LIBVER_LATEST)
    library = _hdf5_library()
    setter = getattr(library, "H5Pset_metadata_read_attempts", None)
    if setter is None:
        logger.debug("HDF5 metadata read attempts cannot be bounded here")
        return fapl
    setter.argtypes = [ctypes.c_int64, ctypes.c_uint]
    setter.restype = ctypes.c_int
    if setter(fapl.id, SWMR_READ_ATTEMPTS) < 0:
        logger.debug("H5Pset_metadata_read_attempts failed")
    return fapl


def open_hdf5_for_reading(path: str | os.PathLike[str]) -> h5py.File:
    """Open an HDF5 file for reading, quickly refusing one that is truncated or damaged.

    See the module documentation: a closed file is opened plainly, a file being
    written (or whose writer was killed) for SWMR reading with bounded retries.

    Raises
    ------
    InputError
        Not an HDF5 file, truncated, or unreadable (one line naming the file).
    """
    p = Path(path)
    block = read_superblock(p)
    if block is None:
        raise InputError(f"{p}: not a readable HDF5 file (no HDF5 signature)")
    size = p.stat().st_size
    if size < block.end_of_file:
        raise InputError(
            f"{p}: truncated: the file has {size} bytes, its header says {block.end_of_file} "
            "(an interrupted copy or download?)"
        )
    try:
        if not block.open_for_writing:
            return h5py.File(p, "r", libver=("v110", "latest"))
        flags = h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ
        return h5py.File(h5py.h5f.open(os.fsencode(p), flags, fapl=_bounded_swmr_access()))
    except (OSError, RuntimeError) as exc:
        text = str(exc)
        reason = text[text.find("(") + 1 : text.rfind(")")] if "(" in text else text
        raise InputError(f"{p}: not a readable HDF5 file ({reason})") from exc


def free_bytes(path: str | os.PathLike[str]) -> int | None:
    """Bytes an unprivileged writer may still use on the file system of ``path`` (None: unknown)."""
    try:
        stats = os.statvfs(path)
    except (OSError, AttributeError):
        return None
    return stats.f_bavail * stats.f_frsize


def _allocate(fd: int, size: int) -> None:
    """Give the open file ``fd`` ``size`` bytes of disk (zeros where fallocate is missing)."""
    allocate = getattr(os, "posix_fallocate", None)
    if allocate is not None:
        allocate(fd, 0, size)
        return
    block = bytes(1 << 16)
    for start in range(0, size, len(block)):
        os.write(fd, block[: min(len(block), size - start)])
    os.fsync(fd)


class DiskReserve:
    """A file of ``size`` bytes beside ``target``, allocated now, deleted to make room later.

    Parameters
    ----------
    target : Path
        The file being protected; the reserve is ``.NAME.reserve`` in its folder (NAME
        shortened, with a hash, where that would be too long a file name).
    size : int
        Bytes to hold.
    name : str, optional
        What to call the target in messages (default: its path).

    Raises
    ------
    OutputError
        The disk has not even that much room.
    """

    def __init__(self, target: Path, size: int = RESERVE_BYTES, *, name: str | None = None) -> None:
        self.path = hidden_sibling(target, ".reserve")
        what = name or str(target)
        try:
            fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        except OSError as exc:
            raise OutputError(f"cannot write {what}: {os_error_text(exc)}") from exc
        try:
            try:
                _allocate(fd, size)
            finally:
                os.close(fd)
        except OSError as exc:
            self.path.unlink(missing_ok=True)
            raise OutputError(
                f"cannot write {what}: the disk has less than {size / 1e6:.0f} MB free "
                f"({os_error_text(exc)})"
            ) from exc
        except BaseException:  # a stop signal while it was allocated: nobody holds it
            self.path.unlink(missing_ok=True)
            raise
        self.held = True

    def release(self) -> None:
        """Delete the reserve (its room goes back to the file system); again does nothing."""
        if self.held:
            self.held = False
            self.path.unlink(missing_ok=True)
