"""The spatial-frequency spectrum of a frame: planned real FFT and a display spectrum.

Frequencies are in cycles per pixel, ``fx`` along columns and ``fy`` along rows,
with numpy's FFT sign (a field ``exp(+2 pi i (fx x + fy y))`` peaks at ``+f``).
A real frame's spectrum is Hermitian, so only the half ``fx >= 0`` is computed
(``rfft2`` layout, shape ``(rows, cols // 2 + 1)``); the value at ``-f`` is the
complex conjugate of the value at ``+f``.
"""

from __future__ import annotations

import numpy as np

from holoview.processing.fourier.fftplans import DEFAULT_THREADS, rfft2_plan
from holoview.processing.fourier.frames import check_frame


def rfft2(frame: np.ndarray, *, threads: int | None = None) -> np.ndarray:
    """Return the half spectrum of a real frame, computed by a planned pyFFTW transform.

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        Pixel values (counts), any integer or real dtype; not modified.
    threads : int, optional
        FFTW threads; by default
        :data:`~holoview.processing.fourier.fftplans.DEFAULT_THREADS`.

    Returns
    -------
    ndarray of complex64, shape (rows, cols // 2 + 1)
        Unnormalised spectrum (counts), ``rfft2`` layout; a new array.
    """
    array = check_frame(frame)
    plan = rfft2_plan(array.shape, threads=threads or DEFAULT_THREADS)
    np.copyto(plan.input_array, array, casting="unsafe")
    plan()
    return plan.output_array.copy()


def frequencies(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Return the centred frequency axes ``(fy, fx)`` of a frame's full spectrum.

    Parameters
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)``.

    Returns
    -------
    fy, fx : ndarray of float64
        Frequencies (cycles/pixel) of the rows and columns of :func:`display_spectrum`.
    """
    rows, cols = shape
    return (
        np.fft.fftshift(np.fft.fftfreq(rows)),
        np.fft.fftshift(np.fft.fftfreq(cols)),
    )


def log_magnitude(half: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Return ``log(1 + |S|)`` of a half spectrum expanded to the centred full spectrum.

    Parameters
    ----------
    half : ndarray of complex, shape (rows, cols // 2 + 1)
        Half spectrum (``rfft2`` layout) of a real frame of shape ``shape``.
    shape : tuple of int
        The frame shape ``(rows, cols)``.

    Returns
    -------
    ndarray of float32, shape ``shape``
        Log magnitude with zero frequency at ``(rows // 2, cols // 2)`` (``fftshift``).
    """
    rows, cols = shape
    if half.shape != (rows, cols // 2 + 1):
        raise ValueError(f"half spectrum of shape {half.shape} does not match frame {shape}")
    magnitude = np.abs(half).astype(np.float32, copy=False)
    magnitude += np.float32(1.0)
    np.log(magnitude, out=magnitude)  # log(1 + |S|); np.log1p is 6 times slower here
    out = np.empty((rows, cols), dtype=np.float32)
    c, r = cols // 2, rows // 2
    right = cols - c
    # right half, fx >= 0: the half spectrum with its rows rolled to centre fy = 0
    out[r:, c:] = magnitude[: rows - r, :right]
    out[:r, c:] = magnitude[rows - r :, :right]
    # left half, fx < 0: the point mirror, value at (-fy, -fx), rows and columns reversed
    out[: r + 1, :c] = magnitude[r::-1, c:0:-1]
    out[r + 1 :, :c] = magnitude[rows - 1 : r : -1, c:0:-1]
    return out


def display_spectrum(frame: np.ndarray, *, threads: int | None = None) -> np.ndarray:
    """Return the centred log-magnitude spectrum of a frame, for display at up to 30 Hz.

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        Pixel values (counts); not modified.
    threads : int, optional
        FFTW threads; by default
        :data:`~holoview.processing.fourier.fftplans.DEFAULT_THREADS`.

    Returns
    -------
    ndarray of float32, shape (rows, cols)
        ``log(1 + |S(f)|)`` with ``S`` in counts, zero frequency at
        ``(rows // 2, cols // 2)``; the axes are given by :func:`frequencies`.
    """
    array = check_frame(frame)
    plan = rfft2_plan(array.shape, threads=threads or DEFAULT_THREADS)
    np.copyto(plan.input_array, array, casting="unsafe")
    plan()
    return log_magnitude(plan.output_array, array.shape)
