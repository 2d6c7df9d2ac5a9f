"""A peak's phase map between demodulation and result: unwrapping in space and noise.

:class:`PhaseMap` carries one peak's wrapped map of one frame. :func:`unwrap_maps`
unwraps the maps of a frame that need it: one (the guide, :func:`guide_index`) in
space (Herraez et al. 2002, :func:`unwrap_in_space`), the others against the guide
scaled by the ratio of their alphas. :func:`phase_noise` gives a map's phase noise
per pixel (rad) from the noise floor of the frames' spectra (:func:`floor_power`).

Maps are at box resolution (:mod:`holoview.processing.fourier.boxes`); phases in rad.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from holoview.processing.maps.unwrap import (
    EDGE,
    has_wraps,
    phase_ratio,
    unwrap_guided,
    unwrap_spatial,
)
from holoview.processing.peaks.detection import Peak

__all__ = [
    "PhaseMap",
    "floor_bins",
    "floor_power",
    "guide_index",
    "phase_noise",
    "unwrap_in_space",
    "unwrap_maps",
    "wrapped_inside",
]

#: Side (map pixels) of the coarse grid :func:`unwrap_in_space` starts from.
COARSE_SIDE = 64

#: About how many spectrum bins :func:`floor_bins` samples per frame for the noise floor.
FLOOR_SAMPLES = 4096

#: :func:`phase_noise` averages over every this many rows and columns of a map.
NOISE_STRIDE = 4


@dataclass
class PhaseMap:
    """One peak's results between demodulation and unwrapping (mutable).

    Attributes
    ----------
    field : ndarray of complex64
        The demodulated field (counts).
    phase : ndarray of float32
        Phase against the reference (rad), wrapped until unwrapped.
    mask : ndarray of bool
        Trusted pixels.
    valid : int
        Number of trusted pixels.
    value : complex
        The field's mean against the sub-bin plane wave (counts).
    mean_phase : float
        Mean phase against the reference (rad, wrapped).
    target : float
        Where the map's mean should sit (rad): sets its 2 pi offset.
    flags : set of str
        Per-peak flags so far.
    live : bool
        False on a reference frame, whose phase is zero by definition.
    noise : float
        Phase noise per trusted pixel (rad, :func:`phase_noise`); 0 when not live.
    unwrapped : bool
        Whether spatial unwrapping ran on the map.
    """

    field: np.ndarray
    phase: np.ndarray
    mask: np.ndarray
    valid: int
    value: complex
    mean_phase: float
    target: float
    flags: set[str]
    live: bool
    noise: float
    unwrapped: bool = False


def wrapped_inside(phase: np.ndarray, mask: np.ndarray) -> bool:
    """Whether a map has wraps away from its edge (:data:`EDGE` pixels)."""
    e = EDGE if min(phase.shape) > 4 * EDGE else 0
    inner = (slice(e, phase.shape[0] - e), slice(e, phase.shape[1] - e))
    return has_wraps(phase[inner], mask[inner])


def guide_index(maps: Sequence[PhaseMap], peaks: Sequence[Peak]) -> int | None:
    """The peak whose map guides the others, or None when no map has a trusted pixel.

    Among peaks with trusted pixels: the one with a known alpha and the smallest
    ``|alpha| / amplitude`` (fewest wraps per unit of noise); with no alpha known,
    the brightest.
    """
    candidates = [i for i, m in enumerate(maps) if m.live and m.valid]
    with_alpha = [(i, a) for i in candidates if (a := peaks[i].alpha) is not None]
    if with_alpha:
        best, _ = min(
            with_alpha, key=lambda item: abs(item[1]) / max(peaks[item[0]].amplitude, 1e-30)
        )
        return best
    if candidates:
        return max(candidates, key=lambda i: peaks[i].amplitude)
    return None


def unwrap_in_space(phase: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, bool]:
    """Herraez on a decimated map (coarse grid of 64 pixels or more), finer if that fails.

    A map still wrapped after the coarse pass (away from the box's edge, where a
    non-periodic frame leaves the field unreliable) moved more than pi between
    coarse samples somewhere: it is done again on a twice finer grid, down to
    every pixel.

    Returns
    -------
    tuple
        The unwrapped map (rad) and whether unwrapping changed it.
    """
    decimate = max(1, min(phase.shape) // COARSE_SIDE)
    while True:
        unwrapped, changed = unwrap_spatial(phase, mask, decimate=decimate)
        if decimate == 1 or not wrapped_inside(unwrapped, mask):
            return unwrapped, changed
        decimate //= 2


def unwrap_maps(maps: Sequence[PhaseMap], peaks: Sequence[Peak], *, always: bool) -> None:
    """Unwrap, in place, the maps that need it: one in space, the others guided by it.

    The guide (:func:`guide_index`), when its map has wraps, is unwrapped in space
    (:func:`unwrap_in_space`). Every other wrapped map is then unwrapped against the
    guide scaled by the ratio of the two alphas
    (:func:`~holoview.processing.maps.unwrap.unwrap_guided`), a few array passes instead of
    a spatial unwrap. When an alpha is unknown the ratio is measured from the two
    maps' gradients (:func:`~holoview.processing.maps.unwrap.phase_ratio`), and a map still
    wrapped after that (another surface, or none) is unwrapped in space.

    Parameters
    ----------
    maps : sequence of PhaseMap
        One frame's maps, one per peak.
    peaks : sequence of Peak
        The peaks, in the same order (alpha and amplitude choose the guide).
    always : bool
        Unwrap every live map, not only those with wraps.
    """
    need = [m.live and (always or has_wraps(m.phase, m.mask)) for m in maps]
    if not any(need):
        return
    guide = guide_index(maps, peaks)
    if guide is None:
        return  # no trusted pixel anywhere: nothing worth unwrapping
    g = maps[guide]
    if need[guide]:
        g.phase, g.unwrapped = unwrap_in_space(g.phase, g.mask)
    guide_alpha = peaks[guide].alpha
    for i, m in enumerate(maps):
        if not need[i] or i == guide or not m.valid:
            continue
        alpha = peaks[i].alpha
        if alpha is not None and guide_alpha is not None:
            m.phase = unwrap_guided(m.phase, g.phase * (alpha / guide_alpha), m.mask)
            m.unwrapped = True
            continue
        ratio = phase_ratio(m.phase, g.phase, m.mask & g.mask)
        guided = unwrap_guided(m.phase, g.phase * np.float32(ratio), m.mask)
        if wrapped_inside(guided, m.mask):
            m.phase, m.unwrapped = unwrap_in_space(m.phase, m.mask)
        else:
            m.phase, m.unwrapped = guided, True


def floor_bins(shape: tuple[int, int]) -> np.ndarray:
    """Flat indices into a frame's half spectrum of about :data:`FLOOR_SAMPLES` spread bins.

    The bins lie on a regular grid offset from the axes (the zero order and the
    streaks along ``fx = 0`` and ``fy = 0`` that a non-periodic frame leaves); peaks
    cover a few percent of the spectrum, so most of these bins hold noise alone.
    """
    rows, cols = shape
    half = cols // 2 + 1
    stride = max(1, int(np.sqrt(rows * half / FLOOR_SAMPLES)))
    ky = np.arange(stride // 2, rows, stride)
    kx = np.arange(max(stride // 2, 1), half, stride)
    index = (ky[:, None] * half + kx[None, :]).astype(np.intp).ravel()
    index.setflags(write=False)
    return index


def floor_power(samples: np.ndarray, reference: np.ndarray | None = None) -> float:
    """Noise power per spectrum bin (counts^2) of a frame, or of its change since another.

    The median of ``|S - S_ref|^2`` over the :func:`floor_bins` (``|S|^2`` without a
    reference) over ln 2: for complex Gaussian noise ``|n|^2`` is exponential, whose
    median is ln 2 times its mean. What does not change between the two frames (fixed
    pattern, the zero order's structure) cancels, as it does in the phase difference.
    """
    d = samples if reference is None else samples - reference
    power = d.real * d.real + d.imag * d.imag
    return float(np.median(power)) / np.log(2)


def phase_noise(
    magnitude: np.ndarray, mask: np.ndarray, floor: float, area_fraction: float, size: int
) -> float:
    """Phase noise per trusted pixel (rad, rms) of a map, from the spectrum's noise floor.

    Noise of power ``floor`` per bin (:func:`floor_power`), passed by a window of area
    fraction ``eta`` (:func:`~holoview.processing.fourier.windows.area_fraction`), gives the
    field a noise of variance ``eta floor / size`` (counts^2, ``size = rows cols``),
    and a pixel of amplitude ``|f|`` a phase noise of variance ``eta floor / (2 size
    |f|^2)``; this returns its rms over the trusted pixels (every
    :data:`NOISE_STRIDE`-th row and column: plenty for an average). It measures the noise of the
    frames alone: unlike differences of the map, it does not grow with the surface's
    curvature.

    Returns
    -------
    float
        Noise (rad); NaN without a trusted pixel.
    """
    sample = (slice(None, None, NOISE_STRIDE), slice(None, None, NOISE_STRIDE))
    trusted = magnitude[sample][mask[sample]]
    if not trusted.size:
        trusted = magnitude[mask]
        if not trusted.size:
            return float("nan")
    inverse_power = float(np.mean(1.0 / (trusted.astype(np.float64) ** 2)))
    return float(np.sqrt(area_fraction * floor / (2.0 * size) * inverse_power))
