"""The omega-k spectrum of a wave field, averaged over time segments, and E(k), E(omega).

A sequence of height maps is a sampled wave field ``h(t, y, x)``. Its power spectral
density ``S(f, ky, kx)`` is estimated by Welch's method: segments of ``segment``
consecutive frames that span no gap (:mod:`~holoview.processing.waves.clock`),
overlapping by half, each detrended per pixel (mean and slope over the segment),
tapered with a Hann window in time and in both space directions, transformed, and
their power averaged. Memory is the segment's, whatever the length of the record: an
:class:`OmegaKAccumulator` takes maps one at a time (a file read in blocks, or a live
stream), and :meth:`OmegaKAccumulator.latest` gives the spectrum of the last
``segment`` frames for a live view.

Sign convention
---------------
numpy's FFT sign over ``(t, y, x)``: a wave ``exp(i (k . x - omega t))`` with
``omega > 0``, travelling along ``+k``, has its power at ``(-omega, +k)`` (and, the
field being real, at ``(+omega, -k)``). :class:`OmegaKSpectrum` stores the
``(-omega, +k)`` half, indexed by ``f = omega / 2 pi >= 0``: power at ``(f, +k)`` is a
wave travelling along ``+k``, so a flow ``U`` shifts it to ``omega_0(|k|) + k . U``.
:data:`SIGN_CONVENTION` says this in every output.

Units and normalisation
-----------------------
``S`` is a one-sided density in ``m^2 / (Hz (rad/m)^2)``: summed over every cell
times ``df dkx dky`` it gives the mean square height of the (detrended) field. The
detrending takes its share of the slowest waves: a wave of fewer than three periods in
a segment is estimated too high or too low (+26 % at 1.5 periods, +12 % at 2, -72 %
at 0.7; within 0.4 % from 3), so the lowest two frequency bins are not to be read as
levels; the lowest frequency a segment measures well is ``3 / (segment interval)``.
Masked pixels (NaN in any frame of a segment) are left out of that segment, the taper
rising smoothly from them over :data:`HOLE_RAMP` pixels (a sharp hole would spread
every strong wave over all wavenumbers), and the normalisation uses the taper kept; a
segment with less than ``min_valid`` of its pixels kept is skipped. Waves beyond the
demodulation window's cut-off ``k_cut`` are not in the maps: it is passed in, kept, and
marked on figures.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from holoview.errors import InputError
from holoview.processing.waves.clock import GAP_TOLERANCE

logger = logging.getLogger(__name__)

__all__ = [
    "SIGN_CONVENTION",
    "OmegaKAccumulator",
    "OmegaKSpectrum",
    "hann",
    "pixel_pair",
]

#: The sign convention of every spectrum and amplitude, as written into the outputs.
SIGN_CONVENTION = (
    "numpy FFT sign over (t, y, x): a wave exp(i(k.x - omega t)), omega > 0, travelling "
    "along +k, has its power at (-omega, +k); spectra store that half indexed by "
    "f = omega / 2 pi >= 0, so power at (f, +k) travels along +k; complex amplitudes A "
    "mean h = Re(A exp(-i omega t)); x along columns, y along rows, theta = atan2(y, x)"
)

#: Default segment length, frames.
SEGMENT = 128


def hann(n: int) -> NDArray[np.float64]:
    """Return a periodic Hann window of ``n`` samples (Welch's usual taper)."""
    return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)


def pixel_pair(pixel_size: float | ArrayLike) -> tuple[float, float]:
    """Return ``(dy, dx)`` in m from one pixel size or a (rows, cols) pair; check them."""
    values = np.atleast_1d(np.asarray(pixel_size, dtype=np.float64)).ravel()
    if values.size == 1:
        values = np.repeat(values, 2)
    if values.size != 2 or not np.all(np.isfinite(values)) or np.any(values <= 0):
        raise InputError(f"the pixel size must be one or two positive lengths (m), got {values}")
    return float(values[0]), float(values[1])


