"""Rates from depth series: a line with an honest standard error, volumes, and display.

1. :func:`fit_rate` fits a line to a depth series; its standard error allows for noise
   correlated from frame to frame: an AR(1) noise whose correlation is read from the
   residuals, corrected for the fit's own pull on them (which matters on short records).
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
from scipy.linalg import lapack

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
        Standard error of the slope in m/s, for noise of lag-1 correlation ``lag1`` from
        frame to frame (AR(1)): about ``sqrt((1 + r) / (1 - r))`` times the white-noise
        error on long records.
    intercept : float
        Depth at ``t = 0`` in m.
    residual_rms : float
        RMS of the residuals in m.
    lag1 : float
        Lag-1 correlation of the noise, from frame to frame (dimensionless, 0 to 0.99):
        the residuals' own, corrected for the line fit, which pulls it low (by
        ``(2 + 3 r) / n`` on ``n`` frames of a long record; more on a short one).
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
    rho, trace, slope_factor = noise_correlation(t, y - (intercept + slope * t))
    variance = rms * rms * (n - 2) / trace  # of the noise, per frame
    stderr = math.sqrt(variance * slope_factor)
    return RateFit(
        rate=slope,
        stderr=float(stderr),
        intercept=intercept,
        residual_rms=rms,
        lag1=rho,
        n_frames=n,
    )


#: The largest noise correlation :func:`fit_rate` allows (a random walk has 1).
MAX_CORRELATION = 0.99


def noise_correlation(
    t: NDArray[np.float64], residual: NDArray[np.float64]
) -> tuple[float, float, float]:
    """The lag-1 correlation of AR(1) noise whose line-fit residuals are ``residual``.

    A line fitted to ``n`` frames takes two degrees of freedom from the noise, and so the
    residuals' lag-1 autocorrelation ``r`` falls short of the noise's own ``rho``: by
    ``(2 + 3 rho) / n`` on long records, more on short ones (0.2 of 0.5 on 20 frames).
    This returns the ``rho`` whose expected ``r``, ``E[e' M A M e] / E[e' M e]`` for the
    fit's projector ``M`` and the lag-1 form ``A``, is the one measured (a secant from
    the long-record correction: one solve on long records); 0 where ``r`` is below what
    white noise gives.

    Parameters
    ----------
    t : ndarray of float, shape (n,)
        Frame times in s, ``n >= 3``.
    residual : ndarray of float, shape (n,)
        The line fit's residuals, in frame order.

    Returns
    -------
    (float, float, float)
        ``rho`` in ``[0, MAX_CORRELATION]``; at that ``rho``, the residuals' expected sum
        of squares per unit noise variance, ``tr(M C)``; and the slope's variance per
        unit noise variance, ``w' C w`` (s^-2), for the noise's correlation ``C``.
    """
    model = _model_of(t)
    total = float(np.dot(residual, residual))
    measured = float(np.dot(residual[1:], residual[:-1])) / total if total > 0 else 0.0
    moments = model.moments(0.0)
    if moments[1] >= measured:
        return 0.0, moments[0], moments[2]
    rho = min(max(measured + (2.0 + 3.0 * measured) / t.size, 0.0), MAX_CORRELATION)
    last: tuple[float, float] | None = None
    for _ in range(40):
        moments = model.moments(rho)
        excess = moments[1] - measured
        slope = 1.0 if last is None else (excess - last[1]) / (rho - last[0])
        step = -excess / slope if slope > 0 else -excess
        following = min(max(rho + step, 0.0), MAX_CORRELATION)
        if abs(step) < 1e-4 or following == rho:
            break
        last, rho = (rho, excess), following
    return rho, moments[0], moments[2]


def _model_of(t: NDArray[np.float64]) -> _ResidualModel:
    """The residual model of frame times ``t``: the last one made where ``t`` is the same
    (the peaks of a series share their times: a live trends update fits seven rates on
    up to 36000 frames, 1.5 ms a model)."""
    last = _last_model.get("times")
    if last is not None and last[0].shape == t.shape and np.array_equal(last[0], t):
        return last[1]
    model = _ResidualModel(t)
    _last_model["times"] = (t.copy(), model)  # replaced whole: a thread sees one or the other
    return model


class _ResidualModel:
    """What a line fit leaves of AR(1) noise on given frame times, per unit variance.

    For the projector ``M = I - Q Q'`` off an orthonormal basis ``Q`` of the fit's columns
    (1 and ``t``), the noise's correlation ``C[i, j] = rho ** |i - j|`` (frame order) and
    the symmetric lag-1 form ``A`` (1/2 beside the diagonal).
    """

    def __init__(self, t: NDArray[np.float64]) -> None:
        dt = t - t.mean()
        self.spread = float(np.dot(dt, dt))
        self.basis = np.column_stack([np.full(t.size, 1.0 / math.sqrt(t.size)), dt])
        self.basis[:, 1] /= math.sqrt(self.spread)
        self.lagged_basis = np.zeros_like(self.basis)  # A Q
        self.lagged_basis[1:] += 0.5 * self.basis[:-1]
        self.lagged_basis[:-1] += 0.5 * self.basis[1:]
        self.qaq = self.basis.T @ self.lagged_basis

    def moments(self, rho: float) -> tuple[float, float, float]:
        """``tr(M C)``, ``tr(M A M C) / tr(M C)`` (the expected ``r``) and ``w' C w``.

        ``w = (t - mean) / spread`` gives the slope. ``C``'s inverse is tridiagonal:
        ``(1 + rho^2)`` on the diagonal (1 at both ends) and ``-rho`` beside it, over
        ``1 - rho^2``; so ``C Q`` is one tridiagonal solve, ``O(n)``.
        """
        n = self.basis.shape[0]
        if rho == 0.0:  # C = I, and Q is orthonormal
            return n - 2.0, -float(np.trace(self.qaq)) / (n - 2.0), 1.0 / self.spread
        diagonal = np.full(n, 1.0 + rho * rho)
        diagonal[[0, -1]] = 1.0
        beside = np.full(n - 1, -rho)
        cq = lapack.dgtsv(beside, diagonal, beside, (1.0 - rho * rho) * self.basis)[3]
        qcq = self.basis.T @ cq
        trace = n - float(np.trace(qcq))
        lagged = (n - 1) * rho - 2.0 * float(np.sum(self.lagged_basis * cq))
        lagged += float(np.sum(self.qaq * qcq))
        return trace, lagged / trace, float(qcq[1, 1]) / self.spread


#: The last model :func:`_model_of` made, with its frame times.
_last_model: dict[str, tuple[NDArray[np.float64], _ResidualModel]] = {}


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
