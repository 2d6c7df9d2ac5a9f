"""Azimuthal decomposition around a centre: ``h = sum_m h_m(r, t) exp(i m theta)``.

Map coordinates: ``x = col dx``, ``y = row dy`` (m, from the centre of the first
pixel), ``theta = atan2(y - y0, x - x0)`` (with rows growing downwards, ``theta``
grows clockwise on the screen). A :class:`PolarGrid` samples a map on rings of radius
``r_min .. r_max`` one pixel apart, each with enough angles that neighbouring samples
are at most a pixel apart (a power of two: an inner ring takes fewer than an outer one),
by Keys' cubic convolution (third-order accurate: a wave of ``k dx = 1`` loses far less
of its amplitude than under bilinear interpolation; one sparse matrix product per map);
the Fourier sum over the angle gives ``h_m(r)`` for ``|m| <= m_max``. A ring touching
an untrusted (NaN) pixel in a frame is NaN in that frame. The rings must lie inside the
map.

:class:`AzimuthalAccumulator` takes maps one at a time and gives

- the (m, f) spectrum (Welch over segments that span no gap, as the omega-k
  spectrum): the power of ``exp(i (m theta - omega t))`` per Hz, mean over the
  annulus weighted by ``r`` (summed over ``m`` and ``f`` it is the mean square height
  there); rings NaN anywhere in a segment are left out of it;
- radial profiles at chosen frequencies (lock-in on the true times, Hann-weighted over
  the record: no gap needs closing): ``A_m(r, f)`` with ``h = Re(sum A_m(r)
  exp(i (m theta - omega t)))``;
- the series ``h_m(r, t)`` of chosen ``m`` (for a ringdown fit).

The centre itself is found by :mod:`.centre`.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse

from holoview.errors import InputError
from holoview.processing.waves.clock import GAP_TOLERANCE
from holoview.processing.waves.omega_k import SEGMENT, hann, pixel_pair

logger = logging.getLogger(__name__)

__all__ = ["AzimuthalAccumulator", "MFSpectrum", "PolarGrid", "polar_grid", "ring_angles"]

#: Frames whose ring samples are made at once (a few MB: reused, not mapped afresh).
MODES_CHUNK = 16

#: The bins of a ring's (m, f) power whose median is its noise near a frequency
#: (:meth:`AzimuthalAccumulator.profile_noise`): from the first to the second either side.
FLOOR_BINS = (3, 8)


def _keys(t: np.ndarray) -> np.ndarray:
    """Keys' cubic convolution weights (a = -0.5) of the samples at -1, 0, 1, 2 from ``t``."""
    t = t[:, np.newaxis]
    d = np.abs(np.array([-1.0, 0.0, 1.0, 2.0]) - t)
    near = 1.5 * d**3 - 2.5 * d**2 + 1.0
    far = -0.5 * d**3 + 2.5 * d**2 - 4.0 * d + 2.0
    return np.where(d <= 1.0, near, np.where(d < 2.0, far, 0.0))


