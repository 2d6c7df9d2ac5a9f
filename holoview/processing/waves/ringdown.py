"""Damped-mode (ringdown) fit in one (m, f) band: frequency and decay rate with errors.

A mode ringing down is ``h_m(r, t) = u(r) C exp(-(gamma + i omega) t)`` in the
convention ``exp(-i omega t)`` (its power at numpy's frequency ``-f``). The fit:

1. a complex FIR band-pass ``F`` for ``f1 <= f <= f2`` (a Hann-windowed sinc of
   half-width ``(f2 - f1) / 2`` moved to the band's centre at ``-f``, at most a quarter
   of the longest gap-free run long) runs within each gap-free run, so no output mixes
   frames across a gap;
2. the rings are combined with the leading right singular vector of the band-passed
   ``(time, ring)`` matrix (rings weighted by ``r``), giving one series ``x(t)``;
3. from the start of the ringdown (by default the peak of the band-passed envelope,
   see :func:`fit_ringdown`) ``F x = F [C exp(-(gamma + i omega)(t - t0))]`` is fitted
   by least squares on the true times, the frames before the start taken as zero in
   both: the model is band-passed exactly as the data are, so the filter's response to
   the cut is part of it. Frames before the start enter nothing (a start at or after
   the mode's onset gives an unbiased decay rate), and none after it is lost to the
   filter's length (a mode that decays within it is measured from its first frames);
4. the outputs whose taps reach before the start also take in, for about the filter's
   main lobe, a part of any signal outside the band (a filter cannot tell frequencies
   apart over less than its length). The fit is repeated without them (the outputs
   whose taps all lie within a run after the start); where that fit measures the mode
   and its gamma or omega differs from the first by more than :data:`AGREEMENT`
   standard errors of the difference (its variance less the first's), it is taken;
5. the errors are the sandwich covariance of the least-squares fit for white noise
   (``F`` makes neighbouring residuals correlated), its level from the residuals.

A mode that does not stand :data:`MIN_SIGNIFICANCE` standard errors out of the noise is
not reported, nor a decay rate whose error exceeds :data:`MAX_DECAY_ERROR` of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from holoview.errors import InputError
from holoview.processing.waves.clock import frame_clock

__all__ = [
    "AGREEMENT",
    "MAX_DECAY_ERROR",
    "MIN_SIGNIFICANCE",
    "Ringdown",
    "band_pass_taps",
    "fit_ringdown",
]

#: Least ratio of the mode's fitted amplitude to its standard error.
MIN_SIGNIFICANCE = 10.0
#: Largest standard error of the decay rate, as a share of it, that is reported.
MAX_DECAY_ERROR = 0.2
#: The fit of every output from the start is kept while the fit of the outputs whose
#: taps all lie after it agrees within this many standard errors of their difference.
AGREEMENT = 3.0


def _convolve(x: np.ndarray, kernel: np.ndarray) -> NDArray[np.complex128]:
    """The full linear convolution of ``x`` with ``kernel`` along axis 0, by FFT."""
    n = x.shape[0] + kernel.shape[0] - 1
    size = scipy.fft.next_fast_len(n)
    product = scipy.fft.fft(x, size, axis=0) * scipy.fft.fft(kernel, size, axis=0)
    return np.asarray(scipy.fft.ifft(product, axis=0)[:n])


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
        The band-passed series ``F x`` at ``times`` and the band-passed model there
        (where the outputs next to ``t0`` were fitted, their taps reach before it into
        zeros: both fall to about half there).
    rms_residual : float
        RMS of ``|series - model|``, m.
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
        At most this many taps (at least 9): a shorter filter separates the band from
        its surroundings within a shorter record, and its band's edges are softer (about
        ``2 / (taps interval)`` Hz wide).
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


@dataclass(frozen=True)
class _RunFilter:
    """The band-pass ``F`` within each gap-free piece of ``frames`` frames, zero outside.

    ``pieces`` are ``(start, stop, cut)``: the input frames ``[start, stop)``; the
    outputs are centred on the frames from ``start`` when ``cut`` (the taps reaching
    before it meet zeros) or else from ``start + taps // 2``, up to ``stop - taps // 2``
    (every tap within the piece).
    """

    taps: NDArray[np.complex128]
    pieces: tuple[tuple[int, int, bool], ...]
    frames: int

    @property
    def _spans(self) -> list[tuple[int, int, int]]:
        """``(start, stop, first output)`` of each piece with outputs."""
        half = self.taps.size // 2
        spans = [(a, b, a if cut else a + half) for a, b, cut in self.pieces]
        return [(a, b, lead) for a, b, lead in spans if b - half > lead]

    @property
    def outputs(self) -> NDArray[np.intp]:
        """The frames the outputs are centred on."""
        half = self.taps.size // 2
        return np.concatenate(
            [np.zeros(0, np.intp)] + [np.arange(lead, b - half) for _, b, lead in self._spans]
        )

    def __call__(self, x: np.ndarray, taps: np.ndarray | None = None) -> NDArray[np.complex128]:
        """``F x`` (frames along axis 0), or the same with other ``taps``."""
        kernel = (self.taps if taps is None else taps).reshape((-1,) + (1,) * (x.ndim - 1))
        half = self.taps.size // 2
        parts = [np.zeros((0, *x.shape[1:]), np.complex128)]
        for a, b, lead in self._spans:
            parts.append(_convolve(x[a:b], kernel)[lead - a + half : b - a])
        return np.concatenate(parts)

    def adjoint(self, y: np.ndarray) -> NDArray[np.complex128]:
        """``F^H y`` (outputs along axis 0)."""
        spread = np.zeros((self.frames, *y.shape[1:]), np.complex128)
        spread[self.outputs] = y
        kernel = self.taps[::-1].conj().reshape((-1,) + (1,) * (y.ndim - 1))
        half = self.taps.size // 2
        for a, b, _ in self._spans:
            spread[a:b] = _convolve(spread[a:b], kernel)[half : half + b - a]
        return spread

    def noise_power(self) -> float:
        """``tr F F^H``: the outputs' summed variance for white noise of variance 1."""
        return float(np.sum(self(np.ones(self.frames), np.abs(self.taps) ** 2).real))


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
        ``+theta`` when ``m > 0``, towards ``-theta`` when ``m < 0``).
    m : int
        The azimuthal number (recorded).
    radii : array_like of float, shape (R,), optional
        Ring radii, m (weights of the combination; equal without).
    start : float, optional
        Fit from this time, s: at or after the mode's onset (frames before it enter
        nothing). Default: the peak of the band-passed envelope (``|F x|`` over the
        filter's gain at the band's centre, which falls at the record's ends and gaps),
        which lies after the onset of a mode that starts within the record.

    Raises
    ------
    InputError
        Too short a record for the band's filter, no finite ring, a fit that does not
        converge, a mode that does not stand out of the noise or lies outside the band,
        or a decay rate that is not determined (its error over ``MAX_DECAY_ERROR`` of it:
        the line gives the mode's length in frames and the record's in decay times).
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
    name = f"ringdown m={m} in {band[0]:g}:{band[1]:g} Hz"
    if _RunFilter(taps, tuple((a, b, False) for a, b in clock.runs), clock.frames).outputs.size < 8:
        raise InputError(
            f"{name}: the band's filter needs runs of more than {taps.size + 8} frames "
            f"without a gap; the longest has {longest}"
        )
    whole = _RunFilter(taps, tuple((a, b, True) for a, b in clock.runs), clock.frames)
    filtered = whole(data)
    scaled = filtered * np.sqrt(weight)
    leading = np.linalg.eigh(scaled.conj().T @ scaled)[1][:, -1]  # the right singular vector
    shape = leading * np.sqrt(weight) / np.sum(weight * np.abs(leading) ** 2)
    if start is None:
        gain = np.abs(whole(np.exp(-1j * np.pi * (band[0] + band[1]) * clock.times)))
        first = int(np.argmax(np.abs(filtered @ shape) / gain))
    else:
        first = int(np.searchsorted(clock.times, start))
    x = data[first:] @ shape
    dt = clock.times[first:] - clock.times[first]
    runs = [(max(a, first) - first, b - first) for a, b in clock.runs if b > first]
    cut = _RunFilter(taps, tuple((a, b, a == 0) for a, b in runs), dt.size)
    if cut.outputs.size < 8:
        raise InputError(f"{name}: {cut.outputs.size} samples after the start, need 8")
    fit = _fit(x, dt, cut, band)
    within = _RunFilter(taps, tuple((a, b, False) for a, b in runs), dt.size)
    if within.outputs.size >= 8:
        fit = _leak_free(fit, _fit(x, dt, within, band), band, clock.interval)
    problem = fit.problem(band, clock.interval)
    if problem is not None:
        raise InputError(f"{name}: {problem}")
    return Ringdown(
        m=int(m),
        band=(float(band[0]), float(band[1])),
        frequency=fit.frequency,
        frequency_stderr=float(fit.errors[3] / (2 * np.pi)),
        decay=fit.decay,
        decay_stderr=float(fit.errors[2]),
        amplitude=complex(fit.params[0], fit.params[1]),
        t0=float(clock.times[first]),
        times=clock.times[first:][fit.outputs],
        series=fit.series,
        model=fit.model,
        rms_residual=float(np.sqrt(np.mean(np.abs(fit.series - fit.model) ** 2))),
    )


@dataclass(frozen=True)
class _Fit:
    """``C exp(-(gamma + i omega) t)`` fitted to a band-passed series."""

    params: NDArray[np.float64]  # Re C, Im C, gamma, omega
    errors: NDArray[np.float64]
    outputs: NDArray[np.intp]
    series: NDArray[np.complex128]
    model: NDArray[np.complex128]
    converged: bool

    @property
    def decay(self) -> float:
        """``gamma``, 1/s."""
        return float(self.params[2])

    @property
    def frequency(self) -> float:
        """``omega / 2 pi``, Hz."""
        return float(self.params[3] / (2 * np.pi))

    def problem(self, band: tuple[float, float], interval: float) -> str | None:
        """Why the fit is not reported (it did not converge, a mode not out of the noise or
        out of the band, an undetermined decay rate), or None."""
        if not (self.converged and np.all(np.isfinite(self.errors))):
            return "the fit did not converge"
        significance = math.hypot(*self.params[:2]) / max(math.hypot(*self.errors[:2]), 1e-300)
        if significance < MIN_SIGNIFICANCE:
            return (
                f"no damped mode stands out of the noise (amplitude {significance:.1f} "
                f"standard errors, need {MIN_SIGNIFICANCE:g})"
            )
        if not band[0] <= self.frequency <= band[1]:
            return (
                f"the fitted frequency {self.frequency:.4g} Hz lies outside the band "
                "(no mode there?)"
            )
        if not self.errors[2] <= MAX_DECAY_ERROR * abs(self.decay):
            frames = int(self.outputs[-1] - self.outputs[0]) + 1
            return _undetermined_decay(self.decay, self.errors[2], frames * interval, interval)
        return None


def _leak_free(every: _Fit, within: _Fit, band: tuple[float, float], interval: float) -> _Fit:
    """The fit of every output from the start unless the fit of those whose taps all lie
    after it measures the mode too and disagrees (a signal outside the band leaking in
    where the filter meets the start): where both are right, their difference has the
    second's variance less the first's."""
    if within.problem(band, interval) is not None:
        return every
    spread = np.sqrt(np.maximum(within.errors[2:] ** 2 - every.errors[2:] ** 2, 0.0))
    agree = np.abs(within.params[2:] - every.params[2:]) <= AGREEMENT * spread
    return every if bool(np.all(agree)) else within


def _fit(x: np.ndarray, dt: np.ndarray, band_pass: _RunFilter, band: tuple[float, float]) -> _Fit:
    """Least squares of ``F x`` against ``F [C exp(-(gamma + i omega) dt)]``."""
    z = band_pass(x)
    unit = float(np.max(np.abs(z))) or 1.0  # the fit in units of the series' peak

    def fitted(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``F`` of the model (over ``unit``) and of its derivatives in ``p`` (columns)."""
        decay = np.exp(-(p[2] + 1j * p[3]) * dt)
        mode = (p[0] + 1j * p[1]) * decay
        out = band_pass(np.stack([mode, decay, 1j * decay, -dt * mode, -1j * dt * mode], 1))
        return out[:, 0], out[:, 1:]

    def residuals(p: np.ndarray) -> np.ndarray:
        diff = z / unit - fitted(p)[0]
        return np.concatenate([diff.real, diff.imag])

    def jacobian(p: np.ndarray) -> np.ndarray:
        derivative = fitted(p)[1]
        return -np.concatenate([derivative.real, derivative.imag])

    guess = _first_guess(z / unit, dt[band_pass.outputs], band)
    result = least_squares(residuals, guess, jac=jacobian, x_scale="jac")
    model, derivative = fitted(result.x)
    errors = _standard_errors(z / unit - model, derivative, band_pass)
    scale = np.array([unit, unit, 1.0, 1.0])
    return _Fit(
        result.x * scale,
        errors * scale,
        band_pass.outputs,
        z,
        np.asarray(model * unit, np.complex128),
        bool(result.success),
    )


def _first_guess(z: np.ndarray, dt: np.ndarray, band: tuple[float, float]) -> NDArray[np.float64]:
    """``Re C, Im C, gamma, omega`` from the band-passed series' envelope and phase."""
    magnitude = np.abs(z)
    useful = magnitude > 0.1 * magnitude.max()
    omega = np.pi * (band[0] + band[1])
    slope_log = 0.0
    if np.count_nonzero(useful) >= 3:
        slope_log = np.polyfit(dt[useful], np.log(magnitude[useful]), 1)[0]
        slope_phase = np.polyfit(dt[useful], np.unwrap(np.angle(z[useful])), 1)[0]
        if band[0] <= -slope_phase / (2 * np.pi) <= band[1]:
            omega = -slope_phase
    peak = int(np.argmax(magnitude))
    c = z[peak] * np.exp((max(-slope_log, 0.0) + 1j * omega) * dt[peak])
    return np.array([c.real, c.imag, max(-slope_log, 0.0), omega])


def _standard_errors(
    residual: np.ndarray, derivative: np.ndarray, band_pass: _RunFilter
) -> NDArray[np.float64]:
    """Sandwich standard errors of a least-squares fit of ``F x`` for white noise in ``x``.

    ``J = F dmodel/dp`` (complex columns, real parameters); for circular white noise of
    variance ``s2`` in ``x`` the estimate's covariance is
    ``s2 / 2 A^-1 Re(G^H G) A^-1`` with ``A = Re(J^H J)`` and ``G = F^H J``, and
    ``E |residual|^2 = s2 (tr F F^H - tr(A^-1 Re(G^H G)) / 2)`` gives ``s2``.
    """
    adjoint = band_pass.adjoint(derivative)
    bread = (derivative.conj().T @ derivative).real
    meat = (adjoint.conj().T @ adjoint).real
    try:
        inverse = np.linalg.inv(bread)
    except np.linalg.LinAlgError:
        return np.full(4, np.nan)
    dof = band_pass.noise_power() - 0.5 * float(np.trace(inverse @ meat))
    variance = float(np.sum(np.abs(residual) ** 2)) / dof
    return np.sqrt(np.diag(0.5 * variance * inverse @ meat @ inverse))


def _undetermined_decay(gamma: float, error: float, duration: float, interval: float) -> str:
    """The line for a decay rate that the fit does not determine, with what sets it."""
    lasting = 1 / max(abs(gamma) * interval, 1e-300)
    return (
        f"the decay rate is not determined: gamma {gamma:.3g} +- {error:.2g} 1/s, more than "
        f"{100 * MAX_DECAY_ERROR:g} % of it (the mode lasts {lasting:.3g} frames, the record "
        f"fitted {abs(gamma) * duration:.2g} decay times)"
    )
