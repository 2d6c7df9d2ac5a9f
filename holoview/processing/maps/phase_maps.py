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

from holoview.processing.fourier.fastmath import TWO_PI
from holoview.processing.maps.unwrap import (
    EDGE,
    has_wraps,
    phase_ratio,
    unwrap_guided,
    unwrap_spatial,
    wrap_bounds,
)
from holoview.processing.peaks.detection import Peak

__all__ = [
    "PhaseMap",
    "floor_grid",
    "floor_power",
    "guide_index",
    "median_magnitude",
    "phase_noise",
    "unwrap_in_space",
    "unwrap_maps",
    "wrapped_inside",
]

#: Side (map pixels) of the coarse grid :func:`unwrap_in_space` starts from.
COARSE_SIDE = 64

#: :func:`unwrap_in_space` unwraps only the rectangle around the wraps when it is at most
#: this fraction of the map (else the whole map).
REGION_FRACTION = 0.5

#: Pixels around the wraps' rectangle that :func:`unwrap_in_space` unwraps with it (at
#: least the decimation's step).
REGION_MARGIN = EDGE + 1

#: About how many spectrum bins :func:`floor_grid` samples per frame for the noise floor.
FLOOR_SAMPLES = 4096

#: Columns of the half spectrum :func:`floor_grid` samples.
FLOOR_COLUMNS = 16

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
        Whether spatial unwrapping ran on the map (only then is :attr:`phase` replaced).
    wraps : bool or None
        Whether the map as demodulated has wraps
        (:func:`~holoview.processing.maps.unwrap.has_wraps`), when checked then (while
        the map is still in cache); None when not checked.
    level : float or None
        The mean phase of the trusted pixels of the map as demodulated (rad), when taken
        then; None when not.
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
    wraps: bool | None = None
    level: float | None = None


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