@dataclass(frozen=True)
class PolarGrid:
    """Rings around a centre and the sparse matrix that samples a map on them.

    Attributes
    ----------
    centre : (float, float)
        ``(x0, y0)``, m, map coordinates.
    radii : ndarray of float, shape (R,)
        Ring radii, m.
    n_theta : ndarray of int, shape (R,)
        Angles on each ring: a power of two, at most a pixel apart (and at least
        ``2 m_max + 2``), so rings of the same count follow one another.
    m_max : int
        Largest ``|m|`` kept.
    shape : (int, int)
        The map's shape.
    matrix : scipy.sparse.csr_matrix, shape (sum of n_theta, rows cols)
        Interpolation weights (16 per sample), float32, ring after ring.
    dft : tuple of ndarray of float32, shape (n, 2 (m_max + 1))
        For each count ``n`` of angles, from the inner rings out: ``cos(m theta) / n``
        then ``-sin(m theta) / n``, ``m = 0 .. m_max``.
    """

    centre: tuple[float, float]
    radii: NDArray[np.float64]
    n_theta: NDArray[np.int64]
    m_max: int
    shape: tuple[int, int]
    matrix: sparse.csr_matrix
    dft: tuple[NDArray[np.float32], ...]

    @property
    def m(self) -> NDArray[np.int64]:
        """Azimuthal numbers kept, ``-m_max .. m_max``."""
        return np.arange(-self.m_max, self.m_max + 1)

    def modes(self, frames: ArrayLike, *, workers: int = 1) -> NDArray[np.complex128]:
        """Return ``h_m(r)`` (m) of maps (rows, cols) or (N, rows, cols): (R, M) or (N, R, M).

        The samples on the rings (one sparse product) times the cosines and sines of
        ``m = 0 .. m_max`` (one matrix product); ``h_-m`` is the conjugate of ``h_m``
        (the maps are real). With ``workers`` above 1 the chunks of
        :data:`MODES_CHUNK` frames are shared among as many threads (the products
        release the GIL; each chunk's numbers are the same).
        """
        block = np.asarray(frames, dtype=np.float32)
        single = block.ndim == 2
        block = block.reshape(-1, self.shape[0] * self.shape[1])
        n = block.shape[0]
        parts = np.empty((self.radii.size, 2 * (self.m_max + 1), n), np.float32)

        def chunk(a: int) -> None:  # the samples of a few frames at a time
            b = min(a + MODES_CHUNK, n)
            samples = np.asarray(self.matrix @ block[a:b].T)
            ring = sample = 0
            for dft in self.dft:  # the rings of each count of angles
                angles = dft.shape[0]
                count = int(np.count_nonzero(self.n_theta == angles))
                rings = samples[sample : sample + count * angles].reshape(count, angles, b - a)
                parts[ring : ring + count, :, a:b] = np.matmul(dft.T, rings)
                ring, sample = ring + count, sample + count * angles

        starts = range(0, n, MODES_CHUNK)
        if workers > 1 and len(starts) > 1:
            with ThreadPoolExecutor(max_workers=min(workers, len(starts))) as pool:
                list(pool.map(chunk, starts))
        else:
            for a in starts:
                chunk(a)
        half = self.m_max + 1
        positive = (parts[:, :half] + 1j * parts[:, half:]).transpose(2, 0, 1)  # (N, R, M+)
        out = np.concatenate([positive[:, :, :0:-1].conj(), positive], axis=2)
        out = out.astype(np.complex128)
        return out[0] if single else out


def ring_angles(radii: ArrayLike, spacing: float, *, fewest: int) -> NDArray[np.int64]:
    """Angles on each ring of ``radii``: the power of two that puts neighbouring samples
    at most ``spacing`` apart (the radii's unit), and at least ``fewest``.

    Examples
    --------
    >>> ring_angles([1.0, 3.0, 10.0], 1.0, fewest=8)
    array([ 8, 32, 64])
    """
    return np.array(
        [
            max(fewest, 1 << math.ceil(math.log2(max(2.0 * math.pi * r / spacing, 1.0))))
            for r in np.asarray(radii, dtype=np.float64)
        ],
        dtype=np.int64,
    )


