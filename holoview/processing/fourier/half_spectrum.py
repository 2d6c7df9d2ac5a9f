"""A frame's half spectrum, transformed only in the columns that are read.

A real 2-D FFT is two passes: a real FFT of every row, then an FFT along every
column of the result. The demodulator reads the spectrum in a few boxes and at the
noise-floor bins only, so :class:`HalfSpectrum` runs the first pass whole and the
second only over the blocks of :data:`~holoview.processing.fourier.fftplans.COLUMN_ALIGN`
columns where its windows are not zero (one plan serves every block of a frame shape:
measured at 1024 x 1024, as fast as a plan per run of blocks, and no new peak waits for
FFTW to plan a new width), and over the floor bins' columns gathered apart. One carrier's
window at 1024 x 1024 covers about half of the 513 columns: the frame's FFT costs about
three quarters of a whole one. The bins it gives there are those of the whole 2-D FFT, up
to float32 rounding (the same transforms, in another order); elsewhere they hold the row
pass alone, which a box multiplies by its window's zeros.

The first pass runs on :data:`ROW_CHUNK` rows at a time, each converted to float32 just
before. The frame's mean comes from the row pass (the sum of every row's zero
frequency), so it does not depend on which columns are transformed.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import pyfftw

from holoview.processing.fourier.fftplans import (
    COLUMN_ALIGN,
    DEFAULT_THREADS,
    column_fft_plan,
    rfft_rows_plan,
)

__all__ = ["HalfSpectrum", "column_runs"]

#: Rows converted to float32 and transformed at a time (a multiple of 8, so that every
#: chunk of the half spectrum is aligned as the first). Measured at 1024 x 1024 (AVX2, one
#: thread): the copy and the row pass in chunks of 128 rows took 1.6 ms, the whole frame
#: at once 2.1 ms (its 4 MB float32 copy is out of cache when transformed).
ROW_CHUNK = 128


def column_runs(half_cols: int, columns: Iterable[np.ndarray]) -> tuple[tuple[int, int], ...]:
    """Return the runs ``(start, stop)`` of blocks of columns that hold every column given.

    Parameters
    ----------
    half_cols : int
        Columns of the half spectrum, ``cols // 2 + 1``.
    columns : iterable of ndarray of int
        Column indices (each in ``[0, half_cols)``) that must be transformed.

    Returns
    -------
    tuple of (int, int)
        Disjoint, ordered runs; each starts at a multiple of
        :data:`~holoview.processing.fourier.fftplans.COLUMN_ALIGN` and ends at one or at
        ``half_cols``.
    """
    blocks = -(-half_cols // COLUMN_ALIGN)
    used = np.zeros(blocks, dtype=bool)
    for c in columns:
        used[np.asarray(c, dtype=np.intp) // COLUMN_ALIGN] = True
    runs = []
    b = 0
    while b < blocks:
        if not used[b]:
            b += 1
            continue
        start = b
        while b < blocks and used[b]:
            b += 1
        runs.append((start * COLUMN_ALIGN, min(b * COLUMN_ALIGN, half_cols)))
    return tuple(runs)


class HalfSpectrum:
    """The real FFT of frames of one shape, complete in chosen columns and at floor bins.

    Parameters
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)``, pixels.
    columns : iterable of ndarray of int
        The half spectrum's columns that must be exact (where each box's window is not zero).
    floor_rows, floor_cols : slice
        The noise-floor bins: every ``(row, col)`` of this grid is sampled.
    threads : int, optional
        FFTW threads.

    Notes
    -----
    Plans come from :mod:`~holoview.processing.fourier.fftplans` (one per calling
    thread); the floor's buffer is this object's: use it from one thread at a time.
    """

    def __init__(
        self,
        shape: tuple[int, int],
        columns: Iterable[np.ndarray],
        floor_rows: slice,
        floor_cols: slice,
        *,
        threads: int | None = None,
    ) -> None:
        self.shape = (int(shape[0]), int(shape[1]))
        self.half_shape = (self.shape[0], self.shape[1] // 2 + 1)
        self.threads = int(threads) if threads else DEFAULT_THREADS
        #: the runs of columns transformed along the rows (start, stop)
        self.runs = column_runs(self.half_shape[1], columns)
        self._floor_rows = floor_rows
        self._floor_cols = floor_cols
        count = len(range(*floor_cols.indices(self.half_shape[1])))
        self._floor = pyfftw.empty_aligned((self.shape[0], count), "complex64")
        self._half = pyfftw.empty_aligned(self.half_shape, "complex64")
        rows = self.shape[0]
        #: the first pass's chunks: rows of the frame and the half spectrum's view of them
        self._chunks = [
            (slice(start, min(start + ROW_CHUNK, rows)), self._half[start : start + ROW_CHUNK])
            for start in range(0, rows, ROW_CHUNK)
        ]
        #: the second pass's blocks of columns (views of the half spectrum), each run cut
        #: into blocks of COLUMN_ALIGN: one plan serves every block of the shape (only the
        #: last block, at the Nyquist column, may be narrower), so new peaks never wait for
        #: FFTW to plan a new width (half a second each, measured)
        self._blocks = [
            self._half[:, block : min(block + COLUMN_ALIGN, stop)]
            for start, stop in self.runs
            for block in range(start, stop, COLUMN_ALIGN)
        ]

    def transform(self, frame: np.ndarray) -> tuple[np.ndarray | None, float, np.ndarray]:
        """Transform a frame (not modified).

        Returns
        -------
        half : ndarray of complex64, shape ``(rows, cols // 2 + 1)``, or None
            The half spectrum (unnormalised, numpy's sign), exact in :attr:`runs` only
            (elsewhere it holds the row pass); this object's buffer, overwritten by the
            next call. None for a frame holding NaN or infinity.
        mean : float
            The frame's mean (counts); NaN when ``half`` is None.
        floor : ndarray of complex64
            The spectrum at the floor grid (rows-major), a new array; empty when
            ``half`` is None.
        """
        half = self._half
        self._rows(frame)
        total = float(half[:, 0].real.sum(dtype=np.float64))
        if not np.isfinite(total):
            return None, float("nan"), np.empty(0, dtype=np.complex64)
        samples = self._floor_samples()
        self._columns()
        return half, total / (self.shape[0] * self.shape[1]), samples

    def _rows(self, frame: np.ndarray) -> None:
        """The first pass: every row's real FFT, converted to float32 a chunk at a time."""
        plans: dict[int, pyfftw.FFTW] = {}  # by chunk height: each looked up once a frame
        for rows, out in self._chunks:
            # a few rows at a time: the float32 copy is still in cache when transformed
            height = out.shape[0]
            plan = plans.get(height)
            if plan is None:
                plan = plans[height] = rfft_rows_plan((height, self.shape[1]), threads=self.threads)
            np.copyto(plan.input_array, frame[rows], casting="unsafe")
            plan.update_arrays(plan.input_array, out)
            plan.execute()

    def _floor_samples(self) -> np.ndarray:
        """The spectrum at the floor grid (a new array), its columns transformed apart."""
        floor = self._floor
        if floor.size:
            np.copyto(floor, self._half[:, self._floor_cols])
            plan = column_fft_plan(floor.shape, floor.shape[1], threads=self.threads)
            plan.update_arrays(floor, floor)
            plan.execute()
        return np.array(floor[self._floor_rows]).reshape(-1)  # a copy, kept by callers

    def _columns(self) -> None:
        """The second pass, in place, over the runs of columns the boxes read."""
        plans: dict[int, pyfftw.FFTW] = {}  # by width: each looked up once a frame
        for columns in self._blocks:
            width = columns.shape[1]
            plan = plans.get(width)
            if plan is None:
                plan = plans[width] = column_fft_plan(self.half_shape, width, threads=self.threads)
            plan.update_arrays(columns, columns)
            plan.execute()
