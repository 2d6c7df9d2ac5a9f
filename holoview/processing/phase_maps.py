"""A peak's phase map between demodulation and result: unwrapping in space and noise.

:class:`PhaseMap` carries one peak's wrapped map of one frame. :func:`unwrap_maps`
unwraps the maps of a frame that need it: one (the guide, :func:`guide_index`) in
space (Herraez et al. 2002, :func:`unwrap_in_space`), the others against the guide
scaled by the ratio of their alphas. :func:`phase_noise` estimates a map's phase
noise per pixel (rad) from second differences.

Maps are at box resolution (:mod:`holoview.processing.boxes`); phases in rad.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from holoview.processing.peaks import Peak
from holoview.processing.unwrap import (
    EDGE,
    has_wraps,
    phase_ratio,
    unwrap_guided,
    unwrap_spatial,
)

__all__ = [
    "PhaseMap",
    "guide_index",
    "phase_noise",
    "unwrap_in_space",
    "unwrap_maps",
    "wrapped_inside",
]

#: Side (map pixels) of the coarse grid :func:`unwrap_in_space` starts from.
COARSE_SIDE = 64


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
    unwrapped: bool = False


def wrapped_inside(phase: np.ndarray, mask: np.ndarray) -> bool:
    """Whether a map has wraps away from its edge (:data:`~holoview.processing.unwrap.EDGE`)."""
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
    with_alpha = [i for i in candidates if peaks[i].alpha is not None]
    if with_alpha:
        return min(
            with_alpha,
            key=lambda i: abs(peaks[i].alpha) / max(peaks[i].amplitude, 1e-30),  # type: ignore[arg-type]
        )
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
    (:func:`~holoview.processing.unwrap.unwrap_guided`), a few array passes instead of
    a spatial unwrap. When an alpha is unknown the ratio is measured from the two
    maps' gradients (:func:`~holoview.processing.unwrap.phase_ratio`), and a map still
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


def phase_noise(phase: np.ndarray, mask: np.ndarray, noise_gain: float) -> float:
    """Phase noise per pixel (rad) from the spread of second differences along rows.

    Second differences cancel the surface's slope; for noise shaped by the window
    they have variance ``sigma^2 noise_gain`` with ``noise_gain = 6 - 8 rho1 + 2
    rho2``, ``rho1`` and ``rho2`` the window's noise correlation at lags 1 and 2
    (:class:`~holoview.processing.boxes.BoxGeometry`). Surface curvature adds to it,
    so the estimate errs on the high side. Every 4th or 8th row is used; differences
    beyond pi (wraps, untrusted pixels) are left out, and so are two pixels at the
    map's edge: where the frame is not periodic the field dips there and its phase
    is noisier than the rest.

    Returns
    -------
    float
        Noise (rad), NaN with fewer than two usable differences.
    """
    edge = 2 if min(phase.shape) > 16 else 0
    every = 8 if phase.shape[0] >= 128 else 4  # thousands of differences are plenty
    rows = phase[edge : phase.shape[0] - edge : every, edge : phase.shape[1] - edge]
    trusted = mask[edge : phase.shape[0] - edge : every, edge : phase.shape[1] - edge]
    second = rows[:, 2:] - 2 * rows[:, 1:-1] + rows[:, :-2]
    keep = trusted[:, 2:] & trusted[:, 1:-1] & trusted[:, :-2]
    keep &= np.abs(second) < np.pi
    count = int(np.count_nonzero(keep))
    if count < 2:
        return float("nan")
    second *= keep
    variance = float(np.vdot(second, second)) / count
    return float(np.sqrt(variance / noise_gain))
