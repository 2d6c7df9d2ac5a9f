"""Incoming and outgoing parts of one partial wave: a Hankel fit to its radial profile.

With ``h = Re(A_m(r) exp(i (m theta - omega t)))`` (the ``exp(-i omega t)`` convention),
a free wave of wavenumber ``k`` has ``A_m(r) = out H_m^(1)(k r) + in H_m^(2)(k r)``:
``H^(1) ~ exp(+i k r)`` travels outwards, ``H^(2)`` inwards. :func:`fit_partial_wave`
fits the complex ``in`` and ``out`` (m) to a profile by linear least squares,
weighting each ring by its radius (a ring of radius ``r`` averages about ``2 pi r``
pixels); ``k`` is given (the dispersion relation at ``f``) or refined by minimising
the residual around it. Standard errors come from the residual scatter: the rings
are a pixel apart, and the maps carry no structure finer than ``pi / k_cut``, so the
covariance is multiplied by ``max(1, pi / (k_cut dr))``.

A lock-in at a frequency ``f`` a little off a tone's ``f0`` returns the tone's amplitude
times the response ``W(f - f0) = sum w exp(2 pi i (f - f0) t) / sum w`` of the weights
on the frame times. :func:`refine_tone` takes lock-ins at a comb of frequencies around
a tone (every ring at once) and fits ``f0`` and the profile ``A(r)``, so that the
amplitude is not lost to the comb's spacing nor to a frequency known only to a
fraction of a spectral bin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special
from scipy.optimize import minimize_scalar

from holoview.errors import InputError

__all__ = ["PartialWaveFit", "fit_partial_wave", "lock_in_response", "refine_tone"]


@dataclass(frozen=True)
class PartialWaveFit:
    """Incoming and outgoing amplitudes of one (m, f) partial wave.

    Attributes
    ----------
    m : int
    frequency, frequency_stderr : float
        Hz (the error as given to :func:`fit_partial_wave`).
    wavenumber, wavenumber_stderr : float
        rad/m (the error is 0 when ``k`` was given, not fitted).
    incoming, outgoing : complex
        Coefficients of ``H_m^(2)(k r)`` and ``H_m^(1)(k r)``, m.
    incoming_stderr, outgoing_stderr : float
        Standard error of each one's real and imaginary parts (and of its modulus), m.
    ratio, ratio_stderr : float
        ``|incoming| / |outgoing|`` (inf when ``outgoing`` is 0).
    radii : ndarray of float
        The rings fitted, m.
    profile, model : ndarray of complex
        The measured and fitted ``A_m(r)``, m.
    rms_residual : float
        RMS of ``|profile - model|`` over the rings, m.
    """

    m: int
    frequency: float
    frequency_stderr: float
    wavenumber: float
    wavenumber_stderr: float
    incoming: complex
    outgoing: complex
    incoming_stderr: float
    outgoing_stderr: float
    ratio: float
    ratio_stderr: float
    radii: NDArray[np.float64]
    profile: NDArray[np.complex128]
    model: NDArray[np.complex128]
    rms_residual: float

    def as_dict(self) -> dict[str, Any]:
        """The values with their errors and units, for a JSON summary."""
        return {
            "m": self.m,
            "frequency_hz": self.frequency,
            "frequency_stderr_hz": self.frequency_stderr,
            "wavenumber_rad_per_m": self.wavenumber,
            "wavenumber_stderr_rad_per_m": self.wavenumber_stderr,
            "incoming_amplitude_m": abs(self.incoming),
            "incoming_phase_rad": math.atan2(self.incoming.imag, self.incoming.real),
            "incoming_stderr_m": self.incoming_stderr,
            "outgoing_amplitude_m": abs(self.outgoing),
            "outgoing_phase_rad": math.atan2(self.outgoing.imag, self.outgoing.real),
            "outgoing_stderr_m": self.outgoing_stderr,
            "incoming_over_outgoing": self.ratio,
            "incoming_over_outgoing_stderr": self.ratio_stderr,
            "rings": int(self.radii.size),
            "r_range_m": [float(self.radii[0]), float(self.radii[-1])],
            "rms_residual_m": self.rms_residual,
        }


def _solve(
    radii: np.ndarray, profile: np.ndarray, m: int, k: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """Weighted complex least squares: coefficients (out, in), design, weighted RSS."""
    design = np.column_stack([special.hankel1(m, k * radii), special.hankel2(m, k * radii)])
    root = np.sqrt(radii)
    coefficients, *_ = np.linalg.lstsq(design * root[:, None], profile * root, rcond=None)
    residual = (profile - design @ coefficients) * root
    return coefficients, design, float(np.sum(np.abs(residual) ** 2))


def fit_partial_wave(
    radii: ArrayLike,
    profile: ArrayLike,
    m: int,
    frequency: float,
    wavenumber: float,
    *,
    fit_wavenumber: bool = True,
    k_cut: float | None = None,
    frequency_stderr: float = 0.0,
) -> PartialWaveFit:
    """Fit incoming and outgoing Hankel components to a radial profile.

    Parameters
    ----------
    radii : array_like of float, shape (R,)
        Ring radii, m (> 0).
    profile : array_like of complex, shape (R,)
        ``A_m(r)`` at ``frequency``, m (NaN rings are left out).
    m : int
        Azimuthal number.
    frequency : float
        Hz (recorded in the result).
    wavenumber : float
        ``k``, rad/m: used as is, or the start of the search (within 20 %).
    fit_wavenumber : bool
        Refine ``k`` by minimising the residual.
    k_cut : float, optional
        The maps' cut-off wavenumber, rad/m (the correlation of neighbouring rings).
    frequency_stderr : float
        The frequency's standard error, Hz (recorded).

    Raises
    ------
    InputError
        Fewer than six finite rings, or a singular fit.
    """
    r = np.asarray(radii, dtype=np.float64)
    a = np.asarray(profile, dtype=np.complex128)
    keep = np.isfinite(a) & (r > 0)
    r, a = r[keep], a[keep]
    if r.size < 6:
        raise InputError(
            f"partial wave m={m} at {frequency:.4g} Hz: {r.size} rings with data, need six"
        )
    if not (math.isfinite(wavenumber) and wavenumber > 0):
        raise InputError(f"the wavenumber must be positive, got {wavenumber!r} rad/m")
    k = float(wavenumber)
    k_err = 0.0
    dof = 2 * r.size - 4 - (1 if fit_wavenumber else 0)
    step = float(np.median(np.diff(r))) if r.size > 1 else 1.0
    correlation = 1.0 if k_cut is None else max(1.0, math.pi / (k_cut * step))
    if fit_wavenumber:
        result = minimize_scalar(
            lambda kk: _solve(r, a, m, kk)[2],
            bounds=(0.8 * k, 1.2 * k),
            method="bounded",
            options={"xatol": 1e-7 * k},
        )
        if (
            not result.success
            or abs(result.x - 0.8 * k) < 1e-6 * k
            or abs(result.x - 1.2 * k) < 1e-6 * k
        ):
            raise InputError(
                f"partial wave m={m} at {frequency:.4g} Hz: the wavenumber fit did not converge "
                f"within 20 % of {k:.4g} rad/m"
            )
        k = float(result.x)
        h = 1e-4 * k
        rss = [_solve(r, a, m, kk)[2] for kk in (k - h, k, k + h)]
        curvature = (rss[0] - 2 * rss[1] + rss[2]) / h**2
        noise = rss[1] / max(dof, 1) * correlation
        k_err = math.sqrt(2.0 * noise / curvature) if curvature > 0 else math.inf
    coefficients, design, rss_value = _solve(r, a, m, k)
    weighted = design * np.sqrt(r)[:, None]
    try:
        inverse = np.linalg.inv(weighted.conj().T @ weighted)
    except np.linalg.LinAlgError as exc:
        raise InputError(f"partial wave m={m} at {frequency:.4g} Hz: singular fit") from exc
    variance = rss_value / max(dof, 1) * correlation
    covariance = inverse.real * variance  # of the complex coefficients
    out_err = math.sqrt(max(covariance[0, 0], 0.0) / 2.0)
    in_err = math.sqrt(max(covariance[1, 1], 0.0) / 2.0)
    outgoing, incoming = complex(coefficients[0]), complex(coefficients[1])
    if abs(outgoing) > 0:
        ratio = abs(incoming) / abs(outgoing)
        ratio_err = ratio * math.hypot(in_err / max(abs(incoming), 1e-300), out_err / abs(outgoing))
    else:
        ratio, ratio_err = math.inf, math.inf
    model = design @ coefficients
    if not all(math.isfinite(v) for v in (out_err, in_err, k_err)):
        raise InputError(f"partial wave m={m} at {frequency:.4g} Hz: the fit did not converge")
    return PartialWaveFit(
        m=int(m),
        frequency=float(frequency),
        frequency_stderr=float(frequency_stderr),
        wavenumber=k,
        wavenumber_stderr=k_err,
        incoming=incoming,
        outgoing=outgoing,
        incoming_stderr=in_err,
        outgoing_stderr=out_err,
        ratio=ratio,
        ratio_stderr=ratio_err,
        radii=r,
        profile=a,
        model=model,
        rms_residual=float(np.sqrt(np.mean(np.abs(a - model) ** 2))),
    )


def lock_in_response(
    times: ArrayLike, weights: ArrayLike, offsets: ArrayLike
) -> NDArray[np.complex128]:
    """Return ``W(offsets) = sum w exp(2 pi i offset t) / sum w`` (offsets in Hz)."""
    t = np.asarray(times, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    d = np.asarray(offsets, dtype=np.float64)
    return np.exp(2j * np.pi * np.outer(d, t)) @ w / np.sum(w)


def refine_tone(
    comb: ArrayLike,
    lock_ins: ArrayLike,
    times: ArrayLike,
    weights: ArrayLike,
) -> tuple[float, float, NDArray[np.complex128]]:
    """Fit one tone's frequency and profile to lock-ins at a comb of frequencies.

    Parameters
    ----------
    comb : array_like of float, shape (C,)
        The lock-in frequencies, Hz, around the tone.
    lock_ins : array_like of complex, shape (C, R)
        The lock-in amplitudes of every ring (m; NaN rings left out).
    times, weights : array_like of float, shape (N,)
        The frame times (s) and their lock-in weights.

    Returns
    -------
    frequency : float
        The tone's frequency, Hz (within the comb).
    frequency_stderr : float
        Its standard error, Hz, from the curvature of the residual (inf when flat).
    profile : ndarray of complex, shape (R,)
        Its amplitude on every ring at that frequency (NaN where the ring had none).
    """
    f = np.asarray(comb, dtype=np.float64)
    a = np.asarray(lock_ins, dtype=np.complex128)
    rings = np.all(np.isfinite(a), axis=0)
    distinct = np.unique(f)  # a comb clipped at Nyquist repeats its last frequency
    if distinct.size < 3 or not np.any(rings):
        raise InputError("a tone needs lock-ins at three frequencies or more, on finite rings")
    data = a[:, rings]

    def fit(f0: float) -> tuple[float, np.ndarray]:
        response = lock_in_response(times, weights, f - f0)  # (C,)
        norm = float(np.sum(np.abs(response) ** 2))
        profile = response.conj() @ data / norm
        residual = data - np.outer(response, profile)
        return float(np.sum(np.abs(residual) ** 2)), profile

    best = int(np.argmax(np.sum(np.abs(data) ** 2, axis=1)))
    low, high = f[max(best - 1, 0)], f[min(best + 1, f.size - 1)]
    result = minimize_scalar(
        lambda f0: fit(f0)[0], bounds=(low, high), method="bounded", options={"xatol": 1e-9}
    )
    frequency = float(result.x)
    step = 1e-3 * float(np.median(np.diff(distinct)))
    rss = [fit(frequency + d)[0] for d in (-step, 0.0, step)]
    curvature = (rss[0] - 2.0 * rss[1] + rss[2]) / step**2
    dof = max(2 * data.size - 2 * data.shape[1] - 1, 1)
    stderr = math.sqrt(2.0 * rss[1] / dof / curvature) if curvature > 0 else math.inf
    profile = np.full(a.shape[1], np.nan + 0j)
    profile[rings] = fit(frequency)[1]
    return frequency, stderr, profile
