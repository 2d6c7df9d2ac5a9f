"""Depth over time from the mean phase of each peak: depth series, fusion and the chain.

The complex value of the spectrum at a peak's carrier carries the spatial average of its
phase (paper section 4.2), so one complex number per peak and frame tracks the mean depth.
This module turns those numbers into physics:

1. the phases are unwrapped in time and checked for aliasing
   (:mod:`holoview.processing.series.phase_series`);
2. :func:`depth_series` converts phases to depth (``delta_h = delta_phi * wavelength /
   (4 pi alpha)``), :func:`series_noise` measures each peak's noise and
   :func:`fuse_depths` averages the peaks with weights ``1 / noise^2``;
3. rates and volumes come from :mod:`holoview.processing.series.rate_fits`.

:func:`track_depth` runs the whole chain. Times are in s, depths in m, phases in rad.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError
from holoview.processing.maps.heights import phase_to_height
from holoview.processing.series.phase_series import (
    DEFAULT_N_SIGMA,
    AliasingReport,
    check_aliasing,
    unwrap_in_time,
)
from holoview.processing.series.rate_fits import RateFit, check_times, fit_rate, line_fit

__all__ = ["DepthTrack", "FusedDepth", "depth_series", "fuse_depths", "series_noise", "track_depth"]

NoiseMethod = Literal["residual", "difference"]


def depth_series(phases: ArrayLike, alphas: ArrayLike, wavelength: float) -> NDArray[np.float64]:
    """Depth change per peak from its unwrapped phase.

    Parameters
    ----------
    phases : array_like of float, shape (N, M)
        Unwrapped phases in rad.
    alphas : array_like of float, shape (M,)
        Prefactor of each peak (dimensionless, non-zero).
    wavelength : float
        Laser wavelength in vacuum, in m.

    Returns
    -------
    ndarray of float, shape (N, M)
        ``phase * wavelength / (4 pi alpha)`` in m.
    """
    phase = np.asarray(phases, dtype=np.float64)
    alpha = np.asarray(alphas, dtype=np.float64)
    if phase.ndim != 2 or alpha.shape != (phase.shape[1],):
        raise InputError(
            f"phases (frames, peaks) {phase.shape} and alphas {alpha.shape} do not match"
        )
    depths = np.empty_like(phase)
    for m, value in enumerate(alpha):
        depths[:, m] = phase_to_height(phase[:, m], float(value), wavelength)
    return depths


def series_noise(
    depths: ArrayLike, times: ArrayLike, method: NoiseMethod = "residual"
) -> NDArray[np.float64]:
    """Noise of each peak's depth series, for the fusion weights.

    Parameters
    ----------
    depths : array_like of float, shape (N, M)
        Depth series in m; NaN where not measured.
    times : array_like of float, shape (N,)
        Frame times in s.
    method : {"residual", "difference"}
        ``"residual"``: RMS of the residual about the peak's own straight-line fit, which
        counts slow drifts and vibration as well as white noise (what matters for a rate;
        use it when the depth changes linearly). ``"difference"``: standard deviation of
        the frame-to-frame differences over sqrt(2), the white-noise level, blind to a
        changing trend (use it when the depth itself moves, e.g. waves).

    Returns
    -------
    ndarray of float, shape (M,)
        In m; NaN for a peak with fewer than three measured frames.
    """
    d = np.asarray(depths, dtype=np.float64)
    if d.ndim != 2:
        raise InputError(f"depths must be (frames, peaks), got shape {d.shape}")
    t = check_times(times, d.shape[0])
    noise = np.full(d.shape[1], np.nan)
    for m in range(d.shape[1]):
        valid = np.isfinite(d[:, m])
        if np.count_nonzero(valid) < 3:
            continue
        if method == "residual":
            noise[m] = line_fit(t[valid], d[valid, m])[2]
        elif method == "difference":
            noise[m] = float(np.std(np.diff(d[valid, m]), ddof=1)) / np.sqrt(2.0)
        else:
            raise InputError(f"unknown noise method {method!r}; use 'residual' or 'difference'")
    return noise


@dataclass(frozen=True)
class FusedDepth:
    """Depth fused over peaks.

    Attributes
    ----------
    depth : ndarray of float, shape (N,)
        Weighted mean depth change in m; NaN in a frame no used peak measured.
    weights : ndarray of float, shape (M,)
        Normalised weights ``1 / noise^2``; zero for peaks not used.
    noise : ndarray of float, shape (M,)
        The noise of each peak the weights came from, in m.
    used : ndarray of bool, shape (M,)
    spread : ndarray of float, shape (N,)
        Weighted RMS deviation of the used peaks from the fused depth, in m (the paper's
        shaded band).
    """

    depth: NDArray[np.float64]
    weights: NDArray[np.float64]
    noise: NDArray[np.float64]
    used: NDArray[np.bool_]
    spread: NDArray[np.float64]


def fuse_depths(
    depths: ArrayLike, noise: ArrayLike, *, exclude: ArrayLike | None = None
) -> FusedDepth:
    """Average the depth series of several peaks, weighted by ``1 / noise^2``.

    Parameters
    ----------
    depths : array_like of float, shape (N, M)
        Depth series in m, all relative to the same start; NaN where not measured (a
        frame's weights are renormalised over the peaks it has).
    noise : array_like of float, shape (M,)
        Noise of each peak in m (:func:`series_noise`); a NaN or non-positive noise
        leaves the peak out.
    exclude : array_like of bool, shape (M,), optional
        Peaks to leave out (for example those aliasing in time).

    Returns
    -------
    FusedDepth

    Raises
    ------
    InputError
        When no peak is left to fuse.
    """
    d = np.asarray(depths, dtype=np.float64)
    sigma = np.asarray(noise, dtype=np.float64)
    if d.ndim != 2 or sigma.shape != (d.shape[1],):
        raise InputError(f"depths {d.shape} and noise {sigma.shape} do not match")
    used = np.isfinite(sigma) & (sigma > 0)
    if exclude is not None:
        excluded = np.asarray(exclude, dtype=bool)
        if excluded.shape != sigma.shape:
            raise InputError(f"exclude has shape {excluded.shape}, expected {sigma.shape}")
        used &= ~excluded
    if not np.any(used):
        raise InputError("no peak left to fuse (all excluded or without a noise estimate)")
    raw = np.where(used, 1.0 / np.where(used, sigma, 1.0) ** 2, 0.0)
    present = np.isfinite(d) & used
    frame_weights = np.where(present, raw, 0.0)
    totals = frame_weights.sum(axis=1)
    filled = np.where(present, d, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        fused = np.where(totals > 0, (frame_weights * filled).sum(axis=1) / totals, np.nan)
        spread = np.sqrt(
            np.where(
                totals > 0,
                (frame_weights * (filled - fused[:, np.newaxis]) ** 2).sum(axis=1) / totals,
                np.nan,
            )
        )
    return FusedDepth(depth=fused, weights=raw / raw.sum(), noise=sigma, used=used, spread=spread)


@dataclass(frozen=True)
class DepthTrack:
    """The outcome of :func:`track_depth`.

    Attributes
    ----------
    times : ndarray of float, shape (N,)
        Frame times in s.
    depths : ndarray of float, shape (N, M)
        Depth change per peak in m.
    aliasing : AliasingReport
        The final aliasing check (with the model's predicted steps).
    fused : FusedDepth
        Fused over the peaks that do not alias.
    fit : RateFit
        Line fitted to the fused depth.
    peak_fits : tuple of (RateFit or None)
        Line fitted to each peak's own depth; None where it has too few frames.
    """

    times: NDArray[np.float64]
    depths: NDArray[np.float64]
    aliasing: AliasingReport
    fused: FusedDepth
    fit: RateFit
    peak_fits: tuple[RateFit | None, ...]


def track_depth(
    values: ArrayLike,
    times: ArrayLike,
    alphas: ArrayLike,
    wavelength: float,
    *,
    exclude: ArrayLike | None = None,
    noise_method: NoiseMethod = "residual",
    n_sigma: float = DEFAULT_N_SIGMA,
) -> DepthTrack:
    """Per-peak depth, aliasing flags, fused depth and its rate, from peak values.

    The aliasing check runs twice: first on the measured steps, then on the step each
    peak's alpha predicts from the rate of the slowest unflagged peak (smallest
    ``|alpha|``, the last to alias); peaks flagged either time are left out of the fusion.

    Parameters
    ----------
    values : array_like, shape (N, M)
        Complex value of each peak per frame (its phase is the peak's mean phase), or
        real wrapped phases in rad; NaN where not measured.
    times : array_like of float, shape (N,)
        Frame times in s.
    alphas : array_like of float, shape (M,)
        Prefactor of each peak (from labels or PCA), signed as the peaks are stored.
    wavelength : float
        Laser wavelength in vacuum, in m.
    exclude : array_like of bool, shape (M,), optional
        Peaks to leave out of the fusion besides those aliasing.
    noise_method : {"residual", "difference"}
        How each peak's noise is measured (:func:`series_noise`).
    n_sigma : float
        Aliasing margin (:func:`check_aliasing`).

    Returns
    -------
    DepthTrack
    """
    phases = unwrap_in_time(values)
    t = check_times(times, phases.shape[0])
    depths = depth_series(phases, alphas, wavelength)
    alpha = np.asarray(alphas, dtype=np.float64)
    noise = series_noise(depths, t, noise_method)
    first = check_aliasing(values, n_sigma=n_sigma)
    candidates = ~first.aliased & (np.count_nonzero(np.isfinite(depths), axis=0) >= 3)
    if exclude is not None:
        extra = np.asarray(exclude, dtype=bool)
        if extra.shape != candidates.shape:
            raise InputError(f"exclude has shape {extra.shape}, expected {candidates.shape}")
        candidates &= ~extra
    if not np.any(candidates):
        raise InputError("every peak aliases in time or is excluded: no depth to track")
    # The peak whose phase moves least per unit depth fixes the rate the others' steps are
    # predicted from: a peak past pi per frame unwraps to a wrong but clean-looking line.
    slowest = int(np.flatnonzero(candidates)[np.argmin(np.abs(alpha[candidates]))])
    rate = fit_rate(t, depths[:, slowest]).rate
    predicted = 4.0 * np.pi * alpha * rate * float(np.median(np.diff(t))) / wavelength
    second = check_aliasing(values, predicted_step=predicted, n_sigma=n_sigma)
    final = AliasingReport(
        step=second.step,
        measured_step=second.measured_step,
        noise=second.noise,
        margin=np.minimum(second.margin, first.margin),
        aliased=second.aliased | first.aliased,
    )
    fused = fuse_depths(depths, noise, exclude=~candidates | final.aliased)
    fit = fit_rate(t, fused.depth)
    peak_fits = tuple(
        fit_rate(t, depths[:, m]) if np.count_nonzero(np.isfinite(depths[:, m])) >= 3 else None
        for m in range(depths.shape[1])
    )
    return DepthTrack(
        times=t, depths=depths, aliasing=final, fused=fused, fit=fit, peak_fits=peak_fits
    )
