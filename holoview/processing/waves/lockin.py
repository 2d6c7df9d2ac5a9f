"""Lock-in maps: amplitude and phase per pixel at a drive frequency and its harmonics.

For each harmonic ``n`` of the drive frequency ``f`` the complex amplitude
``A_n(y, x)`` (m) with ``h ~ mean + sum_n Re(A_n exp(-i n omega t))`` is estimated as
``A_n = 2 sum w (h - mean) exp(+i n omega t) / sum w`` over the frames where the pixel
is finite, on the true frame times (gaps need no closing), with Hann weights ``w`` over
the record's span (their side lobes fall fast, so other frequencies and the other
harmonics leak little into each other; with equal weights the leakage falls only as
``1 / (duration * frequency difference)``). ``|A_n|`` is the amplitude,
``phase = arg A_n`` (``h = |A| cos(n omega t - phase)``, ``t`` the frame times).

The standard errors take the residual (what the mean and the harmonics leave) as
white noise of variance ``s^2`` per pixel: ``var(Re A) = var(Im A) = 2 s^2 sum w^2 /
(sum w)^2``, the error of ``|A|``, and ``error / |A|`` of the phase (rad).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError

__all__ = ["LockIn", "LockInMaps", "push_lockins"]


@dataclass(frozen=True)
class LockInMaps:
    """Amplitude and phase maps at a drive frequency's harmonics.

    Attributes
    ----------
    frequency : float
        Drive frequency, Hz.
    harmonics : tuple of int
        The harmonics ``n`` (1 is the drive itself).
    amplitude : ndarray of complex, shape (H, rows, cols)
        ``A_n``, m (NaN where a pixel has no finite frame).
    stderr : ndarray of float, shape (H, rows, cols)
        Standard error of ``|A_n|`` (and of its real and imaginary parts), m.
    frames : ndarray of int, shape (rows, cols)
        Frames that entered each pixel.
    """

    frequency: float
    harmonics: tuple[int, ...]
    amplitude: NDArray[np.complex128]
    stderr: NDArray[np.float64]
    frames: NDArray[np.int64]

    @property
    def magnitude(self) -> NDArray[np.float64]:
        """``|A_n|``, m."""
        return np.abs(self.amplitude)

    @property
    def phase(self) -> NDArray[np.float64]:
        """``arg A_n``, rad (``h = |A| cos(n omega t - phase)``)."""
        return np.angle(self.amplitude)

    @property
    def phase_stderr(self) -> NDArray[np.float64]:
        """Standard error of the phase, rad."""
        return self.stderr / np.maximum(self.magnitude, np.finfo(float).tiny)


class LockIn:
    """Accumulate lock-in sums over maps pushed in blocks.

    Parameters
    ----------
    shape : (int, int)
        Map shape.
    frequency : float
        Drive frequency, Hz.
    harmonics : sequence of int
        Harmonics to measure (default 1, 2, 3).
    span : (float, float), optional
        First and last time of the record, s (Hann weights over it; default: equal
        weights).
    window : str
        ``"hann"`` (default) or ``"flat"``: equal weights within ``span`` (for a signal
        that fades, such as a ringdown, where Hann's weight on the middle of the record
        would favour the noise).
    """

    def __init__(
        self,
        shape: tuple[int, int],
        frequency: float,
        harmonics: Sequence[int] = (1, 2, 3),
        *,
        span: tuple[float, float] | None = None,
        window: str = "hann",
    ) -> None:
        if window not in ("hann", "flat"):
            raise InputError(f"the lock-in window must be hann or flat, got {window!r}")
        if not (math.isfinite(frequency) and frequency > 0):
            raise InputError(f"the drive frequency must be positive, got {frequency!r} Hz")
        orders = tuple(int(n) for n in harmonics)
        if not orders or any(n < 1 for n in orders):
            raise InputError(f"harmonics must be positive integers, got {harmonics!r}")
        if span is not None and not span[1] > span[0]:
            raise InputError(f"the lock-in span must increase, got {span!r} s")
        self.shape = tuple(int(s) for s in shape)
        self.frequency = float(frequency)
        self.harmonics = orders
        self.span = span
        self.window = window
        rows, cols = self.shape
        n_h = len(orders)
        self._weighted = np.zeros((n_h, rows, cols), np.complex128)  # sum w h e^{+i n w t}
        self._turn = np.zeros((n_h, rows, cols), np.complex128)  # sum w e^{+i n w t}
        self._w = np.zeros((rows, cols))
        self._w2 = np.zeros((rows, cols))
        self._wh = np.zeros((rows, cols))
        self._count = np.zeros((rows, cols), np.int64)
        self._h = np.zeros((rows, cols))
        self._h2 = np.zeros((rows, cols))

    def _weights(self, times: np.ndarray) -> np.ndarray:
        if self.span is None:
            return np.ones_like(times)
        start, stop = self.span
        phase = (times - start) / (stop - start)
        inside = (phase >= 0) & (phase <= 1)
        if self.window == "flat":
            return inside.astype(np.float64)
        return np.where(inside, np.sin(np.pi * phase) ** 2, 0.0)

    def _basis(self, times: np.ndarray) -> np.ndarray:
        """The block's weights and weighted cosines and sines, (N, 1 + 2H)."""
        w = self._weights(times)
        phases = 2.0 * np.pi * self.frequency * np.outer(times, self.harmonics)  # (N, H)
        return np.column_stack([w, w[:, None] * np.cos(phases), w[:, None] * np.sin(phases)])

    def push_block(self, frames: ArrayLike, times: ArrayLike) -> None:
        """Add maps ``(N, rows, cols)`` (m, NaN where untrusted) at ``times`` (s).

        Every sum over the frames of a block is one matrix product (float32) with the
        weights and the weighted cosines and sines, added to float64 totals. Several
        lock-ins fed the same maps share that work through :func:`push_lockins`.
        """
        push_lockins((self,), frames, times)

    def _add(self, sums: np.ndarray, present: np.ndarray, block: _Block) -> None:
        """Add this lock-in's rows of the block's products to its totals."""
        rows, cols = self.shape
        n_h = len(self.harmonics)
        self._wh += sums[0].reshape(rows, cols)
        self._weighted += (sums[1 : 1 + n_h] + 1j * sums[1 + n_h :]).reshape(n_h, rows, cols)
        self._h += block.total
        self._h2 += block.squares
        present = present.reshape(-1, rows, cols)
        self._w += present[0]
        self._turn += present[1 : 1 + n_h] + 1j * present[1 + n_h : 1 + 2 * n_h]
        self._w2 += present[1 + 2 * n_h]
        self._count += np.rint(present[2 + 2 * n_h]).astype(np.int64)

    def result(self) -> LockInMaps:
        """Return the maps (InputError when no pixel had a weighted finite frame)."""
        has = self._w > 0
        if not np.any(has):
            raise InputError("lock-in: no pixel has a finite value in the frames")
        w = np.where(has, self._w, 1.0)
        mean = self._wh / w
        amplitude = np.where(has, 2.0 * (self._weighted - mean * self._turn) / w, np.nan)
        # Residual variance from plain sums: sum (h - mean - fitted)^2 is about
        # sum (h - mean)^2 - n sum |A|^2 / 2 for harmonics orthogonal over the record.
        count = np.maximum(self._count, 1)
        spread = self._h2 - self._h**2 / count
        explained = count * np.sum(np.abs(np.nan_to_num(amplitude)) ** 2, axis=0) / 2.0
        dof = self._count - 1 - 2 * len(self.harmonics)
        variance = np.maximum(spread - explained, 0.0) / np.maximum(dof, 1)
        stderr = np.where(has & (dof > 0), np.sqrt(2.0 * variance * self._w2 / w**2), np.nan)
        return LockInMaps(
            frequency=self.frequency,
            harmonics=self.harmonics,
            amplitude=amplitude,
            stderr=np.broadcast_to(stderr, amplitude.shape).copy(),
            frames=self._count.copy(),
        )


