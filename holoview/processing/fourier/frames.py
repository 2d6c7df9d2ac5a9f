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
    cases instead of raising, see :class:`holoview.processing.maps.demodulate.Demodulator`.

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


class DamagedFrameError(InputError):
    """A frame damaged in transfer (rows lost: zeroed or constant); ``reason`` says where."""

    def __init__(self, message: str, reason: str) -> None:
        super().__init__(message)
        self.reason = reason


#: A run of constant rows touching the frame's edge counts as damage when the row beside
#: it is brighter than this fraction of the typical row (an abrupt edge, not a dark border).
ABRUPT_EDGE = 0.5


def frame_damage(frame: np.ndarray) -> str | None:
    """Say why a frame looks damaged in transfer, or return None.

    A camera buffer handed on with lost packets has whole rows of one value (zeros,
    as the simulator's ``corrupt_rate`` and many drivers leave them): its spectrum is
    smeared into hundreds of spurious peaks. A run of constant rows inside the frame
    is damage; one at the top or bottom edge is damage only when the row beside it is
    lit like the rest of the frame (a dark border under an aperture fades out, lost
    packets cut off). Partial rows are not detected. Cost: a few microseconds, plus
    one pass over the rows that are constant at their first, middle and last pixel.

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        A checked frame (:func:`check_frame`).

    Returns
    -------
    str or None
        For example ``"rows 341-468 of 1024 are all 0 (lost packets?)"``.
    """
    rows, cols = frame.shape
    first, middle, last = frame[:, 0], frame[:, cols // 2], frame[:, -1]
    maybe = np.flatnonzero((first == middle) & (first == last))
    if maybe.size == 0:
        return None
    block = frame[maybe]
    constant = maybe[(block == block[:, :1]).all(axis=1)]
    if constant.size == 0:
        return None
    breaks = np.flatnonzero(np.diff(constant) != 1)
    starts = np.concatenate(([constant[0]], constant[breaks + 1]))
    stops = np.concatenate((constant[breaks], [constant[-1]])) + 1
    typical: float | None = None
    for start, stop in zip(starts.tolist(), stops.tolist(), strict=True):
        value = frame[start, 0]
        if start > 0 and stop < rows:
            return _damage_text(start, stop, rows, value)
        if start == 0 and stop == rows:
            return None  # a constant frame: check_frame_content's to report
        if typical is None:
            typical = float(np.median(frame[:: max(1, rows // 64)].mean(axis=1)))
        beside = frame[stop] if start == 0 else frame[start - 1]
        if float(beside.mean()) - float(value) > ABRUPT_EDGE * (typical - float(value)):
            return _damage_text(start, stop, rows, value)
    return None


def _damage_text(start: int, stop: int, rows: int, value: object) -> str:
    what = "all 0 (lost packets?)" if value == 0 else f"constant at {value}"
    span = f"row {start}" if stop - start == 1 else f"rows {start}-{stop - 1}"
    return f"{span} of {rows} {'is' if stop - start == 1 else 'are'} {what}"
