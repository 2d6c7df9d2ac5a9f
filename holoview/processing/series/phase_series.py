"""Mean phase of each peak over time: unwrapping in time and the aliasing check.

The complex value of the spectrum at a peak's carrier carries the spatial average of its
phase (paper section 4.2), so one complex number per peak and frame tracks the mean depth.

1. :func:`unwrap_in_time` adds the wrapped phase steps between consecutive frames; a step
   is only right while the true step stays under pi in magnitude.
2. :func:`check_aliasing` flags a peak whose step per frame comes near pi: its
   ``|step| + n_sigma * noise`` reaches pi (``n_sigma = 3`` by default), where ``step``
   is the median wrapped step, or the step the model predicts from the peak's alpha and
   a depth rate (which also catches a peak already past pi, whose wrapped step looks
   innocent), and ``noise`` the robust spread of its steps (1.4826 times their median
   absolute deviation).

Phases are in rad.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError

logger = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_N_SIGMA",
    "AliasingReport",
    "as_series",
    "check_aliasing",
    "phase_steps",
    "unwrap_in_time",
]

#: Default number of step-noise standard deviations kept clear of pi (see
#: :func:`check_aliasing`): 3 leaves about one wrong unwrap per 700 frames of Gaussian noise.
DEFAULT_N_SIGMA = 3.0

#: Converts a median absolute deviation into a Gaussian standard deviation.
_MAD_TO_STD = 1.4826


def _as_unit_phasors(values: ArrayLike) -> NDArray[np.complex128]:
    """Complex peak values as they are, or real wrapped phases (rad) as unit phasors."""
    array = np.asarray(values)
    if np.iscomplexobj(array):
        return array.astype(np.complex128)
    return np.exp(1j * array.astype(np.float64))


def as_series(values: ArrayLike, what: str) -> NDArray[np.complex128]:
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
    z = as_series(values, "peak values")
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
    z = as_series(values, "peak values")
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