def polar_grid(
    shape: tuple[int, int],
    pixel_size: float | ArrayLike,
    centre: tuple[float, float],
    *,
    r_min: float | None = None,
    r_max: float | None = None,
    m_max: int = 8,
) -> PolarGrid:
    """Return rings one pixel apart around ``centre`` (m) inside a map of ``shape``.

    Parameters
    ----------
    shape : (int, int)
        Map shape (rows, cols).
    pixel_size : float or (float, float)
        m (one value or (dy, dx)).
    centre : (float, float)
        ``(x0, y0)``, m, map coordinates.
    r_min, r_max : float, optional
        Ring radii, m (defaults: two pixels; the distance to the nearest edge less two
        pixels).
    m_max : int
        Largest ``|m|`` kept.

    Raises
    ------
    InputError
        A centre outside the map, ``r_max`` beyond the nearest edge, or fewer than
        four rings.
    """
    rows, cols = shape
    dy, dx = pixel_pair(pixel_size)
    x0, y0 = (float(c) for c in centre)
    width, height = (cols - 1) * dx, (rows - 1) * dy
    if not (math.isfinite(x0) and math.isfinite(y0) and 0 <= x0 <= width and 0 <= y0 <= height):
        raise InputError(
            f"the centre ({x0 * 1e3:.3g}, {y0 * 1e3:.3g}) mm is outside the maps "
            f"(0 to {width * 1e3:.3g} mm along x, 0 to {height * 1e3:.3g} mm along y)"
        )
    step = min(dx, dy)
    room = min(x0, width - x0, y0, height - y0) - 2.0 * step
    low = 2.0 * step if r_min is None else float(r_min)
    high = room if r_max is None else float(r_max)
    if high > room + 1e-9 * step:
        raise InputError(
            f"rings up to {high * 1e3:.3g} mm around ({x0 * 1e3:.3g}, {y0 * 1e3:.3g}) mm leave "
            f"the maps (the nearest edge is {(room + step) * 1e3:.3g} mm away)"
        )
    if not (low >= 0 and high >= low + 3 * step):
        raise InputError(
            f"no room for rings from {low * 1e3:.3g} to {high * 1e3:.3g} mm around "
            f"({x0 * 1e3:.3g}, {y0 * 1e3:.3g}) mm (at least four, a pixel apart)"
        )
    if m_max < 0:
        raise InputError(f"m_max must be >= 0, got {m_max}")
    radii = np.arange(low, high + 1e-9 * step, step)
    n_theta = ring_angles(radii, step, fewest=max(8, 2 * m_max + 2))
    theta = [2.0 * np.pi * np.arange(n) / n for n in n_theta]
    col = np.concatenate([(x0 + r * np.cos(t)) / dx for r, t in zip(radii, theta, strict=True)])
    row = np.concatenate([(y0 + r * np.sin(t)) / dy for r, t in zip(radii, theta, strict=True)])
    c0, r0 = np.floor(col).astype(np.int64), np.floor(row).astype(np.int64)
    wc, wr = _keys(col - c0), _keys(row - r0)  # (S, 4) weights of offsets -1, 0, 1, 2
    offsets = np.arange(-1, 3)
    rows_of = np.clip(r0[:, None] + offsets, 0, rows - 1)  # (S, 4)
    cols_of = np.clip(c0[:, None] + offsets, 0, cols - 1)
    pixels = (rows_of[:, :, None] * cols + cols_of[:, None, :]).reshape(-1)
    weights = (wr[:, :, None] * wc[:, None, :]).reshape(-1)
    sample = np.arange(col.size).repeat(16)
    matrix = sparse.csr_matrix(
        (weights.astype(np.float32), (sample, pixels)), shape=(col.size, rows * cols)
    )
    dft = []
    for n in np.unique(n_theta):
        turns = np.outer(2.0 * np.pi * np.arange(n) / n, np.arange(m_max + 1))
        dft.append((np.concatenate([np.cos(turns), -np.sin(turns)], axis=1) / n).astype(np.float32))
    return PolarGrid((x0, y0), radii, n_theta, int(m_max), (rows, cols), matrix, tuple(dft))


