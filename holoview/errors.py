"""The exceptions holoview raises for problems a user can fix.

Every subpackage derives its errors from :class:`HoloviewError`, so the command
line can turn any of them into one line on stderr and exit status 2 (3 for an
:class:`OutputError`: an output that could not be written), and the GUI
can show it in the window while the rest keeps running. Programming errors are
not ``HoloviewError`` and keep their tracebacks. :func:`finite_number` is the
number check that the setup (optics) and camera settings (acquire) share;
:func:`os_error_text` turns a failed write (also HDF5's, which h5py raises as
``RuntimeError`` with the C library's whole message) into a few plain words.
"""

import errno
import math
import os
import re
from typing import Any


class HoloviewError(Exception):
    """A problem the user can fix: bad input, a missing device, a broken file."""


class InputError(HoloviewError, ValueError):
    """An argument, frame or file content is invalid; the message names it."""


class OutputError(HoloviewError):
    """Writing an output failed: a full disk, an I/O error, a closed standard output.

    What was written before stays: earlier results are not replaced, and a recording
    keeps every frame it had written. The command line exits with status 3.
    """


#: Plain words for the errors a write meets most often.
_ERRNO_TEXT = {
    errno.ENOSPC: "the disk is full",
    errno.EDQUOT: "the disk quota is exceeded",
    errno.EIO: "an I/O error (a failing disk or a lost network drive?)",
    errno.EROFS: "the file system is read-only",
    errno.EACCES: "permission denied",
    errno.EPIPE: "the reader closed the pipe",
    errno.EFBIG: "the file is too large for its file system",
}


def os_error_text(exc: BaseException) -> str:
    """Return a short description of a failed file operation, without HDF5's stack.

    Parameters
    ----------
    exc : BaseException
        An ``OSError`` (its ``errno``), or an h5py error whose message carries
        ``errno = N`` from the HDF5 library.

    Examples
    --------
    >>> os_error_text(OSError(28, "No space left on device"))
    'the disk is full (No space left on device)'
    """
    code = getattr(exc, "errno", None)
    if not isinstance(code, int):
        found = re.search(r"errno = (\d+)", str(exc))
        code = int(found.group(1)) if found else None
    if code is not None:
        words = os.strerror(code)
        known = _ERRNO_TEXT.get(code)
        return f"{known} ({words})" if known else words
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return first if len(first) <= 160 else first[:157] + "..."


def finite_number(name: str, value: Any) -> float:
    """Return ``value`` as a float, or raise :class:`InputError` naming ``name``.

    Parameters
    ----------
    name : str
        The parameter, as the user knows it (``"exposure_s"``, ``"delta_H"``).
    value : object
        What the user gave: a number, or something ``float()`` accepts.

    Raises
    ------
    InputError
        When ``value`` is not a number, or is NaN or infinite.
    """
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(number):
        raise InputError(f"{name} must be finite, got {value!r}")
    return number