@dataclass(frozen=True)
class _Block:
    """One block of maps as every lock-in fed it uses it (computed once for all).

    ``clean`` is (N, pixels) float32 with untrusted values 0; ``finite`` is None when
    every value is finite, a (pixels,) mask when one mask holds for the whole block,
    else the (N, pixels) mask; ``total`` and ``squares`` are the sums over the frames of
    ``h`` and ``h^2`` per pixel (float64, rows x cols).
    """

    stamps: NDArray[np.float64]
    clean: NDArray[np.float32]
    finite: NDArray[np.bool_] | None
    total: NDArray[np.float64]
    squares: NDArray[np.float64]


def _block(frames: ArrayLike, times: ArrayLike, shape: tuple[int, ...]) -> _Block:
    block = np.asarray(frames, dtype=np.float32)
    stamps = np.asarray(times, dtype=np.float64).ravel()
    if block.ndim != 3 or block.shape[1:] != shape or block.shape[0] != stamps.size:
        raise InputError(
            f"lock-in: maps of shape {block.shape} and {stamps.size} times do not match "
            f"maps of {shape}"
        )
    rows, cols = shape
    flat = block.reshape(stamps.size, rows * cols)
    finite: NDArray[np.bool_] | None = np.isfinite(flat)
    assert finite is not None
    if bool(np.all(finite)):
        clean, finite = flat, None
    else:
        clean = np.where(finite, flat, np.float32(0.0))
        if np.array_equal(finite.min(axis=0), finite.max(axis=0)):  # one mask for the block
            finite = finite[0]
    return _Block(
        stamps=stamps,
        clean=clean,
        finite=finite,
        total=clean.sum(axis=0, dtype=np.float64).reshape(rows, cols),
        squares=np.einsum("np,np->p", clean, clean).reshape(rows, cols).astype(np.float64),
    )


