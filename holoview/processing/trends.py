"""Depth over time from the mean phase of each peak: unwrapping, fusion, rates, volumes.

The complex value of the spectrum at a peak's carrier carries the spatial average of its
phase (paper section 4.2), so one complex number per peak and frame tracks the mean depth.
This module turns those numbers into physics:

1. :func:`unwrap_in_time` adds the wrapped phase steps between consecutive frames; a step
   is only right while the true step stays under pi in magnitude.
2. :func:`check_aliasing` flags a peak whose step per frame comes near pi: its
   ``|step| + n_sigma * noise`` reaches pi (``n_sigma = 3`` by default), where ``step``
   is the median wrapped step, or the step the model predicts from the peak's alpha and
   a depth rate (which also catches a peak already past pi, whose wrapped step looks
   innocent), and ``noise`` the robust spread of its steps (1.4826 times their median
   absolute deviation).
3. :func:`depth_series` converts phases to depth (``delta_h = delta_phi * wavelength /
   (4 pi alpha)``), :func:`series_noise` measures each peak's noise and
   :func:`fuse_depths` averages the peaks with weights ``1 / noise^2``.
4. :func:`fit_rate` fits a line to a depth series; its standard error allows for noise
   correlated from frame to frame (lag-1 autocorrelation of the residuals).
5. :func:`depth_to_volume`, :func:`volume_to_depth` and :func:`compare_rate` relate a
   depth rate to a volume rate for a basin of known area: ``dV = A dh``, so a peak's
   phase moves by ``d phi = 2 k0 alpha dV / A`` (the paper's section 4.2 prints
   ``dV / (2 k0 alpha A)``, which is not dimensionally consistent).

:func:`track_depth` runs the whole chain. Times are in s, depths in m, phases in rad.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError
from holoview.processing.heights import phase_to_height

logger = logging.getLogger(__name__)

__all__ = [
    "AliasingReport",
    "DepthTrack",
    "FusedDepth",
    "RateComparison",
    "RateFit",
    "check_aliasing",
    "compare_rate",
    "depth_series",
    "depth_to_volume",
    "fit_rate",
    "fuse_depths",
    "phase_steps",
    "series_noise",
    "track_depth",
    "unwrap_in_time",
    "volume_to_depth",
]

#: Default number of step-noise standard deviations kept clear of pi (see
#: :func:`check_aliasing`): 3 leaves about one wrong unwrap per 700 frames of Gaussian noise.
DEFAULT_N_SIGMA = 3.0

#: Converts a median absolute deviation into a Gaussian standard deviation.
_MAD_TO_STD = 1.4826

NoiseMethod = Literal["residual", "difference"]


def _as_unit_phasors(values: ArrayLike) -> NDArray[np.complex128]:
    """Complex peak values as they are, or real wrapped phases (rad) as unit phasors."""
    array = np.asarray(values)
    if np.iscomplexobj(array):
        return array.astype(np.complex128)
    return np.exp(1j * array.astype(np.float64))


def _as_series(values: ArrayLike, what: str) -> NDArray[np.complex128]:
    """Check a ``(frames, peaks)`` series of at least two frames."""
    array = _as_unit_phasors(values)
    if array.ndim == 1:
        array = array[:, np.newaxis]
    if array.ndim != 2:
        raise InputError(f"{what} must be (frames, peaks), got shape {array.shape}")
    if array.shape[0] < 2:
        raise InputError(f"{what} has {array.shape[0]} frame; a time series needs at least two")
    if array.shape[1] < 1:
        raise InputError(f"{what} has no peaks")
    return array


def phase_steps(values: ArrayLike) -> NDArray[np.float64]:
    """Wrapped phase steps between consecutive frames, per peak.

    Parameters
    ----------
    values : array_like, shape (N, M)
        Complex value of each of ``M`` peaks in ``N`` frames, or real wrapped phases in
        rad. NaN marks a frame where a peak was not measured.

    Returns
    -------
    ndarray of float, shape (N - 1, M)
        ``angle(z[t + 1] conj(z[t]))`` in rad, in (-pi, pi]; NaN next to a missing frame.
    """
    z = _as_series(values, "peak values")
    return np.angle(z[1:] * np.conj(z[:-1]))


def unwrap_in_time(values: ArrayLike) -> NDArray[np.float64]:
    """Mean phase of each peak unwrapped in time, zero at its first measured frame.

    Parameters
    ----------
    values : array_like, shape (N, M)
        Complex value of each peak per frame, or real wrapped phases in rad; NaN where a
        peak was not measured (the unwrapping steps over the gap).

    Returns
    -------
    ndarray of float, shape (N, M)
        Phase in rad; NaN where the input is NaN.

    Raises
    ------
    InputError
        For a series of fewer than two frames, or a peak never measured.
    """
    z = _as_series(values, "peak values")
    out = np.full(z.shape, np.nan)
    for m in range(z.shape[1]):
        valid = np.flatnonzero(np.isfinite(z[:, m]))
        if valid.size == 0:
            raise InputError(f"peak {m} has no measured frame")
        column = z[valid, m]
        steps = np.angle(column[1:] * np.conj(column[:-1]))
        out[valid, m] = np.concatenate([[0.0], np.cumsum(steps)])
    return out


@dataclass(frozen=True)
class AliasingReport:
    """Whether each peak's phase steps come near pi per frame.

    Attributes
    ----------
    step : ndarray of float, shape (M,)
        The step judged, in rad per frame: the model's prediction where one was given
        (finite), else the median wrapped step.
    measured_step : ndarray of float, shape (M,)
        Median wrapped step, in rad per frame.
    noise : ndarray of float, shape (M,)
        Robust standard deviation of the wrapped steps, in rad.
    margin : ndarray of float, shape (M,)
        ``pi - (|step| + n_sigma * noise)`` in rad: negative when flagged.
    aliased : ndarray of bool, shape (M,)
        True for peaks whose phase aliases (or risks aliasing) in time.
    """

    step: NDArray[np.float64]
    measured_step: NDArray[np.float64]
    noise: NDArray[np.float64]
    margin: NDArray[np.float64]
    aliased: NDArray[np.bool_]


def check_aliasing(
    values: ArrayLike,
    *,
    predicted_step: ArrayLike | None = None,
    n_sigma: float = DEFAULT_N_SIGMA,
) -> AliasingReport:
    """Flag peaks whose phase step per frame comes near pi.

    Parameters
    ----------
    values : array_like, shape (N, M)
        Complex value of each peak per frame, or real wrapped phases in rad.
    predicted_step : array_like of float, shape (M,), optional
        Step per frame the model expects for each peak, in rad (for example
        ``4 pi alpha * rate * frame_interval / wavelength``). Catches a peak whose true
        step is past pi, which the wrapped steps alone cannot show. NaN entries fall back
        to the measured step.
    n_sigma : float
        How many standard deviations of step noise must stay clear of pi.

    Returns
    -------
    AliasingReport
    """
    steps = phase_steps(values)
    n_peaks = steps.shape[1]
    measured = np.full(n_peaks, np.nan)
    noise = np.full(n_peaks, np.nan)
    for m in range(n_peaks):
        column = steps[np.isfinite(steps[:, m]), m]
        if column.size == 0:
            continue
        # The median direction on the circle, then the spread about it (no wrap at pi).
        centre = float(np.angle(np.mean(np.exp(1j * column))))
        deviation = np.angle(np.exp(1j * (column - centre)))
        offset = float(np.median(deviation))
        measured[m] = centre + offset
        noise[m] = _MAD_TO_STD * float(np.median(np.abs(deviation - offset)))
    step = measured.copy()
    if predicted_step is not None:
        predicted = np.asarray(predicted_step, dtype=np.float64)
        if predicted.shape != (n_peaks,):
            raise InputError(f"{predicted.size} predicted steps given for {n_peaks} peaks")
        step = np.where(np.isfinite(predicted), predicted, measured)
    margin = np.pi - (np.abs(step) + n_sigma * noise)
    aliased = ~(margin > 0)  # a peak with no valid step counts as aliased
    if np.any(aliased):
        logger.info("peaks aliasing in time: %s", np.flatnonzero(aliased).tolist())
    return AliasingReport(
        step=step, measured_step=measured, noise=noise, margin=margin, aliased=aliased
    )


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


def _check_times(times: ArrayLike, n_frames: int) -> NDArray[np.float64]:
    t = np.asarray(times, dtype=np.float64)
    if t.shape != (n_frames,):
        raise InputError(f"{t.size} time stamps given for {n_frames} frames")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise InputError("time stamps must be finite and strictly increasing")
    return t


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
    t = _check_times(times, d.shape[0])
    noise = np.full(d.shape[1], np.nan)
    for m in range(d.shape[1]):
        valid = np.isfinite(d[:, m])
        if np.count_nonzero(valid) < 3:
            continue
        if method == "residual":
            noise[m] = _line_fit(t[valid], d[valid, m])[2]
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


def _line_fit(t: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[float, float, float]:
    """Least-squares slope, intercept and residual RMS (n - 2 degrees of freedom)."""
    t0 = t.mean()
    dt = t - t0
    slope = float(np.dot(dt, y - y.mean()) / np.dot(dt, dt))
    intercept = float(y.mean() - slope * t0)
    residual = y - (intercept + slope * t)
    return slope, intercept, float(np.sqrt(np.sum(residual**2) / (t.size - 2)))


@dataclass(frozen=True)
class RateFit:
    """A straight line fitted to a depth series.

    Attributes
    ----------
    rate : float
        Slope in m/s (negative while the fluid evaporates).
    stderr : float
        Standard error of the slope in m/s, widened by ``sqrt((1 + r) / (1 - r))`` for a
        positive lag-1 autocorrelation ``r`` of the residuals.
    intercept : float
        Depth at ``t = 0`` in m.
    residual_rms : float
        RMS of the residuals in m.
    lag1 : float
        Lag-1 autocorrelation of the residuals (dimensionless).
    n_frames : int
        Frames used.
    """

    rate: float
    stderr: float
    intercept: float
    residual_rms: float
    lag1: float
    n_frames: int

    def relative_error(self, truth: float) -> float:
        """``|rate / truth - 1|`` for a known rate ``truth`` in m/s."""
        if truth == 0:
            raise InputError("the true rate is zero: a relative error is undefined")
        return abs(self.rate / truth - 1.0)


def fit_rate(times: ArrayLike, depth: ArrayLike) -> RateFit:
    """Fit ``depth = intercept + rate * t`` and give the rate's standard error.

    Parameters
    ----------
    times : array_like of float, shape (N,)
        Frame times in s (need not be evenly spaced).
    depth : array_like of float, shape (N,)
        Depth in m; NaN frames are left out.

    Returns
    -------
    RateFit

    Raises
    ------
    InputError
        With fewer than three measured frames.
    """
    y = np.asarray(depth, dtype=np.float64)
    if y.ndim != 1:
        raise InputError(f"a depth series must be 1-D, got shape {y.shape}")
    t = _check_times(times, y.size)
    valid = np.isfinite(y)
    n = int(np.count_nonzero(valid))
    if n < 3:
        raise InputError(f"a rate needs at least three measured frames, got {n}")
    t, y = t[valid], y[valid]
    slope, intercept, rms = _line_fit(t, y)
    residual = y - (intercept + slope * t)
    denominator = float(np.dot(residual, residual))
    lag1 = float(np.dot(residual[1:], residual[:-1]) / denominator) if denominator > 0 else 0.0
    lag1 = min(lag1, 0.99)
    inflation = np.sqrt((1.0 + lag1) / (1.0 - lag1)) if lag1 > 0 else 1.0
    dt = t - t.mean()
    stderr = rms / np.sqrt(float(np.dot(dt, dt))) * inflation
    return RateFit(
        rate=slope,
        stderr=float(stderr),
        intercept=intercept,
        residual_rms=rms,
        lag1=lag1,
        n_frames=n,
    )


def depth_to_volume(depth: ArrayLike, area: float) -> NDArray[np.float64]:
    """Volume change in m^3 of a basin of ``area`` m^2 whose depth changes by ``depth`` m."""
    if not area > 0:
        raise InputError(f"basin area must be positive, got {area} m^2")
    return np.asarray(depth, dtype=np.float64) * area


def volume_to_depth(volume: ArrayLike, area: float) -> NDArray[np.float64]:
    """Depth change in m of a basin of ``area`` m^2 whose volume changes by ``volume`` m^3."""
    if not area > 0:
        raise InputError(f"basin area must be positive, got {area} m^2")
    return np.asarray(volume, dtype=np.float64) / area


@dataclass(frozen=True)
class RateComparison:
    """A measured volume rate against a known one (for example a syringe pump).

    Attributes
    ----------
    measured : float
        Volume rate from the depth fit, in m^3/s.
    stderr : float
        Its standard error, in m^3/s.
    expected : float
        The known rate, in m^3/s.
    relative_error : float
        ``measured / expected - 1`` (signed).
    z_score : float
        ``(measured - expected) / stderr``.
    """

    measured: float
    stderr: float
    expected: float
    relative_error: float
    z_score: float


def compare_rate(fit: RateFit, area: float, expected_volume_rate: float) -> RateComparison:
    """Compare a depth-rate fit with a known volume rate for a basin of ``area`` m^2.

    Parameters
    ----------
    fit : RateFit
        Fit of the depth series (m/s).
    area : float
        Cross-section of the basin in m^2.
    expected_volume_rate : float
        Known volume rate in m^3/s (positive for an injection).
    """
    if expected_volume_rate == 0:
        raise InputError("the expected volume rate is zero: nothing to compare against")
    measured = float(depth_to_volume(fit.rate, area))
    stderr = float(depth_to_volume(fit.stderr, area))
    return RateComparison(
        measured=measured,
        stderr=stderr,
        expected=float(expected_volume_rate),
        relative_error=measured / expected_volume_rate - 1.0,
        z_score=(measured - expected_volume_rate) / stderr if stderr > 0 else float("inf"),
    )


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
    t = _check_times(times, phases.shape[0])
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


#: Metres per second to micrometres per minute.
UM_PER_MIN_PER_M_PER_S = 60e6


def format_rate(
    rate_m_per_s: float | None, stderr_m_per_s: float | None, *, ascii: bool = False
) -> str:
    """Return a rate with its standard error in micrometres per minute, for people.

    Both are rounded to the second significant digit of the standard error, so the
    uncertainty never reads as zero: ``-0.81580 ± 0.00013 µm/min``.

    Parameters
    ----------
    rate_m_per_s, stderr_m_per_s : float or None
        Rate and its standard error, metres per second. A missing or non-finite rate
        gives ``"n/a"``; a missing standard error is shown with three decimals.
    ascii : bool
        Write ``+-`` and ``um/min`` (for renderers without those glyphs).

    Returns
    -------
    str
    """
    if rate_m_per_s is None or not math.isfinite(rate_m_per_s):
        return "n/a"
    rate = rate_m_per_s * UM_PER_MIN_PER_M_PER_S
    err = abs(stderr_m_per_s or 0.0) * UM_PER_MIN_PER_M_PER_S
    decimals = 3
    if err > 0 and math.isfinite(err):
        decimals = min(12, max(0, 1 - math.floor(math.log10(err))))
    plus_minus, unit = ("+-", "um/min") if ascii else ("±", "µm/min")
    return f"{rate:+.{decimals}f} {plus_minus} {err:.{decimals}f} {unit}"