def unwrap_in_space(
    phase: np.ndarray, mask: np.ndarray, *, bounds: tuple[int, int, int, int] | None = None
) -> tuple[np.ndarray, bool]:
    """Herraez on a decimated map (coarse grid of 64 pixels or more), finer if that fails.

    Only the rectangle around the wraps (:func:`~holoview.processing.maps.unwrap.wrap_bounds`,
    with a margin) is unwrapped when it is at most :data:`REGION_FRACTION` of the map:
    outside it no neighbours are pi apart, so the rectangle's unwrapped values are put
    by whole turns where its rim meets the rest unchanged (when the rim does not agree
    on one turn, the whole map is unwrapped). A map still wrapped after the coarse pass
    (away from the box's edge, where a non-periodic frame leaves the field unreliable)
    moved more than pi between coarse samples somewhere: it is done again on a twice
    finer grid, down to every pixel.

    Parameters
    ----------
    phase : ndarray of float32, shape (rows, cols)
        Wrapped phase (rad); not modified.
    mask : ndarray of bool, shape (rows, cols)
        Trusted pixels.
    bounds : tuple of int, optional
        The map's :func:`~holoview.processing.maps.unwrap.wrap_bounds`, when known.

    Returns
    -------
    tuple
        The unwrapped map (rad) and whether unwrapping changed it.
    """
    if bounds is None:
        bounds = wrap_bounds(phase, mask)
        if bounds is None:
            return phase, False
    decimate = max(1, min(phase.shape) // COARSE_SIDE)
    region = _region(phase.shape, bounds, max(REGION_MARGIN, decimate))
    if region is not None:
        unwrapped = _unwrap_region(phase, mask, region, decimate)
        if unwrapped is not None:
            return unwrapped, True
    while True:
        unwrapped, changed = unwrap_spatial(phase, mask, decimate=decimate)
        if decimate == 1 or not wrapped_inside(unwrapped, mask):
            return unwrapped, changed
        decimate //= 2


def _region(
    shape: tuple[int, ...], bounds: tuple[int, int, int, int], margin: int
) -> tuple[slice, slice] | None:
    """The wraps' rectangle with a margin, or None when it is too large to be worth it."""
    rows, cols = shape
    top, bottom, left, right = bounds
    r = slice(max(0, top - margin), min(rows, bottom + 1 + margin))
    c = slice(max(0, left - margin), min(cols, right + 1 + margin))
    area = (r.stop - r.start) * (c.stop - c.start)
    return (r, c) if area <= REGION_FRACTION * rows * cols else None


def _unwrap_region(
    phase: np.ndarray, mask: np.ndarray, region: tuple[slice, slice], decimate: int
) -> np.ndarray | None:
    """The map unwrapped in ``region`` only (:func:`unwrap_in_space`), or None."""
    rows, cols = region
    sub, sub_mask = phase[rows, cols], mask[rows, cols]
    rim = np.zeros(sub.shape, dtype=bool)  # the rectangle's sides that meet the rest
    rim[0, :] |= rows.start > 0
    rim[-1, :] |= rows.stop < phase.shape[0]
    rim[:, 0] |= cols.start > 0
    rim[:, -1] |= cols.stop < phase.shape[1]
    rim &= sub_mask
    if not rim.any():
        return None
    # the wraps' rectangle and the pairs across its sides, away from the map's edge
    e = EDGE if min(phase.shape) > 4 * EDGE else 0
    check = (
        slice(max(e, rows.start - 1), min(phase.shape[0] - e, rows.stop + 1)),
        slice(max(e, cols.start - 1), min(phase.shape[1] - e, cols.stop + 1)),
    )
    while True:
        unwrapped, _ = unwrap_spatial(sub, sub_mask, decimate=decimate)
        turns = np.rint((unwrapped - sub) * np.float32(1 / TWO_PI))
        at_rim = turns[rim]
        if at_rim.min() != at_rim.max():
            return None
        turns -= at_rim[0]
        result = np.array(phase, dtype=np.float32)
        result[rows, cols] = sub + TWO_PI * turns.astype(np.float64)
        if decimate == 1 or not has_wraps(result[check], mask[check]):
            return result
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
    guide = guide_index(maps, peaks)
    if guide is None:
        return  # no trusted pixel anywhere: nothing worth unwrapping
    g = maps[guide]
    # where the guide's wraps are (its rectangle is unwrapped), whether the others have any
    bounds = None if g.wraps is False else wrap_bounds(g.phase, g.mask)
    need = [
        m.live and (always or (bounds is not None if i == guide else _has_wraps(m)))
        for i, m in enumerate(maps)
    ]
    if not any(need):
        return
    if bounds is not None:
        g.phase, g.unwrapped = unwrap_in_space(g.phase, g.mask, bounds=bounds)
    guide_alpha = peaks[guide].alpha
    for i, m in enumerate(maps):
        if not need[i] or i == guide or not m.valid:
            continue
        alpha = peaks[i].alpha
        if alpha is not None and guide_alpha is not None:
            m.phase = unwrap_guided(m.phase, g.phase, m.mask, scale=alpha / guide_alpha)
            m.unwrapped = True
            continue
        ratio = phase_ratio(m.phase, g.phase, m.mask & g.mask)
        guided = unwrap_guided(m.phase, g.phase, m.mask, scale=ratio)
        if wrapped_inside(guided, m.mask):
            m.phase, m.unwrapped = unwrap_in_space(m.phase, m.mask)
        else:
            m.phase, m.unwrapped = guided, True


def _has_wraps(part: PhaseMap) -> bool:
    """Whether a map has wraps: as checked when it was demodulated, else now."""
    return has_wraps(part.phase, part.mask) if part.wraps is None else part.wraps


def floor_grid(shape: tuple[int, int]) -> tuple[slice, slice]:
    """Rows and columns of a frame's half spectrum sampled for its noise floor.

    Every row with every column: a grid of about :data:`FLOOR_SAMPLES` spread bins, on
    :data:`FLOOR_COLUMNS` columns (few columns: each costs an FFT along the rows,
    :class:`~holoview.processing.fourier.half_spectrum.HalfSpectrum`). The grid is offset
    from the axes (the zero order and the streaks along ``fx = 0`` and ``fy = 0`` that a
    non-periodic frame leaves); peaks cover a few percent of the spectrum, so most of
    these bins hold noise alone.

    Returns
    -------
    tuple of slice
        The rows and the columns of the half spectrum, ``(rows, cols // 2 + 1)``.
    """
    rows, cols = shape
    half = cols // 2 + 1
    col_stride = max(1, half // FLOOR_COLUMNS)
    col_start = max(col_stride // 2, 1)
    count = min(FLOOR_COLUMNS, len(range(col_start, half, col_stride)))
    row_stride = max(1, rows * count // FLOOR_SAMPLES)
    return (
        slice(max(row_stride // 2, 1), rows, row_stride),
        slice(col_start, col_start + col_stride * (count - 1) + 1, col_stride),
    )


def floor_power(samples: np.ndarray, reference: np.ndarray | None = None) -> float:
    """Noise power per spectrum bin (counts^2) of a frame, or of its change since another.

    The median of ``|S - S_ref|^2`` over the :func:`floor_grid` (``|S|^2`` without a
    reference) over ln 2: for complex Gaussian noise ``|n|^2`` is exponential, whose
    median is ln 2 times its mean. What does not change between the two frames (fixed
    pattern, the zero order's structure) cancels, as it does in the phase difference.
    """
    d = np.asarray(samples if reference is None else samples - reference)
    power = d.real * d.real
    power += d.imag * d.imag
    return _median(power) / np.log(2)


def _median(values: np.ndarray) -> float:
    """``np.median`` of a 1-D array of numbers that it reorders (no copy, no NaN check)."""
    k = values.size // 2
    if values.size % 2:
        values.partition(k)
        return float(values[k])
    values.partition((k - 1, k))
    return float((values[k - 1] + values[k]) / 2)


def median_magnitude(power: np.ndarray) -> float:
    """Return the median of ``sqrt(power)`` (``np.median`` of the magnitudes) from ``|f|^2``."""
    flat = np.array(power).reshape(-1)  # a copy, reordered
    k = flat.size // 2
    if flat.size % 2:
        flat.partition(k)
        return float(np.sqrt(flat[k]))
    flat.partition((k - 1, k))
    return float((np.sqrt(flat[k - 1]) + np.sqrt(flat[k])) / 2)


def phase_noise(
    power: np.ndarray, mask: np.ndarray, floor: float, area_fraction: float, size: int
) -> float:
    """Phase noise per trusted pixel (rad, rms) of a map, from the spectrum's noise floor.

    Noise of power ``floor`` per bin (:func:`floor_power`), passed by a window of area
    fraction ``eta`` (:func:`~holoview.processing.fourier.windows.area_fraction`), gives the
    field a noise of variance ``eta floor / size`` (counts^2, ``size = rows cols``),
    and a pixel of power ``|f|^2`` a phase noise of variance ``eta floor / (2 size
    |f|^2)``; this returns its rms over the trusted pixels (every
    :data:`NOISE_STRIDE`-th row and column: plenty for an average). It measures the noise of the
    frames alone: unlike differences of the map, it does not grow with the surface's
    curvature.

    Parameters
    ----------
    power : ndarray
        The field's ``|f|^2`` per pixel (counts^2).
    mask : ndarray of bool
        Trusted pixels.
    floor : float
        Noise power per spectrum bin (counts^2).
    area_fraction : float
        The window's area fraction.
    size : int
        Pixels in the frame.

    Returns
    -------
    float
        Noise (rad); NaN without a trusted pixel.
    """
    sample = (slice(None, None, NOISE_STRIDE), slice(None, None, NOISE_STRIDE))
    trusted = power[sample][mask[sample]]
    if not trusted.size:
        trusted = power[mask]
        if not trusted.size:
            return float("nan")
    inverse_power = float(np.reciprocal(trusted, dtype=np.float64).sum()) / trusted.size
    return float(np.sqrt(area_fraction * floor / (2.0 * size) * inverse_power))
