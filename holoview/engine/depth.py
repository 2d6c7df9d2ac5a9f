"""Depths, the fused depth and the rates of a mean-phase series, for the trends view and files.

:func:`summarise` turns a :class:`~holoview.engine.series.PhaseSeries` into each peak's
depth change, the fused depth and the rates (m/s): from the series' joint estimate when
it has one (the reference-arm phase solved for and removed from the fused depth), else
each peak unwrapped on its own and the peaks that do not alias in time fused by their
noise (:func:`holoview.processing.series.depth_series.track_depth`). :func:`pca_check` is the
temporal PCA of peaks whose prefactors are known, for information. The live trends
view and ``holoview process`` both call these.

Times are in s from the series' first frame, phases in rad, depths in m.
"""

from __future__ import annotations

import logging
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from holoview.engine.series import PhaseSeries
from holoview.errors import InputError
from holoview.processing.naming.pca import phase_pca
from holoview.processing.series.depth_series import track_depth
from holoview.processing.series.phase_series import check_aliasing
from holoview.processing.series.rate_fits import RateFit, fit_rate

logger = logging.getLogger(__name__)

__all__ = ["DepthSummary", "pca_check", "summarise"]


@dataclass(frozen=True)
class DepthSummary:
    """Depths and rates of a series.

    Attributes
    ----------
    times : ndarray, shape (N,)
        Frame times, s.
    phases : ndarray, shape (N, M)
        Mean phase per peak, rad, unwrapped in time from 0 at the first frame, on the
        twins the alphas' signs give (phase grows with the height).
    heights : ndarray, shape (N, M)
        Mean height change per peak, m (NaN for a peak without alpha).
    fused, fused_spread : ndarray or None, shape (N,)
        Noise-weighted mean height change of the fused peaks and their weighted rms
        deviation from it, m.
    fit : RateFit or None
        Line through the fused depth (m/s).
    peak_fits : tuple of (RateFit or None)
        Line through each peak's depth.
    noise_m : tuple of (float or None)
        Each peak's depth noise about its line, m (its fusion weight's).
    used : tuple of bool
        Whether each peak is in the fused depth.
    aliased : tuple of bool
        Whether each peak's phase steps near pi per frame (aliasing in time): left out
        of the fusion of the per-peak rule; the joint estimate unwraps it with the others.
    vibration : ndarray or None, shape (N,)
        The joint estimate's reference-arm phase since the first frame, rad (None
        without one, NaN when no peak couples to it).
    margins : ndarray or None, shape (N,)
        The joint estimate's ambiguity margin per frame, noise standard deviations.
    flagged : ndarray of bool or None, shape (N,)
        Frames whose ambiguity the joint estimate could not resolve with confidence.
    note : str or None
        Why there is no fused depth, when there is none.
    """

    times: np.ndarray
    phases: np.ndarray
    heights: np.ndarray
    fused: np.ndarray | None
    fused_spread: np.ndarray | None
    fit: RateFit | None
    peak_fits: tuple[RateFit | None, ...]
    noise_m: tuple[float | None, ...]
    used: tuple[bool, ...]
    aliased: tuple[bool, ...]
    vibration: np.ndarray | None = None
    margins: np.ndarray | None = None
    flagged: np.ndarray | None = None
    note: str | None = None


def _from_first(x: np.ndarray) -> np.ndarray:
    """``x`` minus its first finite value (per column), so it starts from 0."""
    out = np.array(x, dtype=np.float64)
    finite = np.isfinite(out)
    first = np.argmax(finite, axis=0)
    start = np.take_along_axis(out, first[None, ...], axis=0)[0] if out.ndim > 1 else out[first]
    return out - np.where(np.any(finite, axis=0), start, 0.0) + 0.0