@dataclass(frozen=True)
class OmegaKSpectrum:
    """Welch estimate of the power of a wave field against frequency and wave vector.

    Attributes
    ----------
    frequency : ndarray of float, shape (F,)
        Temporal frequency ``f >= 0``, Hz (``omega = 2 pi f``), up to Nyquist.
    ky, kx : ndarray of float, shapes (R,) and (C,)
        Wave-vector components, rad/m, increasing (zero at index ``R // 2``, ``C // 2``).
    power : ndarray of float32, shape (F, R, C)
        One-sided power spectral density, m^2 / (Hz (rad/m)^2), in the convention of
        :data:`SIGN_CONVENTION` (power at ``(f, +k)`` travels along ``+k``).
    k_cut : float
        Largest wavenumber the maps hold (the demodulation window's cut-off), rad/m.
    segments : int
        Segments averaged.
    frames : int
        Frames in the segments (each counted once).
    interval : float
        Time between frames, s.
    pixel_size : tuple of float
        ``(dy, dx)``, m.
    valid_fraction : float
        Mean share of the pixels kept over the segments.
    """

    frequency: NDArray[np.float64]
    ky: NDArray[np.float64]
    kx: NDArray[np.float64]
    power: NDArray[np.float32]
    k_cut: float
    segments: int
    frames: int
    interval: float
    pixel_size: tuple[float, float]
    valid_fraction: float

    convention = SIGN_CONVENTION

    @property
    def df(self) -> float:
        """Frequency step, Hz."""
        return float(self.frequency[1] - self.frequency[0])

    @property
    def dk(self) -> tuple[float, float]:
        """Wave-vector steps ``(dky, dkx)``, rad/m."""
        return float(self.ky[1] - self.ky[0]), float(self.kx[1] - self.kx[0])

    @property
    def k(self) -> NDArray[np.float64]:
        """Wavenumber ``|k|`` of every cell, rad/m, shape (R, C)."""
        return np.hypot(self.ky[:, np.newaxis], self.kx[np.newaxis, :])

    @property
    def relative_stderr(self) -> float:
        """Relative standard error of each power value from the averaging (1 / sqrt(segments))."""
        return 1.0 / math.sqrt(max(self.segments, 1))

    def _bins(self) -> tuple[np.ndarray, np.ndarray, float]:
        """Radial bins of width ``min(dk)`` up to ``k_cut``: centres, cell bin, width.

        A cell belongs to the bin whose centre is nearest its ``|k|``."""
        width = min(self.dk)
        n_bins = math.floor(self.k_cut / width + 0.5) + 1
        index = np.rint(self.k / width).astype(np.intp)
        index[self.k > self.k_cut] = n_bins  # beyond the cut-off: left out
        return np.arange(n_bins) * width, index, width

    def energy_k(self) -> tuple[np.ndarray, np.ndarray]:
        """Return ``k`` (rad/m) and ``E(k)`` (m^2 / (rad/m)), 0 to ``k_cut``.

        ``E(k) dk`` is the mean square height of the waves with wavenumbers in
        ``[k - dk / 2, k + dk / 2)``, all frequencies and directions together. A wave
        between two bins spreads over its neighbours (the taper's leakage): its peak
        may stand in the bin after the nearest.
        """
        centres, index, width = self._bins()
        dky, dkx = self.dk
        per_cell = self.power.sum(axis=0, dtype=np.float64) * self.df * dky * dkx
        flat = index.ravel()
        inside = flat < centres.size
        energy = np.bincount(flat[inside], per_cell.ravel()[inside], minlength=centres.size)
        return centres, energy / width

    def energy_omega(self, k_min: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Return ``omega`` (rad/s) and ``E(omega)`` (m^2 s / rad), waves up to ``k_cut``.

        ``E(omega) d omega`` is the mean square height of the waves with angular
        frequencies in ``[omega - d omega / 2, omega + d omega / 2)``.

        Parameters
        ----------
        k_min : float
            Only waves with wavenumbers above this, rad/m (default all).
        """
        dky, dkx = self.dk
        inside = (self.k <= self.k_cut) & (self.k > k_min)
        per_f = np.tensordot(self.power.astype(np.float64), inside, axes=([1, 2], [0, 1]))
        return 2.0 * np.pi * self.frequency, per_f * dky * dkx / (2.0 * np.pi)

    def radial(self) -> tuple[np.ndarray, np.ndarray]:
        """Return ``k`` (rad/m) and the power averaged over directions, (F, K), 0 to ``k_cut``."""
        centres, index, _ = self._bins()
        flat = index.ravel()
        inside = flat < centres.size
        counts = np.bincount(flat[inside], minlength=centres.size).astype(np.float64)
        planes = self.power.reshape(self.power.shape[0], -1)[:, inside]
        out = np.zeros((self.power.shape[0], centres.size))
        for i, plane in enumerate(planes):
            out[i] = np.bincount(flat[inside], plane, minlength=centres.size)
        return centres, out / np.where(counts > 0, counts, 1.0)

    def along(
        self, angle: float, half_width: float = math.radians(15.0)
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return the power against the signed wavenumber along a direction.

        Parameters
        ----------
        angle : float
            Direction ``theta = atan2(ky, kx)``, rad.
        half_width : float
            Cells within this angle of the direction (positive ``q``) or of its
            opposite (negative ``q``) count, rad.

        Returns
        -------
        q : ndarray, shape (Q,)
            Signed wavenumber along the direction, rad/m, ``-k_cut`` to ``k_cut``;
            negative: waves travelling against it.
        power : ndarray, shape (F, Q)
            Mean power of the cells of each bin, m^2 / (Hz (rad/m)^2).
        """
        width = min(self.dk)
        n_half = math.floor(self.k_cut / width + 0.5)
        ey, ex = math.sin(angle), math.cos(angle)
        kyy, kxx = self.ky[:, np.newaxis], self.kx[np.newaxis, :]
        along = kxx * ex + kyy * ey
        across = -kxx * ey + kyy * ex
        k = np.hypot(kyy, kxx)
        keep = (np.abs(across) <= np.tan(half_width) * np.abs(along)) & (k <= self.k_cut)
        index = (np.rint(along / width).astype(np.intp) + n_half)[keep]
        n_bins = 2 * n_half + 1
        counts = np.bincount(index, minlength=n_bins).astype(np.float64)
        planes = self.power.reshape(self.power.shape[0], -1)[:, keep.ravel()]
        out = np.zeros((self.power.shape[0], n_bins))
        for i, plane in enumerate(planes):
            out[i] = np.bincount(index, plane, minlength=n_bins)
        return (np.arange(n_bins) - n_half) * width, out / np.where(counts > 0, counts, 1.0)


#: Pixels over which the taper rises from an untrusted pixel to its full value.
HOLE_RAMP = 4.0


def _hole_taper(finite: NDArray[np.bool_]) -> NDArray[np.float64]:
    """1 far from untrusted pixels, 0 on them, a sine-squared rise over :data:`HOLE_RAMP`.

    A hole cut sharply into the taper would spread every strong wave over all
    wavenumbers at its frequency; a smooth edge keeps the leakage down.
    """
    if np.all(finite):
        return np.ones(finite.shape)
    distance = ndimage.distance_transform_edt(finite)
    return np.sin(0.5 * np.pi * np.clip(distance / HOLE_RAMP, 0.0, 1.0)) ** 2


class OmegaKAccumulator:
    """Welch averaging of the omega-k power of maps pushed one at a time.

    Parameters
    ----------
    shape : (int, int)
        Map shape (rows, cols), at least 8 x 8.
    pixel_size : float or (float, float)
        Pixel size on the surface, m (one value, or (dy, dx)).
    interval : float
        Nominal time between frames, s; a step longer than ``1 + GAP_TOLERANCE``
        intervals is a gap, and segments never span one.
    segment : int
        Frames per segment (at least 8); the frequency resolution is
        ``1 / (segment interval)``.
    overlap : float
        Share of a segment shared with the next (0 to 0.75; 0.5 by default).
    k_cut : float, optional
        The maps' cut-off wavenumber, rad/m (default: the grid's Nyquist, the smaller
        of ``pi / dy`` and ``pi / dx``).
    min_valid : float
        Least share of the pixels a segment must keep (pixels finite in every frame).
    workers : int, optional
        FFT threads (scipy.fft), default 1.

    Examples
    --------
    >>> acc = OmegaKAccumulator((64, 64), 1e-3, 0.01, segment=32)
    >>> for i, frame in enumerate(maps):  # doctest: +SKIP
    ...     acc.push(frame, i * 0.01)
    >>> spectrum = acc.spectrum()  # doctest: +SKIP
    """

    def __init__(
        self,
        shape: tuple[int, int],
        pixel_size: float | ArrayLike,
        interval: float,
        *,
        segment: int = SEGMENT,
        overlap: float = 0.5,
        k_cut: float | None = None,
        min_valid: float = 0.5,
        workers: int | None = None,
    ) -> None:
        rows, cols = (int(s) for s in shape)
        if rows < 8 or cols < 8:
            raise InputError(f"maps of {rows} x {cols} pixels are too small (at least 8 x 8)")
        if not (math.isfinite(interval) and interval > 0):
            raise InputError(f"the frame interval must be positive, got {interval!r} s")
        if segment < 8:
            raise InputError(f"a segment needs at least 8 frames, got {segment}")
        if not 0.0 <= overlap <= 0.75:
            raise InputError(f"the segment overlap must be from 0 to 0.75, got {overlap}")
        self.shape = (rows, cols)
        self.pixel_size = pixel_pair(pixel_size)
        self.interval = float(interval)
        self.segment = int(segment)
        self.hop = max(1, round(segment * (1.0 - overlap)))
        dy, dx = self.pixel_size
        nyquist = min(math.pi / dy, math.pi / dx)
        if k_cut is not None and not (math.isfinite(k_cut) and k_cut > 0):
            raise InputError(f"the cut-off wavenumber must be positive, got {k_cut!r} rad/m")
        self.k_cut = nyquist if k_cut is None else min(float(k_cut), nyquist)
        self.min_valid = float(min_valid)
        self.workers = workers or 1
        self._ring = np.empty((self.segment, rows, cols), np.float32)
        self._work = np.empty_like(self._ring)
        self._next = 0  # ring slot of the next frame
        self._run = 0  # frames pushed since the last gap
        self._last_time: float | None = None
        self._sum = np.zeros((self.segment // 2 + 1, rows, cols), np.float64)
        self._valid_sum = 0.0
        self.segments = 0
        self.skipped = 0
        self.frames_pushed = 0
        self._used_until = -1  # index (in frames pushed) of the last frame in a segment
        self.frames_used = 0
        self._time_taper = hann(self.segment)
        self._space_taper = np.outer(hann(rows), hann(cols))

    def push(self, frame: ArrayLike, time: float) -> None:
        """Add one map (m, NaN where untrusted) taken at ``time`` (s)."""
        data = np.asarray(frame)
        if data.shape != self.shape:
            raise InputError(f"a map of shape {data.shape} in a sequence of {self.shape}")
        t = float(time)
        if not math.isfinite(t):
            raise InputError(f"frame {self.frames_pushed}: the time is not finite ({t})")
        if self._last_time is not None:
            step = t - self._last_time
            if step <= 0:
                raise InputError(
                    f"frame {self.frames_pushed}: times must increase ({t!r} s after "
                    f"{self._last_time!r} s)"
                )
            if step > (1.0 + GAP_TOLERANCE) * self.interval:
                self._run = 0  # a gap: segments start again after it
        self._last_time = t
        self._ring[self._next] = data
        self._next = (self._next + 1) % self.segment
        self._run += 1
        self.frames_pushed += 1
        if self._run >= self.segment and (self._run - self.segment) % self.hop == 0:
            self._add_segment()

    def extend(self, frames: ArrayLike, times: ArrayLike) -> None:
        """Add maps ``frames`` (N, rows, cols) taken at ``times`` (N,), in order."""
        block = np.asarray(frames)
        stamps = np.asarray(times, dtype=np.float64)
        if block.ndim != 3 or stamps.shape != (block.shape[0],):
            raise InputError(
                f"maps of shape {block.shape} and times of shape {stamps.shape} do not match"
            )
        for frame, t in zip(block, stamps, strict=True):
            self.push(frame, float(t))

    def _ordered(self) -> NDArray[np.float32]:
        """The last ``segment`` frames in time order, copied into the work buffer.

        One buffer kept for every segment: a fresh array this size each time would be
        mapped from the system and faulted in page by page.
        """
        head = self.segment - self._next
        self._work[:head] = self._ring[self._next :]
        self._work[head:] = self._ring[: self._next]
        return self._work

    def _segment_power(self, block: NDArray[np.float32], into: np.ndarray) -> float | None:
        """Add one segment's two-sided density at f >= 0 (numpy's sign, unshifted) to ``into``.

        ``block`` is a work buffer (it is worked on in place, a frame at a time so that
        each step stays in the cache); the one-sided factor 2 is applied to the average
        (:meth:`_result`). Returns the share of pixels kept, or None (nothing added) when
        it is under ``min_valid``.
        """
        finite = np.ones(self.shape, bool)
        for frame in block:
            finite &= np.isfinite(frame)
        share = float(finite.mean())
        if share < self.min_valid:
            return None
        n = block.shape[0]
        if share < 1.0:
            for frame in block:
                frame[~finite] = 0.0
        ramp = np.linspace(-1.0, 1.0, n, dtype=np.float32)
        mean = block.mean(axis=0)
        slope = np.tensordot(ramp, block, axes=(0, 0)) / np.float32(np.sum(ramp**2))
        space = self._space_taper * _hole_taper(finite)
        dy, dx = self.pixel_size
        norm = (
            (1.0 / self.interval)
            * (2.0 * np.pi / dy)
            * (2.0 * np.pi / dx)
            * float(np.sum(self._time_taper**2))
            * float(np.sum(space**2))
        )
        space32 = (space / math.sqrt(norm)).astype(np.float32)  # the normalisation folded in
        for i in range(n):
            block[i] -= mean
            block[i] -= ramp[i] * slope
            block[i] *= np.float32(self._time_taper[i]) * space32
        spectrum = scipy.fft.rfftn(block, axes=(1, 2, 0), workers=self.workers)
        for i, plane in enumerate(spectrum):
            into[i] += np.square(plane.real)
            into[i] += np.square(plane.imag)
        return share

    def _add_segment(self) -> None:
        share = self._segment_power(self._ordered(), self._sum)
        if share is None:
            self.skipped += 1
            logger.debug("segment skipped: under %.0f %% of the pixels kept", 100 * self.min_valid)
            return
        self._valid_sum += share
        self.segments += 1
        first = self.frames_pushed - self.segment
        self.frames_used += self.frames_pushed - max(first, self._used_until + 1)
        self._used_until = self.frames_pushed - 1

    def _result(
        self, total: np.ndarray, segments: int, share: float, frames: int
    ) -> OmegaKSpectrum:
        total = total.astype(np.float64)
        total[1 : (self.segment + 1) // 2] *= 2.0  # one-sided: every f but 0 and Nyquist twice
        rows, cols = self.shape
        # (+f, k) -> (-f, k) = (+f, -k): flip both space axes, then centre zero.
        flipped = total[:, (-np.arange(rows)) % rows][:, :, (-np.arange(cols)) % cols]
        power = np.fft.fftshift(flipped, axes=(1, 2)).astype(np.float32)
        dy, dx = self.pixel_size
        return OmegaKSpectrum(
            frequency=np.arange(total.shape[0]) / (self.segment * self.interval),
            ky=2.0 * np.pi * np.fft.fftshift(np.fft.fftfreq(rows, dy)),
            kx=2.0 * np.pi * np.fft.fftshift(np.fft.fftfreq(cols, dx)),
            power=power,
            k_cut=self.k_cut,
            segments=segments,
            frames=frames,
            interval=self.interval,
            pixel_size=self.pixel_size,
            valid_fraction=share,
        )

    def spectrum(self) -> OmegaKSpectrum:
        """Return the Welch average of the segments so far.

        Raises
        ------
        InputError
            No segment yet: fewer than ``segment`` consecutive frames without a gap
            (or every segment had too few finite pixels).
        """
        if self.segments == 0:
            why = (
                f"{self.skipped} segments had under {100 * self.min_valid:.0f} % finite pixels"
                if self.skipped
                else f"{self.frames_pushed} frames, no run of {self.segment} without a gap"
            )
            raise InputError(f"no omega-k spectrum: a segment needs {self.segment} frames ({why})")
        return self._result(
            self._sum / self.segments,
            self.segments,
            self._valid_sum / self.segments,
            self.frames_used,
        )

    def latest(self) -> OmegaKSpectrum:
        """Return the spectrum of the last ``segment`` frames alone (a live view).

        Raises
        ------
        InputError
            Fewer than ``segment`` frames since the last gap, or too few finite pixels.
        """
        if self._run < self.segment:
            raise InputError(
                f"the last {self._run} frames since a gap or the start are fewer than a "
                f"segment ({self.segment})"
            )
        power = np.zeros_like(self._sum)
        share = self._segment_power(self._ordered(), power)
        if share is None:
            raise InputError(
                f"the last {self.segment} frames keep under {100 * self.min_valid:.0f} % of "
                "the pixels"
            )
        return self._result(power, 1, share, self.segment)
