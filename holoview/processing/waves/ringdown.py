"""Damped-mode (ringdown) fit in one (m, f) band: frequency and decay rate with errors.

A mode ringing down is ``h_m(r, t) = u(r) C exp(-(gamma + i omega) t)`` in the
convention ``exp(-i omega t)`` (its power at numpy's frequency ``-f``). The fit:

1. each ring's series ``h_m(r, t)`` is band-passed to ``f1 <= f <= f2`` by a complex
   FIR filter (a Hann-windowed sinc of half-width ``(f2 - f1) / 2`` moved to the band's
   centre at ``-f``, at most a quarter of the longest gap-free run long, so that most
   of the record is left to fit), run within each gap-free run in "valid" mode, so no
   output mixes frames across a gap or past a run's ends. A linear filter keeps a
   damped exponential's ``gamma`` and ``omega``: only its complex amplitude changes;
2. the rings are combined with the leading singular vector of the filtered
   ``(time, ring)`` matrix (rings weighted by ``r``), giving one series ``z(t)``;
3. ``z(t) = C exp(-(gamma + i omega)(t - t0))`` is fitted by least squares on the
   true times from the start of the ringdown (by default the time of largest
   ``|z|``). The filter makes neighbouring residuals correlated: the covariance is
   multiplied by ``1 / sum |h|^2`` of the filter taps ``h`` (gain 1 at the band's
   centre: the sampling rate over the filter's noise bandwidth, the number of samples
   per independent one for white noise).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from holoview.errors import InputError
from holoview.processing.waves.clock import frame_clock

__all__ = ["MIN_SIGNIFICANCE", "Ringdown", "band_pass_taps", "fit_ringdown"]

#: Least ratio of the mode's fitted amplitude to its standard error.
MIN_SIGNIFICANCE = 10.0


@dataclass(frozen=True)
class Ringdown:
    """A damped mode fitted in one band.

    Attributes
    ----------
    m : int
    band : (float, float)
        Hz.
    frequency, frequency_stderr : float
        ``omega / 2 pi``, Hz.
    decay, decay_stderr : float
        ``gamma``, 1/s (amplitude ``exp(-gamma t)``).
    amplitude : complex
        ``C`` of the combined series at ``t0`` (m, arbitrary radial normalisation).
    t0 : float
        Start of the fitted stretch, s.
    times : ndarray of float
        The times fitted, s.
    series, model : ndarray of complex
        ``z(t)`` and the fitted model there.
    rms_residual : float
        RMS of ``|z - model|``, m.
    """

    m: int
    band: tuple[float, float]
    frequency: float
    frequency_stderr: float
    decay: float
    decay_stderr: float
    amplitude: complex
    t0: float
    times: NDArray[np.float64]
    series: NDArray[np.complex128]
    model: NDArray[np.complex128]
    rms_residual: float

    @property
    def quality(self) -> float:
        """Quality factor ``omega / (2 gamma)`` (inf without decay)."""
        return math.inf if self.decay <= 0 else math.pi * self.frequency / self.decay

    def as_dict(self) -> dict[str, Any]:
        """The values with their errors and units, for a JSON summary."""
        return {
            "m": self.m,
            "band_hz": list(self.band),
            "frequency_hz": self.frequency,
            "frequency_stderr_hz": self.frequency_stderr,
            "decay_per_s": self.decay,
            "decay_stderr_per_s": self.decay_stderr,
            "quality_factor": self.quality,
            "t0_s": self.t0,
            "samples": int(self.times.size),
            "rms_residual_m": self.rms_residual,
        }


def band_pass_taps(
    band: tuple[float, float], interval: float, *, max_taps: int | None = None
) -> NDArray[np.complex128]:
    """Return a complex FIR band-pass for ``exp(-i omega t)`` with ``f`` in ``band`` (Hz).

    A Hann-windowed sinc, four periods of the band's half-width long (odd, at least
    9 taps), moved to numpy's frequency ``-f_centre``; gain 1 at the centre.

    Parameters
    ----------
    band : (float, float)
        ``f1, f2``, Hz.
    interval : float
        Time between frames, s.
    max_taps : int, optional
        At most this many taps (at least 9): a shorter filter leaves more of a short
        record to fit, and its band's edges are softer (about ``2 / (taps interval)`` Hz
        wide).
    """
    f1, f2 = band
    if not (0 <= f1 < f2 <= 0.5 / interval):
        raise InputError(
            f"the band {f1:g}:{f2:g} Hz must lie within 0 and the Nyquist frequency "
            f"{0.5 / interval:.4g} Hz and increase"
        )
    half = 0.5 * (f2 - f1)
    n = 2 * math.ceil(2.0 / (half * interval)) + 1
    if max_taps is not None:
        n = min(n, max_taps - (1 - max_taps % 2))  # odd
    n = max(9, n)
    t = (np.arange(n) - (n - 1) / 2) * interval
    taps = 2 * half * np.sinc(2 * half * t) * np.hanning(n + 2)[1:-1]
    taps = taps * np.exp(-2j * np.pi * 0.5 * (f1 + f2) * t)
    return taps / np.sum(taps * np.exp(2j * np.pi * 0.5 * (f1 + f2) * t))


def _filtered(
    series: np.ndarray, runs: Sequence[tuple[int, int]], taps: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Valid-mode filtering of (N, R) within each run: output and its frame indices."""
    n = taps.size
    outputs, where = [], []
    for start, stop in runs:
        if stop - start < n:
            continue
        block = series[start:stop]
        out = np.stack(
            [np.convolve(block[:, j], taps, mode="valid") for j in range(block.shape[1])],
            axis=1,
        )
        outputs.append(out)
        where.append(np.arange(start + n // 2, stop - n // 2))
    if not outputs:
        return np.zeros((0, series.shape[1]), complex), np.zeros(0, np.intp)
    return np.concatenate(outputs), np.concatenate(where)


def fit_ringdown(
    times: ArrayLike,
    series: ArrayLike,
    band: tuple[float, float],
    *,
    m: int = 0,
    radii: ArrayLike | None = None,
    start: float | None = None,
) -> Ringdown:
    """Fit a damped mode to ``h_m(r, t)`` in a frequency band.

    Parameters
    ----------
    times : array_like of float, shape (N,)
        Frame times, s (gaps allowed).
    series : array_like of complex, shape (N,) or (N, R)
        ``h_m(t)`` (m) of one ring or of several; rings with a NaN are left out.
    band : (float, float)
        ``f1, f2``, Hz (``exp(-i omega t)``: ``f > 0`` for a mode turning towards
        ``+theta``).
    m : int
        The azimuthal number (recorded).
    radii : array_like of float, shape (R,), optional
        Ring radii, m (weights of the combination; equal without).
    start : float, optional
        Fit from this time, s (default: the time of the largest filtered ``|z|``).

    Raises
    ------
    InputError
        Too short a record for the band's filter, no finite ring, or a fit that does
        not converge (a decay rate that is not determined).
    """
    clock = frame_clock(times)
    data = np.asarray(series, dtype=np.complex128)
    if data.ndim == 1:
        data = data[:, np.newaxis]
    if data.shape[0] != clock.frames:
        raise InputError(f"{data.shape[0]} samples and {clock.frames} times do not match")
    rings = np.all(np.isfinite(data), axis=0)
    if not np.any(rings):
        raise InputError(f"ringdown m={m}: no ring is finite in every frame")
    data = data[:, rings]
    weight = np.ones(data.shape[1]) if radii is None else np.asarray(radii, float)[rings]
    longest = max(b - a for a, b in clock.runs)
    taps = band_pass_taps(band, clock.interval, max_taps=longest // 4)
    filtered, index = _filtered(data, clock.runs, taps)
    if index.size < 8:
        raise InputError(
            f"ringdown m={m} in {band[0]:g}:{band[1]:g} Hz: the band's filter needs runs of "
            f"more than {taps.size + 8} frames without a gap; the longest has {longest}"
        )
    scaled = filtered * np.sqrt(weight)[np.newaxis, :]
    _, _, vh = np.linalg.svd(scaled, full_matrices=False)
    shape = vh[0].conj() * np.sqrt(weight)
    z = filtered @ shape / np.sum(np.abs(shape) ** 2)
    t = clock.times[index]
    first = int(np.argmax(np.abs(z))) if start is None else int(np.searchsorted(t, start))
    t, z = t[first:], z[first:]
    if t.size < 8:
        raise InputError(f"ringdown m={m}: {t.size} samples after the start, need 8")
    t0 = float(t[0])
    phase = np.unwrap(np.angle(z))
    slope_phase = np.polyfit(t - t0, phase, 1)[0]
    magnitude = np.abs(z)
    useful = magnitude > 0.1 * magnitude[0]
    if np.count_nonzero(useful) >= 3:
        slope_log = np.polyfit(t[useful] - t0, np.log(magnitude[useful]), 1)[0]
    else:
        slope_log = 0.0
    x0 = np.array([z[0].real, z[0].imag, max(-slope_log, 0.0), -slope_phase])

    def residuals(x: np.ndarray) -> np.ndarray:
        c = x[0] + 1j * x[1]
        model = c * np.exp(-(x[2] + 1j * x[3]) * (t - t0))
        diff = z - model
        return np.concatenate([diff.real, diff.imag])

    result = least_squares(residuals, x0, x_scale="jac")
    correlation = float(1.0 / np.sum(np.abs(taps) ** 2))  # taps have gain 1 at the centre
    dof = 2 * t.size - 4
    variance = float(np.sum(result.fun**2)) / max(dof, 1) * correlation
    try:
        covariance = np.linalg.inv(result.jac.T @ result.jac) * variance
    except np.linalg.LinAlgError:
        covariance = np.full((4, 4), np.nan)
    errors = np.sqrt(np.diag(covariance))
    omega, gamma = result.x[3], result.x[2]
    if not (result.success and np.all(np.isfinite(errors))):
        raise InputError(f"ringdown m={m} in {band[0]:g}:{band[1]:g} Hz: the fit did not converge")
    frequency = omega / (2.0 * np.pi)
    significance = abs(complex(result.x[0], result.x[1])) / max(
        math.hypot(errors[0], errors[1]), 1e-300
    )
    if significance < MIN_SIGNIFICANCE:
        raise InputError(
            f"ringdown m={m} in {band[0]:g}:{band[1]:g} Hz: no damped mode stands out of the "
            f"noise (amplitude {significance:.1f} standard errors, need {MIN_SIGNIFICANCE:g})"
        )
    if not band[0] <= frequency <= band[1]:
        raise InputError(
            f"ringdown m={m}: the fitted frequency {frequency:.4g} Hz lies outside the band "
            f"{band[0]:g}:{band[1]:g} Hz (no mode there?)"
        )
    c = complex(result.x[0], result.x[1])
    model = c * np.exp(-(gamma + 1j * omega) * (t - t0))
    return Ringdown(
        m=int(m),
        band=(float(band[0]), float(band[1])),
        frequency=float(frequency),
        frequency_stderr=float(errors[3] / (2.0 * np.pi)),
        decay=float(gamma),
        decay_stderr=float(errors[2]),
        amplitude=c,
        t0=t0,
        times=t,
        series=z,
        model=model,
        rms_residual=float(np.sqrt(np.mean(np.abs(z - model) ** 2))),
    )