def summarise(
    series: PhaseSeries,
    alphas: Sequence[float | None],
    wavelength_m: float,
    *,
    exclude: Sequence[bool] | None = None,
) -> DepthSummary:
    """Depth per peak, fused depth and rates of a series.

    With a joint estimate (:meth:`PhaseSeries.track_joint`) its peaks are unwrapped by
    it and its height is the fused depth (the reference-arm phase solved for and
    removed); otherwise each peak is unwrapped on its own and the peaks that do not
    alias in time are fused by their noise
    (:func:`holoview.processing.series.depth_series.track_depth`).

    Parameters
    ----------
    series : PhaseSeries
        The frames.
    alphas : sequence of (float or None)
        Each peak's prefactor, signed as the peak was measured (a negative alpha: the
        peak's phase falls with the height; its phases are stored negated). None: no
        height for that peak.
    wavelength_m : float
        Laser wavelength, m.
    exclude : sequence of bool, optional
        Peaks left out of the fused depth of the per-peak rule besides those aliasing
        in time (the joint estimate's own are set by :meth:`PhaseSeries.track_joint`).
    """
    n, m = series.values.shape
    signs = np.array([-1.0 if (a is not None and a < 0) else 1.0 for a in alphas])
    phases = series.unwrapped() * signs + 0.0  # no negative zeros in files
    values = np.where(signs < 0, np.conj(series.values), series.values)
    magnitudes = [abs(a) if a is not None else None for a in alphas]
    joint = series.joint()
    columns = list(series.joint_columns)
    if joint is not None and columns:
        phases[:, columns] = _from_first(joint[0][:, columns])
    to_metres = [None if a is None else wavelength_m / (4 * np.pi * a) for a in magnitudes]
    heights = np.full((n, m), np.nan)
    for j, scale in enumerate(to_metres):
        if scale is not None:
            heights[:, j] = phases[:, j] * scale
    peak_fits = tuple(
        fit_rate(series.times, heights[:, j])
        if np.count_nonzero(np.isfinite(heights[:, j])) >= 3
        else None
        for j in range(m)
    )
    aliased = [False] * m
    if n >= 3:
        # the joint estimate knows the true steps, also past pi, where the wrapped ones hide
        with np.errstate(invalid="ignore"):
            true_steps = np.nanmedian(np.diff(phases, axis=0), axis=0) if columns else None
        predicted = None
        if true_steps is not None:
            predicted = np.where(np.isin(np.arange(m), columns), true_steps, np.nan)
        aliased = [bool(a) for a in check_aliasing(values, predicted_step=predicted).aliased]
    if joint is not None and columns:
        return _joint_summary(
            series,
            phases=phases,
            heights=heights,
            peak_fits=peak_fits,
            aliased=aliased,
            to_metres=to_metres,
            joint=joint,
        )
    return _per_peak_summary(
        series,
        values=values,
        phases=phases,
        heights=heights,
        magnitudes=magnitudes,
        exclude=exclude,
        wavelength_m=wavelength_m,
    )


def _joint_summary(
    series: PhaseSeries,
    *,
    phases: np.ndarray,
    heights: np.ndarray,
    peak_fits: tuple[RateFit | None, ...],
    aliased: list[bool],
    to_metres: list[float | None],
    joint: tuple[np.ndarray, ...],
) -> DepthSummary:
    """The summary when the joint estimate gives the fused depth."""
    m = heights.shape[1]
    columns = list(series.joint_columns)
    _, height, vibration, margins, flagged = joint
    fused = _from_first(height)
    vibration = _from_first(vibration)
    couplings = series.joint_couplings
    corrected = np.column_stack(
        [
            (phases[:, j] - couplings[k] * np.nan_to_num(vibration)) * to_metres[j]
            for k, j in enumerate(columns)
        ]
    )
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a NaN frame: an all-NaN row
        deviation = corrected - fused[:, None]
        spread = np.sqrt(np.nanmean(deviation**2, axis=1)) if len(columns) > 1 else None
    noise: list[float | None] = [None] * m
    for j in columns:
        column = series.noise_rad[:, j]
        column = column[np.isfinite(column)]
        scale = to_metres[j]  # known: the joint estimate takes only peaks with a prefactor
        if column.size and scale is not None:
            noise[j] = float(np.median(column)) * scale
    fit = fit_rate(series.times, fused) if np.count_nonzero(np.isfinite(fused)) >= 3 else None
    return DepthSummary(
        times=series.times.copy(),
        phases=phases,
        heights=heights,
        fused=fused,
        fused_spread=spread,
        fit=fit,
        peak_fits=peak_fits,
        noise_m=tuple(noise),
        used=tuple(j in columns for j in range(m)),
        aliased=tuple(aliased),
        vibration=vibration,
        margins=margins.copy(),
        flagged=flagged.copy(),
    )