def push_lockins(lockins: Sequence[LockIn], frames: ArrayLike, times: ArrayLike) -> None:
    """Add maps ``(N, rows, cols)`` at ``times`` (s) to every lock-in of ``lockins``.

    The same as each lock-in's :meth:`LockIn.push_block`, with the work on the maps done
    once: their mask, their sums, and one matrix product with every lock-in's weighted
    cosines and sines stacked.
    """
    if not lockins:
        return
    shape = lockins[0].shape
    if any(lockin.shape != shape for lockin in lockins):
        raise InputError("lock-ins fed the same maps must have the same map shape")
    block = _block(frames, times, shape)
    bases = [lockin._basis(block.stamps) for lockin in lockins]
    stacked = np.column_stack(bases)  # (N, sum of 1 + 2H)
    sums = (stacked.astype(np.float32).T @ block.clean).astype(np.float64)
    # per lock-in: its basis, the sum of w^2 and the frame count, over the present frames
    counts = np.column_stack(
        [np.column_stack([basis, basis[:, 0] ** 2, np.ones(block.stamps.size)]) for basis in bases]
    )
    pixels = block.clean.shape[1]
    if block.finite is None:
        present = np.broadcast_to(counts.sum(axis=0)[:, None], (counts.shape[1], pixels))
    elif block.finite.ndim == 1:
        present = np.outer(counts.sum(axis=0), block.finite)
    else:
        present = counts.astype(np.float32).T @ block.finite.astype(np.float32)
    present = np.asarray(present, dtype=np.float64)
    row = col = 0
    for lockin, basis in zip(lockins, bases, strict=True):
        width = basis.shape[1]
        lockin._add(sums[row : row + width], present[col : col + width + 2], block)
        row += width
        col += width + 2
