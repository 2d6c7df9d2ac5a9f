"""What a path names when it is not a file to read: a FIFO, a broken link, a device.

Inputs are opened only when they are regular files (or folders, where a folder is an
input): opening a FIFO for reading waits for a writer, forever if none comes, and a
device or socket is no recording either. A broken symbolic link is said as such
instead of "no such file", and an entry of a folder or glob that is one of these is
named, never dropped in silence. :func:`special_file` says what is there;
:func:`check_regular_file` refuses it; :func:`read_regular_file` reads a small file
(an experiment) without ever blocking on a FIFO swapped in meanwhile.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from holoview.errors import InputError

__all__ = ["check_regular_file", "read_regular_file", "special_file"]


def _kind(mode: int) -> str:
    kinds = (
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
    )
    return next((name for test, name in kinds if test(mode)), "a special file")


def special_file(path: Path, *, folder_ok: bool = True) -> str | None:
    """Say what ``path`` is when it is neither a regular file nor (with ``folder_ok``) a folder.

    Returns
    -------
    str or None
        ``"a FIFO (named pipe)"``, ``"a broken symbolic link to TARGET"``, ``"a
        socket"``, ...; None for a regular file, a folder (with ``folder_ok``), or a path
        where nothing is (the caller says "no such file").
    """
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        if path.is_symlink():
            try:
                target = os.readlink(path)
            except OSError:
                target = "?"
            return f"a broken symbolic link to {target}"
        return None
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"
    if stat.S_ISREG(mode) or (folder_ok and stat.S_ISDIR(mode)):
        return None
    return _kind(mode)


def check_regular_file(path: Path, what: str) -> None:
    """Refuse ``path`` when something other than a regular file is there (nothing: fine).

    Raises
    ------
    InputError
        ``path`` is a FIFO, a socket, a device, a folder or a broken link (``what``
        names it in the line).
    """
    problem = special_file(path, folder_ok=False)
    if problem is not None:
        raise InputError(f"{what}: {problem}, not a regular file")


def read_regular_file(path: Path, what: str) -> bytes:
    """Return the bytes of the regular file ``path``, opened without blocking on a FIFO.

    Raises
    ------
    InputError
        The file cannot be opened or read, or is not a regular file (``what`` names it).
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        check_regular_file(path, what)  # a broken link is said as such
        raise InputError(f"{what}: cannot be read ({exc.strerror or exc})") from exc
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise InputError(f"{what}: {_kind(mode)}, not a regular file")
        with os.fdopen(fd, "rb", closefd=False) as f:
            return f.read()
    except OSError as exc:
        raise InputError(f"{what}: cannot be read ({exc.strerror or exc})") from exc
    finally:
        os.close(fd)