def _per_peak_summary(
    series: PhaseSeries,
    *,
    values: np.ndarray,
    phases: np.ndarray,
    heights: np.ndarray,
    magnitudes: list[float | None],
    exclude: Sequence[bool] | None,
    wavelength_m: float,
) -> DepthSummary:
    """The summary when each peak is unwrapped on its own (no joint estimate)."""
    n, m = heights.shape
    known_magnitudes = [(j, a) for j, a in enumerate(magnitudes) if a is not None]
    known = [j for j, _ in known_magnitudes]
    skip = list(exclude) if exclude is not None else [False] * m
    fits: list[RateFit | None] = [None] * m
    noise: list[float | None] = [None] * m
    used = [False] * m
    aliased = [False] * m
    fused = spread = None
    fit = None
    note = None
    if n >= 3 and known:
        try:
            track = track_depth(
                values[:, known],
                series.times,
                [a for _, a in known_magnitudes],
                wavelength_m,
                exclude=[skip[j] for j in known],
            )
        except InputError as exc:
            note = f"no fused depth: {exc}"
        else:
            fused, spread, fit = track.fused.depth, track.fused.spread, track.fit
            for k, j in enumerate(known):
                fits[j] = track.peak_fits[k]
                value = float(track.fused.noise[k])
                noise[j] = value if math.isfinite(value) else None
                used[j] = bool(track.fused.used[k])
                aliased[j] = bool(track.aliasing.aliased[k])
    elif known and any(not skip[j] for j in known):
        chosen = [j for j in known if not skip[j]]
        finite = np.isfinite(heights[:, chosen])
        total = np.where(finite, heights[:, chosen], 0.0).sum(axis=1)
        count = finite.sum(axis=1)
        fused = np.where(count > 0, total / np.maximum(count, 1), np.nan)
        used = [j in chosen for j in range(m)]
    return DepthSummary(
        times=series.times.copy(),
        phases=phases,
        heights=heights,
        fused=fused,
        fused_spread=spread,
        fit=fit,
        peak_fits=tuple(fits),
        noise_m=tuple(noise),
        used=tuple(used),
        aliased=tuple(aliased),
        note=note,
    )


def pca_check(
    phases: np.ndarray, labels: Sequence[str], alphas: Sequence[float | None]
) -> dict[str, object] | None:
    """Temporal PCA of peaks with known prefactors, against the brightest with one.

    Parameters
    ----------
    phases : ndarray, shape (N, M)
        Unwrapped mean phases, rad (:attr:`DepthSummary.phases`).
    labels : sequence of str
        The peaks' labels, brightest first.
    alphas : sequence of (float or None)
        Their prefactors (the first known one fixes the PCA's scale).

    Returns
    -------
    dict or None
        ``confidence`` (the principal component's share), ``reference`` (label),
        ``prefactors`` and ``explained`` per label, ``n_samples``; None with fewer than
        two peaks or three frames, no known prefactor, or no motion to analyse.
    """
    known = [(j, a) for j, a in enumerate(alphas) if a is not None]
    if len(labels) < 2 or phases.shape[0] < 3 or not known:
        return None
    try:
        pca = phase_pca(phases)
        reference, alpha = known[0]
        prefactors = pca.prefactors(reference, abs(float(alpha)))
    except InputError as exc:
        logger.debug("no PCA: %s", exc)
        return None
    return {
        "confidence": pca.confidence,
        "reference": labels[reference],
        "prefactors": dict(zip(labels, map(float, prefactors), strict=True)),
        "explained": dict(zip(labels, map(float, pca.explained), strict=True)),
        "n_samples": pca.n_samples,
    }
