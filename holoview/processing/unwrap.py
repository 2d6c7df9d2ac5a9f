"""Phase unwrapping in space and time, and masks of pixels worth unwrapping.

Spatial unwrapping is Herraez et al. 2002 (Appl. Opt. 41, 7437), as implemented
by :func:`skimage.restoration.unwrap_phase`; it costs 20-40 times a whole
demodulation, so :func:`unwrap_spatial` first checks cheaply whether the map has
any wrap at all and returns it unchanged when not.
"""

from __future__ import annotations

import warnings

import numpy as np
from skimage.restoration import unwrap_phase

from holoview.errors import InputError

TWO_PI = 2.0 * np.pi


def wrap(phase: np.ndarray | float) -> np.ndarray:
    """Wrap phases (rad) into [-pi, pi)."""
    return (np.asarray(phase) + np.pi) % TWO_PI - np.pi


def has_wraps(phase: np.ndarray, mask: np.ndarray | None = None) -> bool:
    """Return whether two neighbouring trusted pixels differ by more than pi (rad).

    Parameters
    ----------
    phase : ndarray, shape (rows, cols)
        Wrapped phase map (rad); not modified.
    mask : ndarray of bool, optional
        Trusted pixels; a pair counts only when both are trusted.
    """
    p = np.asarray(phase)
    jump_x = np.abs(p[:, 1:] - p[:, :-1]) > np.pi
    jump_y = np.abs(p[1:, :] - p[:-1, :]) > np.pi
    if mask is not None:
        m = np.asarray(mask, dtype=bool)
        jump_x &= m[:, 1:] & m[:, :-1]
        jump_y &= m[1:, :] & m[:-1, :]
    return bool(jump_x.any() or jump_y.any())


def unwrap_spatial(phase: np.ndarray, mask: np.ndarray | None = None) -> tuple[np.ndarray, bool]:
    """Unwrap a phase map in space when it has wraps (Herraez et al. 2002).

    Parameters
    ----------
    phase : ndarray, shape (rows, cols)
        Wrapped phase (rad); not modified.
    mask : ndarray of bool, optional
        Trusted pixels; the others are left as they are in the result.

    Returns
    -------
    unwrapped : ndarray of float32
        The unwrapped map (a new array), or ``phase`` itself when nothing was wrapped.
        The global offset is a multiple of 2 pi chosen by the algorithm.
    changed : bool
        Whether unwrapping ran.
    """
    p = np.asarray(phase)
    if p.ndim != 2:
        raise InputError(f"phase map must be 2-D, got shape {p.shape}")
    if not has_wraps(p, mask):
        return p, False
    source = p.astype(np.float64)
    if mask is None:
        return unwrap_phase(source).astype(np.float32), True
    m = np.asarray(mask, dtype=bool)
    if not m.any():
        return p, False
    with warnings.catch_warnings():
        # separate trusted islands are unwrapped independently; skimage says so in a warning
        warnings.simplefilter("ignore", UserWarning)
        result = unwrap_phase(np.ma.masked_array(source, mask=~m))
    return np.where(m, result.filled(0.0), p).astype(np.float32), True


def unwrap_temporal(phases: np.ndarray, *, axis: int = 0) -> np.ndarray:
    """Unwrap a series of phases (rad) in time: steps beyond pi become steps below it.

    Parameters
    ----------
    phases : ndarray
        Phases in time order along ``axis`` (e.g. the mean phase per frame); not modified.

    Returns
    -------
    ndarray of float64
        Continuous phases, equal to the input at the first sample.
    """
    return np.unwrap(np.asarray(phases, dtype=np.float64), axis=axis)


def amplitude_mask(field: np.ndarray, threshold: float) -> np.ndarray:
    """Return the pixels whose field amplitude reaches ``threshold`` (unit of the field)."""
    return np.abs(np.asarray(field)) >= threshold


def aperture_mask(
    shape: tuple[int, int],
    *,
    center: tuple[float, float] | None = None,
    radius: float | None = None,
) -> np.ndarray:
    """Return a disc-shaped aperture mask.

    Parameters
    ----------
    shape : tuple of int
        Mask shape ``(rows, cols)``.
    center : tuple of float, optional
        Disc centre ``(row, col)`` in pixels; the frame centre by default.
    radius : float, optional
        Disc radius in pixels; half the shorter side by default.

    Returns
    -------
    ndarray of bool
    """
    rows, cols = shape
    cy, cx = center if center is not None else ((rows - 1) / 2, (cols - 1) / 2)
    r = radius if radius is not None else min(rows, cols) / 2
    if r <= 0:
        raise InputError(f"aperture radius must be > 0 pixels, got {r}")
    y, x = np.ogrid[:rows, :cols]
    return (y - cy) ** 2 + (x - cx) ** 2 <= r * r
