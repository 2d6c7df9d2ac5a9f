"""Checks that a camera frame can be demodulated, with one-line errors naming the problem."""

from __future__ import annotations

import numpy as np

from holoview.errors import InputError

#: Smallest frame side (pixels) the spectral analysis accepts.
MIN_SIDE = 16


def check_frame(frame: object, *, name: str = "frame") -> np.ndarray:
    """Return ``frame`` as an array after checking its shape and type (never a copy if avoidable).

    Parameters
    ----------
    frame : array_like
        A monochrome image, shape ``(rows, cols)``, integer or real values (counts).
    name : str
        What to call the array in error messages.

    Raises
    ------
    InputError
        For an empty, 1-D, 3-D (colour) or too small array, or a complex or
        non-numeric one.
    """
    array = np.asarray(frame)
    if array.size == 0:
        raise InputError(f"{name} is empty (shape {array.shape})")
    if array.ndim == 3 and array.shape[-1] in (3, 4):
        raise InputError(
            f"{name} has shape {array.shape}: a colour image; holograms must be monochrome 2-D"
        )
    if array.ndim != 2:
        raise InputError(f"{name} must be 2-D (rows, cols), got {array.ndim}-D shape {array.shape}")
    if min(array.shape) < MIN_SIDE:
        raise InputError(f"{name} of shape {array.shape} is too small (each side >= {MIN_SIDE})")
    if array.dtype.kind not in "uif":
        raise InputError(f"{name} has dtype {array.dtype}: expected integer or real pixel values")
    return array


def check_frame_content(frame: np.ndarray, *, name: str = "frame") -> None:
    """Raise if a checked frame holds NaN/inf or no fringes at all (constant, e.g. saturated).

    This reads every pixel; the per-frame path of the demodulator flags these
    cases instead of raising, see :class:`holoview.processing.demodulate.Demodulator`.

    Raises
    ------
    InputError
        Naming the problem: non-finite values, or a constant frame.
    """
    if frame.dtype.kind == "f" and not np.isfinite(frame).all():
        bad = int(np.count_nonzero(~np.isfinite(frame)))
        raise InputError(f"{name} holds {bad} NaN or infinite pixel(s)")
    low, high = frame.min(), frame.max()
    if low == high:
        what = "saturated or blank" if high != 0 else "black"
        raise InputError(f"{name} is constant (every pixel = {high}): {what}, no fringes")
