"""Band filters in wavenumber, frequency and direction of travel, giving filtered h(t, y, x).

A :class:`Band` keeps the wave-vector and frequency cells with ``k_min <= |k| <=
k_max``, ``f_min <= |f| <= f_max`` and, given a direction, those travelling within
``half_width`` of it. The direction of travel needs the sign of the frequency (a wave
along ``+k`` has its power at numpy's ``(-omega, +k)``, and at ``(+omega, -k)``): with
a frequency band or a direction the filter works in time, with only a wavenumber band
on each frame alone. Every edge is smooth and passes half the amplitude (-6 dB) at the
limit given; the filter is linear, time- and shift-invariant and of zero phase.

In time each wave-vector cell is convolved with a finite impulse response (FIR) of
``block + 1`` frames: the band's ideal response (a boxcar in signed frequency) times a
Kaiser window (beta 3.4). Its edges have a width (passband within 1 % of one to
stopband below 1 %) of ``df = 2.25 * rate / block`` (3.5 Hz at 100 maps/s and the
default block of 64), half of it either side of each limit: a band narrower than
``df`` never reaches a gain of one. The cells take one of a few responses in signed
frequency: ``|f|`` in the band (no direction), or one sign only, weighted by the
direction's sector (power at ``f < 0`` travels along ``+k``). With a direction the band
starts no lower than ``df / 2``, so that a steady field, which travels nowhere, is
stopped (below 1 % at ``f = 0``); near Nyquist the two signs meet, and a band up to it
passes half there.

In space the band's edges in ``|k|`` and the sector's edges are raised cosines
:data:`K_TRANSITION` ``dk`` wide (``dk = 2 pi / L``, L the map's shorter side; across
the sector's edge measured perpendicular to it, in the wave-vector plane), half either
side; with a direction the band starts no lower than half that width (a uniform field
travels nowhere either). Each map is padded with zeros by a quarter of its size before
its transform, so that a wave is not wrapped round onto the map's far side (zero
padding did better than none, than mirroring and than a taper divided out). Near the
edges the filter sees the zeros beyond and a wave's gain falls (to about one half at
the edge), and a band only a few ``dk`` wide cannot part waves well anywhere. Measured
on two plane waves off the FFT grid (12.3 mm kept, 7.1 mm dropped, ``k`` band 1.3 times
either side of the kept wave's, random directions): on a 64 mm map (a band under 3
``dk`` wide) the rms residual is 22 % over the map, 13 % from 4 pixels in, 6-7 % from 8
(brick walls: 26 %, 16 %, 12 %); on 128 mm, 15 %, 4-5 % from 8 pixels in and 3 % from
16 (brick walls: 3-11 % from 16). A direction parting two 12.3 mm waves at 10 Hz 80 to
280 degrees apart on 64 mm: 15 % over the map, 3.5 % from 8 pixels in, 1.1 % from 16
(brick walls: 21 %, 8.5 %, 7 %). A NaN hole acts as the map's edges on the pixels
around it (gain 0.85 one pixel away, 0.95 at four).

:func:`band_filter` reads the maps a block at a time (anything indexable by frame
slices: an array, an HDF5 dataset) and writes the filtered maps to ``out`` the same
way, so memory stays a few blocks'. In time it is overlap-save: each frame is read
once and transformed in space once, its spatial spectrum kept for the two blocks that
need it, and a transform over ``2 * block`` frames gives the ``block`` frames in their
middle. Each gap-free run is filtered alone, as if the frames beyond it were zero: the
first and last ``block / 2`` frames of a run see those zeros: a wave passes at about
one half at the run's ends, within 5 % from ``block / 4`` frames in. Untrusted pixels
(NaN) enter as zeros and stay NaN in the output.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import scipy.fft
from numpy.typing import NDArray

from holoview.errors import InputError
from holoview.processing.waves.clock import frame_clock
from holoview.processing.waves.omega_k import pixel_pair

__all__ = ["K_TRANSITION", "Band", "band_filter", "block_for", "transition_width"]

#: Kaiser window of the FIR in time: ripple 0.5 %, edges ``2.24 * rate / block`` wide.
KAISER_BETA = 3.4

#: Width of the FIR's edges (1 % to 99 % of one), times ``rate / block``.
TRANSITION = 2.25

#: Width of the edges in ``|k|`` and of the sector's, in ``dk = 2 pi / L``.
K_TRANSITION = 3.0

#: Least block of frames in time (:func:`block_for`).
MIN_BLOCK = 64

#: Most memory the spectra of a block may take (two blocks of padded maps' transforms).
MAX_BLOCK_BYTES = 1 << 30


class FrameStack(Protocol):
    """Maps indexable by frame slices: ``stack[a:b]`` -> array (b - a, rows, cols)."""

    @property
    def shape(self) -> tuple[int, ...]:
        """``(frames, rows, cols)``."""

    def __getitem__(self, key: Any) -> Any: ...


class FrameSink(Protocol):
    """Where filtered maps go: ``sink[a:b] = array``."""

    def __setitem__(self, key: Any, value: Any) -> None: ...


def _fall(beyond: NDArray[np.float64], width: float) -> NDArray[np.float64]:
    """Raised-cosine edge: 1 for ``beyond <= -width / 2``, 0 from ``width / 2``, 1/2 at 0."""
    return 0.5 * (1.0 - np.sin(np.pi * np.clip(beyond / width, -0.5, 0.5)))


@dataclass(frozen=True)
class Band:
    """The cells a band filter keeps (None: no limit on that side); edges pass one half.

    Attributes
    ----------
    k_min, k_max : float or None
        Wavenumbers, rad/m.
    f_min, f_max : float or None
        Frequencies, Hz (``f >= 0``: ``|f|`` of the cell).
    direction : float or None
        Direction of travel, rad (``atan2(ky, kx)``: x along columns, y along rows).
    half_width : float
        Half-width of the direction's sector, rad.
    """

    k_min: float | None = None
    k_max: float | None = None
    f_min: float | None = None
    f_max: float | None = None
    direction: float | None = None
    half_width: float = math.radians(30.0)

    def __post_init__(self) -> None:
        for low, high, unit in (("k_min", "k_max", "rad/m"), ("f_min", "f_max", "Hz")):
            a, b = getattr(self, low), getattr(self, high)
            for value in (a, b):
                if value is not None and not (math.isfinite(value) and value >= 0):
                    raise InputError(f"band limits must be finite and >= 0, got {value!r} {unit}")
            if a is not None and b is not None and not a < b:
                raise InputError(f"the band {a:g}:{b:g} {unit} must increase")
        if self.direction is not None and not math.isfinite(self.direction):
            raise InputError(f"the direction must be finite, got {self.direction!r} rad")
        if not 0 < self.half_width <= math.pi:
            raise InputError(f"the sector's half-width must be in (0, pi], got {self.half_width}")

    @property
    def temporal(self) -> bool:
        """True when the filter needs time (a frequency band or a direction)."""
        return self.f_min is not None or self.f_max is not None or self.direction is not None

    def k_gain(self, k: NDArray[np.float64], width: float) -> NDArray[np.float64]:
        """Return the gain on ``|k|`` (rad/m), edges ``width`` (rad/m) wide."""
        gain = np.ones(k.shape)
        k_min = self.k_min
        if self.direction is not None:
            k_min = max(k_min or 0.0, 0.5 * width)
        if k_min is not None:
            gain *= _fall(k_min - k, width)
        if self.k_max is not None:
            gain *= _fall(k - self.k_max, width)
        return gain

    def sector_gain(
        self, ky: NDArray[np.float64], kx: NDArray[np.float64], width: float
    ) -> NDArray[np.float64]:
        """Return the direction's gain for waves travelling along ``(ky, kx)`` (rad/m).

        The edge is ``width`` (rad/m) wide across the sector's boundary, so that it turns
        in angle over ``width / |k|``.
        """
        if self.direction is None or self.half_width >= math.pi:
            return np.ones(np.broadcast_shapes(ky.shape, kx.shape))
        off = np.abs(np.angle(np.exp(1j * (np.arctan2(ky, kx) - self.direction))))
        beyond = np.clip(off - self.half_width, -0.5 * np.pi, 0.5 * np.pi)
        return _fall(np.hypot(ky, kx) * np.sin(beyond), width)

    def frequency_intervals(self, rate: float, block: int) -> list[list[tuple[float, float]]]:
        """Return the passbands in signed frequency, Hz, of each response in time.

        One response (``+-[f_min, f_max]``) without a direction; with one, two: ``f > 0``
        (travelling along ``-k``), then ``f < 0`` (along ``+k``).
        """
        nyquist = 0.5 * rate
        if self.direction is None:
            if self.f_min is None:
                return [[(-(self.f_max or nyquist), self.f_max or nyquist)]]
            if self.f_max is None:  # up to Nyquist and on, through the negative side's top
                return [[(self.f_min, rate - self.f_min)]]
            return [[(self.f_min, self.f_max), (-self.f_max, -self.f_min)]]
        low = max(self.f_min or 0.0, 0.5 * transition_width(rate, block))
        high = nyquist if self.f_max is None else self.f_max
        if not low < high:
            raise InputError(
                f"the band filter's band up to {high:g} Hz lies within the filter's "
                f"transition ({transition_width(rate, block):.3g} Hz): its direction of "
                "travel is not resolved; use a longer block"
            )
        return [[(low, high)], [(-high, -low)]]


def transition_width(rate: float, block: int) -> float:
    """Return the width of the filter's edges in frequency, Hz (module docstring).

    Parameters
    ----------
    rate : float
        Frames per second.
    block : int
        Frames per block (the FIR has ``block + 1`` taps).

    Examples
    --------
    >>> round(transition_width(100.0, 64), 3)
    3.516
    """
    return TRANSITION * rate / block


def block_for(band: Band, rate: float, shape: tuple[int, int], frames: int) -> int:
    """Return the block that filters ``band`` at ``rate`` (maps/s) on maps of ``shape``
    whose longest gap-free run holds ``frames``.

    At least :data:`MIN_BLOCK` frames, and enough that the edges are at most half the
    band's width: a wave in its middle then passes at one.

    Raises
    ------
    InputError
        A band so narrow that its filter would be longer than the longest run, or its
        spectra would take over :data:`MAX_BLOCK_BYTES`.

    Examples
    --------
    >>> block_for(Band(f_min=8.0, f_max=12.0), 100.0, (64, 64), 1000)
    114
    >>> block_for(Band(f_max=12.0), 100.0, (64, 64), 1000)
    64
    """
    block = MIN_BLOCK
    if band.f_min is None or band.f_max is None:
        return block
    block = max(block, 2 * math.ceil(TRANSITION * rate / (band.f_max - band.f_min)))
    spectra = 2 * block * _padded(shape[0]) * (_padded(shape[1]) // 2 + 1) * 8
    longest = min(frames, block * MAX_BLOCK_BYTES // spectra)
    if block > max(longest, MIN_BLOCK):
        why = (
            f"{spectra / 2**30:.1f} GB of spectra"
            if spectra > MAX_BLOCK_BYTES
            else f"the longest run without a gap has {frames}"
        )
        raise InputError(
            f"the band {band.f_min:g}:{band.f_max:g} Hz is too narrow to filter at "
            f"{rate:.4g} maps/s: its filter would span {block} frames ({why}); widen it to "
            f"{2.0 * transition_width(rate, longest):.3g} Hz or more"
        )
    return block


def _fir(intervals: list[tuple[float, float]], rate: float, block: int) -> NDArray[np.complex128]:
    """Return the FIR passing ``intervals`` (signed Hz), taps ``-block / 2 .. block / 2``.

    Each interval's ideal response (one in it, zero outside) times a Kaiser window; the
    taps satisfy ``g[-j] = conj(g[j])``, so the response is real (zero phase).
    """
    j = np.arange(-(block // 2), block // 2 + 1)
    taps = np.zeros(j.size, np.complex128)
    nonzero = j != 0
    for low, high in intervals:
        a, b = low / rate, high / rate
        taps[~nonzero] += b - a
        jj = j[nonzero]
        taps[nonzero] += (np.exp(2j * np.pi * b * jj) - np.exp(2j * np.pi * a * jj)) / (
            2j * np.pi * jj
        )
    return taps * np.kaiser(j.size, KAISER_BETA)


def _temporal_response(
    band: Band,
    rate: float,
    block: int,
    k: tuple[NDArray[np.float64], NDArray[np.float64]],
    dk: float,
) -> NDArray[np.float32]:
    """Return the filter's response, shape (2 block, ky, kx), on a transform of 2 block
    frames (numpy's order of signed frequencies) and of the padded map (``kx >= 0``)."""
    kyy, kxx = k[0][:, np.newaxis], k[1][np.newaxis, :]
    space = band.k_gain(np.hypot(kyy, kxx), dk)
    # power at f > 0 travels along -k, at f < 0 along +k (one response, no direction)
    sectors = [band.sector_gain(-kyy, -kxx, dk), band.sector_gain(kyy, kxx, dk)]
    response = np.zeros((2 * block, k[0].size, k[1].size), np.float32)
    for intervals, sector in zip(band.frequency_intervals(rate, block), sectors, strict=False):
        taps = _fir(intervals, rate, block)
        placed = np.zeros(2 * block, complex)
        placed[np.arange(-(block // 2), block // 2 + 1)] = taps  # tap j at j mod 2 block
        gain = np.fft.fft(placed).real
        response += (gain[:, np.newaxis, np.newaxis] * (space * sector)).astype(np.float32)
    return response


def _padded(n: int) -> int:
    """Length of a map's side padded with zeros by a quarter, for its transform."""
    return scipy.fft.next_fast_len(n + n // 4, real=True)


def band_filter(
    maps: FrameStack,
    times: NDArray[np.float64],
    pixel_size: float | tuple[float, float],
    band: Band,
    out: FrameSink,
    *,
    block: int = 64,
    workers: int | None = None,
) -> None:
    """Write the band-filtered maps of ``maps`` into ``out`` (module docstring).

    Parameters
    ----------
    maps : array-like, shape (N, rows, cols)
        Height maps, m (NaN where untrusted), readable by frame slices.
    times : ndarray of float, shape (N,)
        Frame times, s.
    pixel_size : float or (float, float)
        m.
    band : Band
    out : array-like, shape (N, rows, cols)
        Written by frame slices (float32 or float64).
    block : int
        Frames per block in time (even, at least 8): the FIR has ``block + 1`` taps and
        edges ``2.25 * rate / block`` wide (:func:`transition_width`); the first and last
        ``block / 2`` frames of each gap-free run are attenuated.
    workers : int, optional
        FFT threads.

    Raises
    ------
    InputError
        Maps and times that do not match, a bad block, or a band with a direction that
        lies below half the transition width.
    """
    n_frames, rows, cols = (int(s) for s in maps.shape)
    clock = frame_clock(times)
    if clock.frames != n_frames:
        raise InputError(f"{n_frames} maps and {clock.frames} times do not match")
    dy, dx = pixel_pair(pixel_size)
    shape = (_padded(rows), _padded(cols))
    ky = 2.0 * np.pi * np.fft.fftfreq(shape[0], dy).astype(np.float64)
    kx = 2.0 * np.pi * np.fft.rfftfreq(shape[1], dx).astype(np.float64)
    dk = K_TRANSITION * 2.0 * np.pi / min(rows * dy, cols * dx)
    if not band.temporal:
        gain = band.k_gain(np.hypot(ky[:, np.newaxis], kx[np.newaxis, :]), dk)
        for start in range(0, n_frames, block):
            data = np.asarray(maps[start : start + block], dtype=np.float64)
            finite = np.isfinite(data)
            spectrum = scipy.fft.rfft2(np.where(finite, data, 0.0), s=shape, workers=workers)
            filtered = scipy.fft.irfft2(spectrum * gain, s=shape, workers=workers)
            out[start : start + block] = np.where(finite, filtered[:, :rows, :cols], np.nan)
        return
    if block < 8 or block % 2:
        raise InputError(f"the filter's block must be even and at least 8 frames, got {block}")
    half = block // 2
    response = _temporal_response(band, clock.rate, block, (ky, kx), dk)
    for start, stop in clock.runs:
        # overlap-save: row i of the buffers holds frame cursor - half + i (zero outside
        # the run), and the frames [cursor, cursor + block) are the middle rows' output
        spectra = np.zeros(response.shape, np.complex64)
        finite = np.zeros((2 * block, rows, cols), bool)
        read_to = start
        for cursor in range(start, stop, block):
            first, last = cursor - half, min(cursor + block + half, stop)
            if last > read_to:
                data = np.asarray(maps[read_to:last], np.float32)
                rows_read = slice(read_to - first, last - first)
                finite[rows_read] = np.isfinite(data)
                spectra[rows_read] = scipy.fft.rfft2(
                    np.where(finite[rows_read], data, np.float32(0.0)), s=shape, workers=workers
                )
                read_to = last
            product = scipy.fft.fft(spectra, axis=0, workers=workers)
            product *= response
            filtered = scipy.fft.ifft(product, axis=0, overwrite_x=True, workers=workers)
            done = min(block, stop - cursor)
            frames = scipy.fft.irfft2(filtered[half : half + done], s=shape, workers=workers)
            out[cursor : cursor + done] = np.where(
                finite[half : half + done], frames[:, :rows, :cols], np.nan
            )
            spectra[:block] = spectra[block:]
            spectra[block:] = 0.0
            finite[:block] = finite[block:]
            finite[block:] = False