@dataclass(frozen=True)
class MFSpectrum:
    """Power of ``exp(i (m theta - omega t))`` against ``m`` and ``f`` around a centre.

    Attributes
    ----------
    m : ndarray of int, shape (M,)
    frequency : ndarray of float, shape (F,)
        Hz, ``f >= 0`` (``exp(-i omega t)``).
    power : ndarray of float, shape (M, F)
        One-sided density, m^2/Hz, mean over the rings weighted by ``r``.
    radii : ndarray of float
        The rings, m.
    segments : int
        Segments averaged.
    """

    m: NDArray[np.int64]
    frequency: NDArray[np.float64]
    power: NDArray[np.float64]
    radii: NDArray[np.float64]
    segments: int

    def strongest(self, count: int, *, f_min: float = 0.0) -> list[tuple[int, float]]:
        """Return up to ``count`` ``(m, f)`` local maxima of the power, strongest first.

        ``f`` is refined between bins by the vertex of a parabola on the log-power.
        """
        p = self.power
        order = np.argsort(p, axis=None)[::-1]
        found: list[tuple[int, float]] = []
        for flat in order:
            i, j = np.unravel_index(flat, p.shape)
            if self.frequency[j] <= f_min or j == 0 or j >= p.shape[1] - 1:
                continue
            block = p[max(i - 1, 0) : i + 2, j - 1 : j + 2]
            if p[i, j] < block.max():
                continue
            logs = np.log(np.maximum(p[i, j - 1 : j + 2], np.finfo(float).tiny))
            curvature = logs[0] - 2 * logs[1] + logs[2]
            shift = 0.5 * (logs[0] - logs[2]) / curvature if curvature < 0 else 0.0
            df = self.frequency[1] - self.frequency[0]
            found.append((int(self.m[i]), float(self.frequency[j] + shift * df)))
            if len(found) >= count:
                break
        return found


