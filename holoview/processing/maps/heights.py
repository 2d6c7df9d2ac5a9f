"""From phases to heights: conversion and the fusion of co-registered maps.

Each peak images a laterally shifted patch of the surface (paper section 2:
``h_AB(r) = h(r + delta_AB)``); :mod:`holoview.processing.maps.coregister` measures those
shifts from many frames and moves the maps onto one grid. :func:`fuse` combines
co-registered maps weighted by their noise, with the per-pixel uncertainty.
:func:`plain_average` and :func:`rms_spread` are the paper's average and shaded spread
(its Fig. 3g), kept for comparison.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from holoview.errors import InputError


def phase_to_height(phase: np.ndarray | float, alpha: float, wavelength: float) -> np.ndarray:
    """Convert a phase change to a height change: ``delta_h = phase wavelength / (4 pi alpha)``.

    Parameters
    ----------
    phase : ndarray or float
        Phase change (rad); not modified.
    alpha : float
        The peak's prefactor (n1 for RF, j n2 for FB_j, j n2 - n1 for RB_j, sign by
        the twin, docs/design.md); nonzero.
    wavelength : float
        Laser wavelength (m).

    Returns
    -------
    ndarray
        Height change (m), float32 for a float32 input, else float64.
    """
    if not (np.isfinite(alpha) and alpha != 0):
        raise InputError(f"alpha must be finite and nonzero, got {alpha}")
    if not (np.isfinite(wavelength) and wavelength > 0):
        raise InputError(f"wavelength must be > 0 metres, got {wavelength}")
    p = np.asarray(phase)
    factor = wavelength / (4.0 * np.pi * alpha)
    if p.dtype == np.float32:
        return p * np.float32(factor)
    return p.astype(np.float64) * factor


def height_to_phase(delta_h: np.ndarray | float, alpha: float, wavelength: float) -> np.ndarray:
    """Invert :func:`phase_to_height`: phase change (rad) from height change (m)."""
    if not (np.isfinite(alpha) and alpha != 0):
        raise InputError(f"alpha must be finite and nonzero, got {alpha}")
    if not (np.isfinite(wavelength) and wavelength > 0):
        raise InputError(f"wavelength must be > 0 metres, got {wavelength}")
    return np.asarray(delta_h, dtype=np.float64) * (4.0 * np.pi * alpha / wavelength)


def _stack(maps: Sequence[np.ndarray], what: str = "maps") -> np.ndarray:
    if len(maps) == 0:
        raise InputError(f"no {what} given")
    arrays = [np.asarray(m, dtype=np.float64) for m in maps]
    shapes = {a.shape for a in arrays}
    if len(shapes) != 1 or arrays[0].ndim != 2:
        raise InputError(f"{what} must be 2-D and of one shape, got {sorted(shapes)}")
    return np.stack(arrays)


def fuse(
    maps: Sequence[np.ndarray],
    noises: Sequence[float | np.ndarray],
    *,
    masks: Sequence[np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Combine co-registered maps of one quantity, weighting each by its inverse variance.

    Parameters
    ----------
    maps : sequence of ndarray, shape (rows, cols)
        Co-registered maps (e.g. delta-h in m); not modified.
    noises : sequence of float or ndarray
        Each map's noise standard deviation, a number or per pixel (unit of the maps).
    masks : sequence of ndarray of bool, optional
        Trusted pixels of each map.

    Returns
    -------
    fused : ndarray of float64
        ``sum(w_i m_i) / sum(w_i)`` with ``w_i = 1 / noise_i^2``; NaN where no map is trusted.
    uncertainty : ndarray of float64
        ``1 / sqrt(sum(w_i))`` per pixel (standard deviation, unit of the maps);
        NaN where no map is trusted. Exact for independent noise.
    """
    stack = _stack(maps)
    if len(noises) != len(stack):
        raise InputError(f"{len(stack)} maps but {len(noises)} noise values")
    sigma = np.stack(
        [np.broadcast_to(np.asarray(n, dtype=np.float64), stack.shape[1:]) for n in noises]
    )
    if not (np.all(sigma > 0) and np.isfinite(sigma).all()):
        raise InputError("noise values must be finite and > 0")
    weights = 1.0 / sigma**2
    if masks is not None:
        if len(masks) != len(stack):
            raise InputError(f"{len(stack)} maps but {len(masks)} masks")
        trusted = np.stack([np.asarray(m, dtype=bool) for m in masks])
        if trusted.shape != stack.shape:
            raise InputError("masks must have the maps' shape")
        weights = np.where(trusted, weights, 0.0)
    weights = np.where(np.isfinite(stack), weights, 0.0)
    total = weights.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        fused = np.sum(weights * np.nan_to_num(stack), axis=0) / total
        uncertainty = 1.0 / np.sqrt(total)
    none = total == 0
    fused[none] = np.nan
    uncertainty[none] = np.nan
    return fused, uncertainty


def plain_average(maps: Sequence[np.ndarray]) -> np.ndarray:
    """Return the paper's plain average of the maps (unweighted mean per pixel)."""
    return _stack(maps).mean(axis=0)


def rms_spread(maps: Sequence[np.ndarray]) -> np.ndarray:
    """Return each map's rms deviation from the plain average, over the pixels (paper Fig. 3g).

    Returns
    -------
    ndarray of float64, shape (len(maps),)
        ``sqrt(<|m_i - mean|^2>_r)`` in the maps' unit.
    """
    stack = _stack(maps)
    deviation = stack - stack.mean(axis=0)
    return np.sqrt(np.mean(deviation**2, axis=(1, 2)))
