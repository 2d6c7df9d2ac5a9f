"""Moving maps between the demodulation box grid and the frame grid.

A demodulated map has the box's shape ``(by, bx)``; its pixel ``(p, q)`` sits at the
frame position ``(p rows / by, q cols / bx)`` (frame pixels, origin top-left), so
both grids share pixel ``(0, 0)``.
"""

from __future__ import annotations

import numpy as np

from holoview.errors import InputError


def box_positions(
    box_shape: tuple[int, int], frame_shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Return the frame coordinates ``(y, x)`` (pixels) of a box grid's rows and columns."""
    by, bx = box_shape
    rows, cols = frame_shape
    return np.arange(by) * (rows / by), np.arange(bx) * (cols / bx)


def upsample(box_map: np.ndarray, frame_shape: tuple[int, int]) -> np.ndarray:
    """Interpolate a box-resolution map to the frame grid by Fourier zero-padding.

    Exact for a band-limited map (a demodulated field is band-limited by its
    window). Wrapped phase maps must be unwrapped first, or the complex field
    upsampled and its angle taken; NaN must be filled first.

    Parameters
    ----------
    box_map : ndarray, shape (by, bx)
        Real or complex map at box resolution; not modified.
    frame_shape : tuple of int
        Target shape ``(rows, cols)``, each at least the box's.

    Returns
    -------
    ndarray, shape ``frame_shape``
        complex64 for a complex map, float32 for a real one.
    """
    array = np.asarray(box_map)
    if array.ndim != 2:
        raise InputError(f"map to upsample must be 2-D, got shape {array.shape}")
    by, bx = array.shape
    rows, cols = frame_shape
    if rows < by or cols < bx:
        raise InputError(f"cannot upsample a {array.shape} map to the smaller {frame_shape}")
    if not np.isfinite(array).all():
        raise InputError("map to upsample holds NaN or infinite values; fill them first")
    spectrum = np.fft.fft2(array)
    padded = np.zeros((rows, cols), dtype=np.complex128)
    ky = np.fft.fftfreq(by, 1.0 / by).astype(int)
    kx = np.fft.fftfreq(bx, 1.0 / bx).astype(int)
    padded[np.ix_(ky % rows, kx % cols)] = spectrum
    if by % 2 == 0 and rows > by:
        # split the unpaired Nyquist row between +by/2 and -by/2 so a real map stays real
        half = padded[-by // 2 % rows].copy() / 2
        padded[-by // 2 % rows] = half
        padded[by // 2] = half
    if bx % 2 == 0 and cols > bx:
        half = padded[:, -bx // 2 % cols].copy() / 2
        padded[:, -bx // 2 % cols] = half
        padded[:, bx // 2] = half
    out = np.fft.ifft2(padded) * (rows * cols / (by * bx))
    if np.iscomplexobj(array):
        return out.astype(np.complex64)
    return out.real.astype(np.float32)


def resample_mask(mask: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Resample a boolean mask to another grid by nearest neighbour (same field of view).

    Parameters
    ----------
    mask : ndarray of bool, shape (rows, cols)
        Mask on its grid; not modified.
    shape : tuple of int
        Target shape.

    Returns
    -------
    ndarray of bool, shape ``shape``
    """
    array = np.asarray(mask, dtype=bool)
    if array.ndim != 2:
        raise InputError(f"mask must be 2-D, got shape {array.shape}")
    rows = np.minimum(
        (np.arange(shape[0]) * array.shape[0] / shape[0]).round().astype(int), array.shape[0] - 1
    )
    cols = np.minimum(
        (np.arange(shape[1]) * array.shape[1] / shape[1]).round().astype(int), array.shape[1] - 1
    )
    return array[np.ix_(rows, cols)]