class AzimuthalAccumulator:
    """The azimuthal decomposition of maps pushed one at a time (module docstring).

    Parameters
    ----------
    grid : PolarGrid
    interval : float
        Nominal time between frames, s (gaps as in :mod:`~holoview.processing.waves.clock`).
    segment : int
        Frames per segment of the (m, f) spectrum.
    lock_in : sequence of float
        Frequencies (Hz) of the radial profiles.
    span : (float, float), optional
        First and last time of the record, s: the lock-in's Hann weights run over it
        (without it, equal weights).
    series : sequence of int
        Azimuthal numbers whose ``h_m(r, t)`` are kept, every frame.
    workers : int
        Threads sampling the rings (:meth:`PolarGrid.modes`), default 1.
    spectrum : bool
        Make the (m, f) spectrum (default). Without it only the lock-ins and the series
        are kept: a pass for the lock-ins at more frequencies costs less.
    """

    def __init__(
        self,
        grid: PolarGrid,
        interval: float,
        *,
        segment: int = SEGMENT,
        lock_in: Sequence[float] = (),
        span: tuple[float, float] | None = None,
        series: Sequence[int] = (),
        workers: int = 1,
        spectrum: bool = True,
    ) -> None:
        if not (math.isfinite(interval) and interval > 0):
            raise InputError(f"the frame interval must be positive, got {interval!r} s")
        if segment < 8:
            raise InputError(f"a segment needs at least 8 frames, got {segment}")
        for m in series:
            if abs(m) > grid.m_max:
                raise InputError(f"m = {m} is beyond the decomposition's |m| <= {grid.m_max}")
        self.grid = grid
        self.workers = max(1, int(workers))
        self.makes_spectrum = bool(spectrum)
        self.interval = float(interval)
        self.segment = int(segment)
        self.hop = self.segment // 2
        n_r, n_m = grid.radii.size, grid.m.size
        self._ring = np.empty((self.segment, n_r, n_m), np.complex128)
        self._next = 0
        self._run = 0
        self._last_time: float | None = None
        self._sum = np.zeros((n_m, self.segment // 2 + 1))
        self._ring_sum = np.zeros((n_m, n_r, self.segment // 2 + 1))  # per ring, for noise
        self._ring_segments = np.zeros(n_r)
        self.segments = 0
        self.frames = 0
        self.frequencies = np.asarray(lock_in, dtype=np.float64)
        self.span = span
        self._lock = np.zeros((self.frequencies.size, n_r, n_m), np.complex128)
        self._lock_weight = np.zeros(n_r)
        self._lock_weight_squares = np.zeros(n_r)
        self.series_m = tuple(int(m) for m in series)
        self._series: list[np.ndarray] = []
        self._times: list[float] = []
        self._taper = hann(self.segment)

    def push_block(self, frames: ArrayLike, times: ArrayLike) -> None:
        """Add maps ``(N, rows, cols)`` (m) taken at ``times`` (N,) (s), in order."""
        self.push_modes(self.grid.modes(frames, workers=self.workers), times)

    def push_modes(self, modes: np.ndarray, times: ArrayLike) -> None:
        """Add ``h_m(r)`` of maps (:meth:`PolarGrid.modes` of this grid, (N, R, M), m) taken
        at ``times`` (N,) (s), in order."""
        stamps = np.asarray(times, dtype=np.float64).ravel()
        if modes.shape[0] != stamps.size:
            raise InputError(f"{modes.shape[0]} maps and {stamps.size} times do not match")
        self._lock_in(modes, stamps)
        if self.series_m:
            columns = [m + self.grid.m_max for m in self.series_m]
            self._series.append(modes[:, :, columns])
            self._times.extend(stamps.tolist())
        if self.makes_spectrum:
            for item, t in zip(modes, stamps, strict=True):
                self._push_modes(item, float(t))

    def _lock_in(self, modes: np.ndarray, times: np.ndarray) -> None:
        if self.frequencies.size == 0:
            return
        if self.span is None:
            weights = np.ones(times.size)
        else:
            start, stop = self.span
            phase = (times - start) / max(stop - start, 1e-300)
            weights = np.where((phase >= 0) & (phase <= 1), np.sin(np.pi * phase) ** 2, 0.0)
        finite = np.all(np.isfinite(modes), axis=2)  # (N, R)
        w = weights[:, np.newaxis] * finite  # (N, R)
        weighted = np.where(finite[:, :, np.newaxis], modes, 0.0) * w[:, :, np.newaxis]
        self._lock_weight += w.sum(axis=0)
        self._lock_weight_squares += (w**2).sum(axis=0)
        turns = np.exp(2j * np.pi * np.outer(self.frequencies, times))  # (F, N)
        n = times.size
        self._lock += (turns @ weighted.reshape(n, -1)).reshape(self._lock.shape)

    def _push_modes(self, modes: np.ndarray, t: float) -> None:
        if self._last_time is not None:
            step = t - self._last_time
            if step <= 0:
                raise InputError(f"frame {self.frames}: times must increase ({t!r} s)")
            if step > (1.0 + GAP_TOLERANCE) * self.interval:
                self._run = 0
        self._last_time = t
        self._ring[self._next] = modes
        self._next = (self._next + 1) % self.segment
        self._run += 1
        self.frames += 1
        if self._run >= self.segment and (self._run - self.segment) % self.hop == 0:
            self._add_segment()

    def _add_segment(self) -> None:
        block = np.concatenate([self._ring[self._next :], self._ring[: self._next]])
        rings = np.all(np.isfinite(block), axis=(0, 2))
        if not np.any(rings):
            return
        data = block if bool(rings.all()) else block[:, rings]
        del block  # worked on in place: one copy of the segment (58 MB for 2048 frames of
        # 104 rings with |m| <= 8)
        n = self.segment
        ramp = np.linspace(-1.0, 1.0, n)
        data -= data.mean(axis=0)
        slope = np.tensordot(ramp, data, axes=(0, 0)) / np.sum(ramp**2)
        for i in range(n):
            data[i] -= ramp[i] * slope
            data[i] *= self._taper[i]
        spectrum = np.fft.fft(data, axis=0)
        del data
        # exp(-i omega t) sits at numpy's frequency -f: bins 0, -1, ..., -n/2.
        power = np.abs(spectrum[(-np.arange(n // 2 + 1)) % n]) ** 2  # (F, R, M)
        del spectrum
        power *= self.interval / float(np.sum(self._taper**2))
        power[1 : (n + 1) // 2] *= 2.0
        r = self.grid.radii[rings]
        self._sum += (np.tensordot(r, power, axes=(0, 1)) / np.sum(r)).T  # (M, F)
        self._ring_sum[:, rings] += power.transpose(2, 1, 0)
        self._ring_segments[rings] += 1
        self.segments += 1

    def spectrum(self) -> MFSpectrum:
        """Return the (m, f) spectrum (InputError without a complete segment)."""
        if self.segments == 0:
            raise InputError(
                f"no (m, f) spectrum: {self.frames} frames hold no run of {self.segment} "
                "without a gap whose rings are finite"
            )
        return MFSpectrum(
            m=self.grid.m,
            frequency=np.arange(self.segment // 2 + 1) / (self.segment * self.interval),
            power=self._sum / self.segments,
            radii=self.grid.radii,
            segments=self.segments,
        )

    def profiles(self) -> NDArray[np.complex128]:
        """Return ``A_m(r, f)`` (m), shape (F, R, M): NaN on rings with no data."""
        has = self._lock_weight > 0
        weight = np.where(has, self._lock_weight, 1.0)[np.newaxis, :, np.newaxis]
        return np.where(has[np.newaxis, :, np.newaxis], 2.0 * self._lock / weight, np.nan)

    def profile_noise(self, m: int, frequency: float) -> NDArray[np.float64]:
        """Return the noise variance of each ring's profile value near ``(m, frequency)``.

        The variance of each of the real and imaginary parts of ``A_m(r, f)``
        (:meth:`profiles`, m^2), from that ring's own (m, f) power between
        :data:`FLOOR_BINS` bins either side of ``frequency``, the two nearest on each
        side left out (a tone's leakage through the segments' taper): their median,
        scaled to the mean of a chi-square of the segments' degrees of freedom, as a
        density of white noise, through the lock-in's weights (``sum w^2 / (sum w)^2``).
        NaN on rings that no complete segment or lock-in holds.
        """
        column = m + self.grid.m_max
        n_f = self._sum.shape[1]
        centre = round(frequency * self.segment * self.interval)
        offsets = np.r_[-FLOOR_BINS[1] : -FLOOR_BINS[0] + 1, FLOOR_BINS[0] : FLOOR_BINS[1] + 1]
        bins = centre + offsets
        bins = bins[(bins >= 2) & (bins < n_f - 1)]  # a segment's mean and slope are removed
        if bins.size == 0 or self.segments == 0:
            return np.full(self._ring_segments.size, np.nan)
        counts = np.maximum(self._ring_segments, 1.0)
        density = np.median(self._ring_sum[column][:, bins], axis=1) / counts  # (R,)
        dof = 2.0 * counts  # a segment's complex bin holds 2; overlaps neglected
        density /= (1.0 - 2.0 / (9.0 * dof)) ** 3  # Wilson-Hilferty: median to mean
        held = (self._ring_segments > 0) & (self._lock_weight > 0)
        weight = np.where(held, self._lock_weight, 1.0)
        spread = self._lock_weight_squares / weight**2
        return np.where(held, density / self.interval * spread, np.nan)

    def series(self) -> tuple[NDArray[np.float64], NDArray[np.complex128]]:
        """Return the times (N,) (s) and ``h_m(r, t)`` (N, R, len(series_m)) kept (m)."""
        if not self._series:
            shape = (0, self.grid.radii.size, len(self.series_m))
            return np.zeros(0), np.zeros(shape, np.complex128)
        return np.asarray(self._times), np.concatenate(self._series)
