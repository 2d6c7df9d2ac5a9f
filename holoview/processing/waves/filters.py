"""Band filters in wavenumber, frequency and direction of travel, giving filtered h(t, y, x).

A :class:`Band` keeps the wave-vector and frequency cells with ``k_min <= |k| <=
k_max``, ``f_min <= f <= f_max`` and, given a direction, those travelling within
``half_width`` of it. The direction of travel needs the sign of the frequency (a wave
along ``+k`` has its power at numpy's ``(-omega, +k)``, and at ``(+omega, -k)``): with
a frequency band or a direction the filter works on blocks of frames in time, with only
a wavenumber band on each frame alone.

:func:`band_filter` reads the maps a block at a time (anything indexable by frame
slices: an array, an HDF5 dataset) and writes the filtered maps to ``out`` the same
way, so memory stays a block's. In time, blocks of ``block`` frames overlap by half,
each tapered with a sine-squared window (the windows add up to one), transformed,
masked, transformed back and added (overlap-add; each frame read once, a block's second
half kept as the next one's first); each gap-free run is treated alone,
as if it were padded with zeros by half a block at both ends, so the first and last
frames of a run see less of their neighbours. Untrusted pixels (NaN) enter as zeros and
stay NaN in the output.
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

__all__ = ["Band", "band_filter"]


class FrameStack(Protocol):
    """Maps indexable by frame slices: ``stack[a:b]`` -> array (b - a, rows, cols)."""

    @property
    def shape(self) -> tuple[int, ...]:
        """``(frames, rows, cols)``."""

    def __getitem__(self, key: Any) -> Any: ...


class FrameSink(Protocol):
    """Where filtered maps go: ``sink[a:b] = array``."""

    def __setitem__(self, key: Any, value: Any) -> None: ...


@dataclass(frozen=True)
class Band:
    """The cells a band filter keeps (None: no limit on that side).

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

    def _k_mask(self, k: np.ndarray) -> np.ndarray:
        keep = np.ones(k.shape, bool)
        if self.k_min is not None:
            keep &= k >= self.k_min
        if self.k_max is not None:
            keep &= k <= self.k_max
        return keep

    def mask(self, frequency: np.ndarray, ky: np.ndarray, kx: np.ndarray) -> np.ndarray:
        """Return the cells kept, shape (F, R, C), for numpy's FFT axes (signed ``f``, Hz)."""
        kyy, kxx = ky[:, np.newaxis], kx[np.newaxis, :]
        keep = self._k_mask(np.hypot(kyy, kxx))[np.newaxis]
        f = frequency[:, np.newaxis, np.newaxis]
        if self.f_min is not None:
            keep = keep & (np.abs(f) >= self.f_min)
        if self.f_max is not None:
            keep = keep & (np.abs(f) <= self.f_max)
        if self.direction is not None:
            # travelling along +k at f < 0, along -k at f > 0; f = 0 travels nowhere
            sign = -np.sign(f)
            angle = np.arctan2(sign * kyy, sign * kxx)
            off = np.abs(np.angle(np.exp(1j * (angle - self.direction))))
            keep = keep & (off <= self.half_width) & (f != 0) & ((kyy != 0) | (kxx != 0))
        return np.broadcast_to(keep, (frequency.size, ky.size, kx.size))


def _sine_window(n: int) -> NDArray[np.float64]:
    """``sin^2(pi (j + 1/2) / n)``: shifted by half a block, such windows add up to one."""
    return np.sin(np.pi * (np.arange(n) + 0.5) / n) ** 2


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
        Frames per block in time (even, at least 8).
    workers : int, optional
        FFT threads.
    """
    n_frames, rows, cols = (int(s) for s in maps.shape)
    clock = frame_clock(times)
    if clock.frames != n_frames:
        raise InputError(f"{n_frames} maps and {clock.frames} times do not match")
    dy, dx = pixel_pair(pixel_size)
    ky = 2.0 * np.pi * np.fft.fftfreq(rows, dy)
    kx = 2.0 * np.pi * np.fft.fftfreq(cols, dx)
    if not band.temporal:
        keep = band._k_mask(np.hypot(ky[:, np.newaxis], kx[np.newaxis, :]))
        for start in range(0, n_frames, block):
            data = np.asarray(maps[start : start + block], dtype=np.float64)
            finite = np.isfinite(data)
            spectrum = scipy.fft.fft2(np.where(finite, data, 0.0), workers=workers)
            filtered = scipy.fft.ifft2(spectrum * keep, workers=workers).real
            out[start : start + block] = np.where(finite, filtered, np.nan)
        return
    if block < 8 or block % 2:
        raise InputError(f"the filter's block must be even and at least 8 frames, got {block}")
    hop = block // 2
    window = _sine_window(block).astype(np.float32)[:, np.newaxis, np.newaxis]
    # the mask is symmetric under (f, k) -> (-f, -k): its half f >= 0 for a real transform
    mask = band.mask(np.fft.rfftfreq(block, clock.interval), ky, kx).astype(np.float32)
    for start, stop in clock.runs:
        # frames [cursor, cursor + block): the maps as read (NaN: untrusted, or no frame of
        # the run) and the filtered sum; each frame is read once, its block's second half
        # kept as the next block's first
        held = np.full((block, rows, cols), np.nan, np.float32)
        pending = np.zeros((block, rows, cols), np.float32)
        cursor = start - hop  # the first block starts half a block before the run
        read_to = start
        while cursor < stop:
            hi = min(cursor + block, stop)
            if hi > read_to:
                held[read_to - cursor : hi - cursor] = np.asarray(maps[read_to:hi], np.float32)
                read_to = hi
            data = np.where(np.isfinite(held), held, np.float32(0.0)) * window
            spectrum = scipy.fft.rfftn(data, axes=(1, 2, 0), workers=workers)
            spectrum *= mask
            pending += scipy.fft.irfftn(
                spectrum, s=(rows, cols, block), axes=(1, 2, 0), workers=workers
            )
            done_lo, done_hi = max(cursor, start), min(cursor + hop, stop)
            if done_hi > done_lo:
                finished = pending[done_lo - cursor : done_hi - cursor]
                source = held[done_lo - cursor : done_hi - cursor]
                out[done_lo:done_hi] = np.where(np.isfinite(source), finished, np.nan)
            pending[:hop] = pending[hop:]
            pending[hop:] = 0.0
            held[:hop] = held[hop:]
            held[hop:] = np.nan
            cursor += hop
