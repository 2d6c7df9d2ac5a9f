"""The exceptions holoview raises for problems a user can fix.

Every subpackage derives its errors from :class:`HoloviewError`, so the command
line can turn any of them into one line on stderr and exit status 2, and the GUI
can show it in the window while the rest keeps running. Programming errors are
not ``HoloviewError`` and keep their tracebacks. :func:`finite_number` is the
number check that the setup (optics) and camera settings (acquire) share.
"""

import math
from typing import Any


class HoloviewError(Exception):
    """A problem the user can fix: bad input, a missing device, a broken file."""


class InputError(HoloviewError, ValueError):
    """An argument, frame or file content is invalid; the message names it."""


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
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(number):
        raise InputError(f"{name} must be finite, got {value!r}")
    return number
