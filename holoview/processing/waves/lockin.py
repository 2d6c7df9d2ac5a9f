"""Lock-in maps: amplitude and phase per pixel at a drive frequency and its harmonics.

For each harmonic ``n`` of the drive frequency ``f`` the complex amplitude
``A_n(y, x)`` (m) of ``h ~ c + sum_n Re(A_n exp(-i n omega t))`` is the weighted least
squares fit, per pixel, of a constant and a cosine and a sine of each harmonic to the
frames where the pixel is finite, on the true frame times: lost frames and untrusted
pixels are left out of the fit, never filled, and cost nothing in accuracy but their
noise. The weights ``w`` are Hann's over the record's span (their side lobes fall fast,
so other frequencies leak little into the fit; with equal weights the leakage falls only
as ``1 / (duration * frequency difference)``). ``|A_n|`` is the amplitude,
``phase = arg A_n`` (``h = |A| cos(n omega t - phase)``, ``t`` the frame times).

The standard errors take the residual (what the constant and the harmonics leave) as
white noise of variance ``s^2`` per pixel, estimated from the unweighted residual of
the frames within the span: the fit's covariance is ``s^2 G^-1 (B' W^2 B) G^-1`` with
``G = B' W B`` (the basis ``B``, the weights ``W``), and a harmonic's error is the root
mean square of those of ``Re A`` and ``Im A`` (equal where the record holds many
periods), that of ``|A|``; the phase's is ``error / |A|`` (rad).

Every sum is accumulated in float64 over blocks of maps: the products of the data with
the weighted basis, and the basis' products with itself over the frames each pixel has
(for all pixels at once, less what each pixel's untrusted values leave out), so memory
is a few maps per parameter, whatever the record's length. The residual, a difference
of such sums, keeps its digits while the maps' offsets stay below about 10^6 times their
noise (1 mm over 1 nm; a float32 map holds 10^7).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError

__all__ = ["LockIn", "LockInMaps", "push_lockins"]

#: Least eigenvalue of a pixel's normal matrix scaled to unit diagonal for a fit: below
#: it the frames a pixel has cannot tell the harmonics apart (a drive at the frame rate's
#: half, or too few frames), and its maps are NaN.
WELL_POSED = 1e-9


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
        ``A_n``, m (NaN where a pixel has too few finite frames for the fit).
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


@dataclass(frozen=True)
class _Lost:
    """A block's untrusted values: the pixels that have any, and where (None: in every
    frame of the block, as a hole or a masked core), ``(N, len(pixels))``, 1 or 0."""

    pixels: NDArray[np.intp]
    frames: NDArray[np.float64] | None


class _Gram:
    """Sums over frames of ``v_t b_t b_t'`` per pixel (upper triangle, ``(Q, pixels)``).

    Held as the sum over every frame (one for all pixels) less, per pixel, the frames
    where it is untrusted (kept only once a pixel has been).
    """

    def __init__(self, size: int, pixels: int) -> None:
        self.rows, self.cols = np.triu_indices(size)
        self.size, self.pixels = size, pixels
        self.every = np.zeros(self.rows.size)
        self.missing: NDArray[np.float64] | None = None

    def pairs(self, basis: np.ndarray) -> np.ndarray:
        """``b_i(t) b_j(t)`` for each frame, ``(N, Q)`` (weighted, a block's products)."""
        return basis[:, self.rows] * basis[:, self.cols]

    def add(self, products: np.ndarray, lost: _Lost | None) -> None:
        """Add a block's products ``(N, Q)`` (``lost``: its untrusted values, if any)."""
        self.every += products.sum(axis=0)
        if lost is None:
            return
        if self.missing is None:
            self.missing = np.zeros((self.rows.size, self.pixels))
        if lost.frames is None:  # untrusted in every frame of the block
            self.missing[:, lost.pixels] += products.sum(axis=0)[:, np.newaxis]
        else:
            self.missing[:, lost.pixels] += products.T @ lost.frames

    def matrices(self, pixels: NDArray[np.intp]) -> NDArray[np.float64]:
        """The symmetric matrices of ``pixels`` and, last, that of a pixel that has had
        every frame: ``(len(pixels) + 1, size, size)``."""
        upper = np.repeat(self.every[:, np.newaxis], pixels.size + 1, axis=1)
        if self.missing is not None:
            upper[:, :-1] -= self.missing[:, pixels]
        out = np.empty((pixels.size + 1, self.size, self.size))
        out[:, self.rows, self.cols] = upper.T
        out[:, self.cols, self.rows] = upper.T
        return out


class LockIn:
    """Accumulate the lock-in fit's sums over maps pushed in blocks.

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
        size = 1 + 2 * len(orders)  # a constant, a cosine and a sine per harmonic
        pixels = self.shape[0] * self.shape[1]
        # the fit's normal matrices (weights w), those of its covariance (w^2) and of the
        # residual (1 within the span), and the data's products with the basis
        self._grams = tuple(_Gram(size, pixels) for _ in range(3))
        self._fitted = np.zeros((size, pixels))  # sum w b h
        self._within = np.zeros((size, pixels))  # sum b h within the span
        self._squares = np.zeros(pixels)  # sum h^2 within the span
        self._count = np.zeros(pixels, np.int64)

    def _weights(self, times: np.ndarray) -> np.ndarray:
        if self.span is None:
            return np.ones_like(times)
        start, stop = self.span
        phase = (times - start) / (stop - start)
        inside = (phase >= 0) & (phase <= 1)
        if self.window == "flat":
            return inside.astype(np.float64)
        return np.where(inside, np.sin(np.pi * phase) ** 2, 0.0)

    def _basis(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The block's basis ``(N, 1 + 2H)`` (1, cosines, sines), weights and span."""
        phases = 2.0 * np.pi * self.frequency * np.outer(times, self.harmonics)  # (N, H)
        basis = np.column_stack([np.ones(times.size), np.cos(phases), np.sin(phases)])
        w = self._weights(times)
        return basis, w, (w > 0).astype(np.float64)

    def push_block(self, frames: ArrayLike, times: ArrayLike) -> None:
        """Add maps ``(N, rows, cols)`` (m, NaN where untrusted) at ``times`` (s).

        Several lock-ins fed the same maps share the work on them through
        :func:`push_lockins`.
        """
        push_lockins((self,), frames, times)

    def result(self) -> LockInMaps:
        """Return the maps (InputError when no pixel has frames enough for the fit)."""
        # the pixels that lost frames have matrices of their own; the others share one
        touched = np.zeros(self._count.size, bool)
        for gram in self._grams:
            if gram.missing is not None:
                touched |= np.any(gram.missing != 0, axis=0)
        lost = np.flatnonzero(touched)
        fit, covariance, residual = (gram.matrices(lost) for gram in self._grams)
        size = fit.shape[1]
        scale = np.sqrt(np.maximum(np.einsum("pii->pi", fit), np.finfo(float).tiny))
        unit = fit / (scale[:, :, np.newaxis] * scale[:, np.newaxis, :])
        dof = residual[:, 0, 0] - size  # frames within the span, less the parameters
        posed = (dof > 0) & (np.linalg.eigvalsh(unit)[:, 0] > WELL_POSED)
        fit[~posed] = np.eye(size)  # solvable; those pixels are NaN below
        index = np.full(self._count.size, lost.size)  # each pixel's matrices
        index[lost] = np.arange(lost.size)
        good = posed[index]
        if not np.any(good):
            raise InputError(
                f"lock-in: no pixel has more than {size} finite frames that tell the "
                f"harmonics apart at {self.frequency:g} Hz"
            )
        inverse = np.linalg.inv(fit)
        # the diagonal of inverse @ covariance @ inverse (the inverse is symmetric)
        spread = np.sum((inverse @ covariance) * inverse, axis=2)[index]
        inverse, residual, dof = inverse[index], residual[index], dof[index]
        beta = (inverse @ self._fitted.T[:, :, np.newaxis])[:, :, 0]  # (pixels, size)
        rss = (
            self._squares
            - 2.0 * np.einsum("pi,ip->p", beta, self._within)
            + np.einsum("pi,pi->p", beta, (residual @ beta[:, :, np.newaxis])[:, :, 0])
        )
        noise = np.maximum(rss, 0.0) / np.maximum(dof, 1.0)
        variance = spread * noise[:, np.newaxis]
        n_h = len(self.harmonics)
        amplitude = beta[:, 1 : 1 + n_h] + 1j * beta[:, 1 + n_h :]
        stderr = np.sqrt(0.5 * (variance[:, 1 : 1 + n_h] + variance[:, 1 + n_h :]))
        amplitude[~good] = np.nan
        stderr[~good] = np.nan
        rows, cols = self.shape
        return LockInMaps(
            frequency=self.frequency,
            harmonics=self.harmonics,
            amplitude=np.ascontiguousarray(amplitude.T).reshape(n_h, rows, cols),
            stderr=np.ascontiguousarray(stderr.T).reshape(n_h, rows, cols),
            frames=self._count.reshape(rows, cols).copy(),
        )


def _block(
    frames: ArrayLike, times: ArrayLike, shape: tuple[int, ...]
) -> tuple[NDArray[np.float64], NDArray[np.float64], _Lost | None]:
    """The block's times, its maps ``(N, pixels)`` in float64 with untrusted values 0,
    and where they are untrusted (None: nowhere)."""
    block = np.asarray(frames)
    stamps = np.asarray(times, dtype=np.float64).ravel()
    if block.ndim != 3 or block.shape[1:] != shape or block.shape[0] != stamps.size:
        raise InputError(
            f"lock-in: maps of shape {block.shape} and {stamps.size} times do not match "
            f"maps of {shape}"
        )
    untrusted = ~np.isfinite(block.reshape(stamps.size, -1))  # in the maps' own type
    pixels = np.flatnonzero(untrusted.any(axis=0))
    # float64 for the sums; a copy where untrusted values are set to 0
    flat = block.reshape(stamps.size, -1).astype(np.float64, copy=pixels.size > 0)
    if not pixels.size:
        return stamps, flat, None
    where = untrusted[:, pixels]
    flat[:, pixels] = np.where(where, 0.0, flat[:, pixels])
    lost = _Lost(pixels, None if where.all() else where.astype(np.float64))
    return stamps, flat, lost


def push_lockins(lockins: Sequence[LockIn], frames: ArrayLike, times: ArrayLike) -> None:
    """Add maps ``(N, rows, cols)`` at ``times`` (s) to every lock-in of ``lockins``.

    The same as each lock-in's :meth:`LockIn.push_block`, with the work on the maps done
    once: their mask, and one matrix product with every lock-in's weighted basis stacked.
    """
    if not lockins:
        return
    shape = lockins[0].shape
    if any(lockin.shape != shape for lockin in lockins):
        raise InputError("lock-ins fed the same maps must have the same map shape")
    stamps, clean, lost = _block(frames, times, shape)
    for lockin in lockins:  # every frame pushed, weighted or not
        lockin._count += stamps.size
        if lost is not None:
            lockin._count[lost.pixels] -= (
                stamps.size if lost.frames is None else lost.frames.sum(axis=0).astype(np.int64)
            )
    # the lock-ins whose span meets the block (a record's segments mostly do not), each
    # with its weighted basis and, where its weights are not all 1, its basis in the span
    active = []
    for lockin in lockins:
        basis, w, inside = lockin._basis(stamps)
        if np.any(inside):
            flat = bool(np.array_equal(w, inside))
            active.append((lockin, basis, w, inside, flat))
    if not active:
        return
    columns = [
        w[:, None] * basis
        if flat
        else np.column_stack([w[:, None] * basis, inside[:, None] * basis])
        for _, basis, w, inside, flat in active
    ]
    sums = np.column_stack(columns).T @ clean
    squares: dict[bytes, np.ndarray] = {}  # sum h^2 over each span's frames, once a span
    row = 0
    for lockin, basis, w, inside, flat in active:
        size = basis.shape[1]
        lockin._fitted += sums[row : row + size]
        lockin._within += sums[row : row + size] if flat else sums[row + size : row + 2 * size]
        key = inside.tobytes()
        if key not in squares:
            span = clean if inside.all() else clean[inside > 0]
            squares[key] = np.einsum("fp,fp->p", span, span)
        lockin._squares += squares[key]
        row += size if flat else 2 * size
        pairs = lockin._grams[0].pairs(basis)  # the three grams share the basis's pairs
        for gram, v in zip(lockin._grams, (w, w * w, inside), strict=True):
            gram.add(v[:, np.newaxis] * pairs, lost)
