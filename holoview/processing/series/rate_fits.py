"""Rates from depth series: a line with an honest standard error, volumes, and display.

1. :func:`fit_rate` fits a line to a depth series; its standard error allows for noise
   correlated from frame to frame (lag-1 autocorrelation of the residuals).
2. :func:`depth_to_volume`, :func:`volume_to_depth` and :func:`compare_rate` relate a
   depth rate to a volume rate for a basin of known area: ``dV = A dh``, so a peak's
   phase moves by ``d phi = 2 k0 alpha dV / A`` (the paper's section 4.2 prints
   ``dV / (2 k0 alpha A)``, which is not dimensionally consistent).
3. :func:`format_rate` writes a rate and its standard error in um/min for people.

Times are in s, depths in m, rates in m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError

__all__ = [
    "UM_PER_MIN_PER_M_PER_S",
    "RateComparison",
    "RateFit",
    "check_times",
    "compare_rate",
    "depth_to_volume",
    "fit_rate",
    "format_rate",
    "line_fit",
    "volume_to_depth",
]


def check_times(times: ArrayLike, n_frames: int) -> NDArray[np.float64]:
    """Return frame times in s as floats, checked finite and strictly increasing."""
    t = np.asarray(times, dtype=np.float64)
    if t.shape != (n_frames,):
        raise InputError(f"{t.size} time stamps given for {n_frames} frames")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise InputError("time stamps must be finite and strictly increasing")
    return t


def line_fit(t: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[float, float, float]:
    """Least-squares line through ``(t, y)``.

    Parameters
    ----------
    t, y : ndarray of float, shape (n,)
        Times in s and values (any unit), all finite, ``n >= 3``.

    Returns
    -------
    tuple of float
        Slope (unit of ``y`` per s), intercept (unit of ``y``) and the residual RMS with
        ``n - 2`` degrees of freedom (unit of ``y``).
    """
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
    t = check_times(times, y.size)
    valid = np.isfinite(y)
    n = int(np.count_nonzero(valid))
    if n < 3:
        raise InputError(f"a rate needs at least three measured frames, got {n}")
    t, y = t[valid], y[valid]
    slope, intercept, rms = line_fit(t, y)
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
