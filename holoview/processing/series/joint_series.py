"""A whole recording through the joint estimate: depths, fused depth, vibration, rates.

:func:`estimate_joint` runs :class:`~holoview.processing.series.joint_estimation.JointEstimator`
over every frame twice: the first pass learns each peak's phase noise and how far the
steps depart from their prediction, the second runs with both fixed at what the first
measured (robust spreads: 1.4826 times the median absolute deviation), so that the
early frames are weighed as the late ones. Rates come from
:func:`holoview.processing.series.rate_fits.fit_rate`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError
from holoview.processing.series.frame_gaps import intervals_of
from holoview.processing.series.joint_estimation import DEFAULT_MIN_MARGIN, JointEstimator
from holoview.processing.series.rate_fits import RateFit, check_times, fit_rate

logger = logging.getLogger(__name__)

__all__ = ["JointSeries", "estimate_joint"]

#: Converts a median absolute deviation into a Gaussian standard deviation.
_MAD_TO_STD = 1.4826

#: Smallest phase noise a peak is given, rad (a noiseless simulation would otherwise
#: give it an infinite weight).
MIN_SIGMA = 1e-4

#: Smallest ``1 - leverage`` a peak's residual is scaled by (a peak that alone fixes a
#: direction leaves no residual to measure its noise by).
LEVERAGE_FLOOR = 0.05


@dataclass(frozen=True)
class JointSeries:
    """The joint estimate of a recording.

    Attributes
    ----------
    times : ndarray, shape (N,)
        Frame times, s.
    phases : ndarray, shape (N, M)
        Each peak's phase unwrapped by the joint solution, rad, 0 at its first frame
        (NaN where not measured).
    depths : ndarray, shape (N, M)
        Each peak's own depth change, ``phase * wavelength / (4 pi alpha)``, m: the
        reference arm's phase is still in the RF and RB_j series.
    fused : ndarray, shape (N,)
        The fused depth change, m: the reference arm's phase solved for and removed.
    vibration : ndarray, shape (N,)
        The reference arm's phase since the first frame, rad (NaN when no peak couples
        to it): ``wavelength / (4 pi n1)`` times it is the air path's change, m.
    margins : ndarray, shape (N,)
        Per frame, the height step's ambiguity margin in noise standard deviations (inf
        at the first).
    vibration_margins : ndarray, shape (N,)
        Per frame, the margin against a whole turn of the reference arm (the RF and
        RB_j series and the vibration series may slip a turn where it is small).
    flagged : ndarray of bool, shape (N,)
        Frames whose integers were not resolved with confidence (margin below the
        threshold).
    sigma : ndarray, shape (M,)
        Each peak's phase noise per frame in use, rad: as measured by the first pass,
        or as given (the median over frames of a per-frame one).
    noise : ndarray, shape (M,)
        The same in depth, m (``sigma * wavelength / (4 pi alpha)``).
    fit : RateFit or None
        Line through the fused depth (None with fewer than three frames).
    peak_fits : tuple of (RateFit or None)
        Line through each peak's depth.
    """

    times: NDArray[np.float64]
    phases: NDArray[np.float64]
    depths: NDArray[np.float64]
    fused: NDArray[np.float64]
    vibration: NDArray[np.float64]
    margins: NDArray[np.float64]
    vibration_margins: NDArray[np.float64]
    flagged: NDArray[np.bool_]
    sigma: NDArray[np.float64]
    noise: NDArray[np.float64]
    fit: RateFit | None
    peak_fits: tuple[RateFit | None, ...]


def _run(
    estimator: JointEstimator,
    values: NDArray[np.complex128],
    times: NDArray[np.float64],
    sigma: NDArray[np.float64] | None = None,
) -> tuple[
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.bool_],
]:
    """Every frame through ``estimator`` (the intervals between them from ``times``,
    :func:`~holoview.processing.series.frame_gaps.intervals_of`): phases, height,
    vibration, margins, flags."""
    n, m = values.shape
    phases = np.full((n, m), np.nan)
    fused, vibration = np.full(n, np.nan), np.full(n, np.nan)
    margins, vibration_margins = np.full(n, np.inf), np.full(n, np.inf)
    flagged = np.zeros(n, dtype=bool)
    intervals = intervals_of(times)
    for t in range(n):
        frame = estimator.update(
            values[t], None if sigma is None else sigma[t], intervals=int(intervals[t])
        )
        phases[t], fused[t], vibration[t] = frame.phases, frame.height, frame.vibration
        margins[t], vibration_margins[t] = frame.margin, frame.vibration_margin
        flagged[t] = frame.flagged
    return phases, fused, vibration, margins, vibration_margins, flagged


def _robust_std(x: NDArray[np.float64]) -> float:
    x = x[np.isfinite(x)]
    if x.size < 3:
        return float("nan")
    return _MAD_TO_STD * float(np.median(np.abs(x - np.median(x))))


def estimate_joint(
    values: ArrayLike,
    times: ArrayLike,
    alphas: ArrayLike,
    couplings: ArrayLike,
    wavelength: float,
    *,
    sigma: ArrayLike | None = None,
    min_margin: float = DEFAULT_MIN_MARGIN,
) -> JointSeries:
    """Jointly unwrap and fuse a recording's peaks (module documentation).

    Parameters
    ----------
    values : array_like of complex, shape (N, M)
        Each peak's carrier value per frame on its stored twin (or wrapped phases, rad);
        NaN where not measured.
    times : array_like of float, shape (N,)
        Frame times, s, strictly increasing.
    alphas : array_like of float, shape (M,)
        Each peak's prefactor on its stored twin, > 0.
    couplings : array_like of int, shape (M,)
        Each peak's coupling to the reference-arm phase (its lattice ``rf`` coordinate,
        :attr:`holoview.processing.naming.lattice.LatticePeak.coupling`).
    wavelength : float
        Laser wavelength in vacuum, m.
    sigma : array_like of float, shape (M,) or (N, M), optional
        Each peak's phase noise, rad: one per peak, or per frame and peak (for example
        a spectrum bin's noise over ``|value|``); measured when omitted.
    min_margin : float
        Frames whose ambiguity margin (noise standard deviations) is below this are
        flagged.

    Returns
    -------
    JointSeries

    Raises
    ------
    InputError
        For mismatched shapes, times that do not increase, or invalid alphas or
        couplings.
    """
    z = np.asarray(values)
    if z.ndim == 1:
        z = z[:, np.newaxis]
    if z.ndim != 2 or z.shape[0] < 1:
        raise InputError(f"values must be (frames, peaks), got shape {z.shape}")
    z = z.astype(np.complex128) if np.iscomplexobj(z) else np.exp(1j * z.astype(np.float64))
    t = check_times(times, z.shape[0])
    per_frame = None
    fixed = None
    if sigma is not None:
        given = np.asarray(sigma, dtype=np.float64)
        if given.shape == z.shape:
            per_frame = given
            if not np.all(np.isfinite(given) & (given > 0)):
                raise InputError("sigma must be positive phase noises (rad)")
        elif given.shape == (z.shape[1],):
            fixed = given
        else:
            raise InputError(f"sigma has shape {given.shape}; give (peaks,) or {z.shape}")
    first = JointEstimator(alphas, couplings, wavelength, sigma=fixed, min_margin=min_margin)
    phases, fused, vibration, margins, vibration_margins, flagged = _run(first, z, t, per_frame)
    k = 4 * np.pi / wavelength
    design = np.column_stack([first.alphas, first.couplings])
    state = np.column_stack([fused * k, np.nan_to_num(vibration)])
    residual = phases - state @ design.T
    measured = np.array(
        [_robust_std(np.diff(residual[:, j])) / np.sqrt(2) for j in range(z.shape[1])]
    )
    learned = first.sigma
    noise = np.where(np.isfinite(measured), measured, learned if learned is not None else 1.0)
    noise = np.maximum(noise, MIN_SIGMA)
    for _ in range(3):  # a heavily weighted peak pulls the fit to itself: undo its leverage
        w = 1.0 / noise**2
        hat = (
            np.einsum(
                "ij,jk,ik->i", design, np.linalg.pinv(design.T @ (w[:, None] * design)), design
            )
            * w
        )
        noise = np.maximum(measured / np.sqrt(np.clip(1.0 - hat, LEVERAGE_FLOOR, 1.0)), MIN_SIGMA)
        noise = np.where(np.isfinite(noise), noise, learned if learned is not None else 1.0)
    if fixed is not None:
        noise = fixed
    elif per_frame is not None:
        noise = np.median(per_frame, axis=0)
    steps = np.diff(state, axis=0)
    innovation = np.column_stack([np.diff(steps[:, 0]), steps[1:, 1]])
    spread = np.array([_robust_std(innovation[:, 0]), _robust_std(innovation[:, 1])])
    if np.all(np.isfinite(spread)) and z.shape[0] > 10:
        second = JointEstimator(
            alphas,
            couplings,
            wavelength,
            sigma=noise,
            min_margin=min_margin,
            spread=np.maximum(spread, 1e-3),
            step=(float(np.median(steps[:5, 0])), 0.0),
        )
        phases, fused, vibration, margins, vibration_margins, flagged = _run(
            second, z, t, per_frame
        )
    depths = phases * wavelength / (4 * np.pi * first.alphas)
    fit = fit_rate(t, fused) if np.count_nonzero(np.isfinite(fused)) >= 3 else None
    peak_fits = tuple(
        fit_rate(t, depths[:, j]) if np.count_nonzero(np.isfinite(depths[:, j])) >= 3 else None
        for j in range(z.shape[1])
    )
    if np.any(flagged):
        logger.info("%d of %d frames flagged (ambiguity margin)", int(flagged.sum()), flagged.size)
    return JointSeries(
        times=t,
        phases=phases,
        depths=depths,
        fused=fused,
        vibration=vibration,
        margins=margins,
        vibration_margins=vibration_margins,
        flagged=flagged,
        sigma=noise,
        noise=noise * wavelength / (4 * np.pi * first.alphas),
        fit=fit,
        peak_fits=peak_fits,
    )
