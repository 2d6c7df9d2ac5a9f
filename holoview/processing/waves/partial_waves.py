"""Incoming and outgoing parts of one partial wave: a Hankel fit to its radial profile.

With ``h = Re(A_m(r) exp(i (m theta - omega t)))`` (the ``exp(-i omega t)`` convention),
a free wave of wavenumber ``k`` has ``A_m(r) = out H_m^(1)(k r) + in H_m^(2)(k r)``:
``H^(1) ~ exp(+i k r)`` travels outwards, ``H^(2)`` inwards. :func:`fit_partial_wave`
fits the complex ``in`` and ``out`` (m) to a profile by linear least squares,
weighting each ring by its radius (a ring of radius ``r`` averages about ``2 pi r``
pixels); ``k`` is given (the dispersion relation at ``f``) or refined by minimising
the residual around it. Standard errors come from the residual scatter and the fit's
Jacobian in ``k`` and the coefficients together (an error in ``k`` turns both
coefficients' phases by about ``dk r``); the rings are a pixel apart, and the maps
carry no structure finer than ``pi / k_cut``, so the covariance is multiplied by
``max(1, pi / (k_cut dr))`` (the rings' noise summed over a disk of wavenumbers up to
``k_cut``; 5.3 on the accuracy benchmark's maps). Arrays of noise white up to the
pixels' Nyquist wavenumber (no ``k_cut``) have their neighbouring rings correlated by
the interpolation itself (0.10 to 0.11 at a pixel apart), which the errors leave out:
they come out 6 to 11 % small there. The amplitudes' errors are those of their moduli and of
their phases: the phases are the less certain.

A lock-in at a frequency ``f`` a little off a tone's ``f0`` returns the tone's amplitude
times the response ``W(f - f0) = sum w exp(2 pi i (f - f0) t) / sum w`` of the weights
on the frame times. :func:`refine_tone` takes lock-ins at a comb of frequencies around
a tone (every ring at once) and fits ``f0`` and the profile ``A(r)``, so that the
amplitude is not lost to the comb's spacing nor to a frequency known only to a
fraction of a spectral bin. The comb's lock-ins are a quarter of a resolution apart,
nearly the same numbers: their noise is correlated as ``sum w^2 exp(2 pi i (f_j - f_k)
t)``, and the frequency's error is propagated with that correlation, each ring's noise
measured from its residual off the tone. A frequency off by ``df`` turns the profile's
phase (that of ``t = 0``) by ``2 pi df t_mean``, ``t_mean`` the weights' mean time:
:func:`fit_partial_wave` adds it to the coefficients' phases. :func:`unsteady_tone` says
where one steady tone does not explain the lock-ins (two tones of one m that the record
does not part, a mode that grows or decays), against each ring's noise beside the tone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special
from scipy.optimize import minimize, minimize_scalar

from holoview.errors import InputError

__all__ = [
    "PartialWaveFit",
    "Tone",
    "Unsteady",
    "fit_partial_wave",
    "lock_in_response",
    "refine_tone",
    "unsteady_tone",
]

#: A tone's lock-ins are not one steady tone when what the tone leaves of them is this
#: many times its expectation from the noise beside it, and :data:`UNSTEADY_Z` of its
#: standard deviations over it (the ratio guards against the noise's level being off,
#: the z against a chance excess). On white noise that level holds to 10-20 %; beside a
#: tone it can be off by a factor of 2 (noise that is not white: at m = 0 each frame's
#: piston left 2.0 times it beside a steady wave, ``accuracy_waves.py``'s seed 8, before
#: :func:`unsteady_tone` left the piston out). Two tones a resolution apart or a
#: decaying mode leave more: the tests' 994-4000 times it; ``bench_waves.py``'s four
#: modes, blends of tones and a decaying mode, 5.2-92...
UNSTEADY_EXCESS = 3.0
UNSTEADY_Z = 5.0
#: ... and a second tone fitted with it moves its profile by this fraction (rms over
#: the rings): the size of error the partial waves' amplitudes are held to.
UNSTEADY_SHIFT = 0.02


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
        Standard error of each one's modulus, m.
    incoming_phase_stderr, outgoing_phase_stderr : float
        Standard error of each one's phase, rad (inf for a coefficient of 0).
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
    incoming_phase_stderr: float
    outgoing_phase_stderr: float
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
            "incoming_phase_stderr_rad": self.incoming_phase_stderr,
            "outgoing_amplitude_m": abs(self.outgoing),
            "outgoing_phase_rad": math.atan2(self.outgoing.imag, self.outgoing.real),
            "outgoing_stderr_m": self.outgoing_stderr,
            "outgoing_phase_stderr_rad": self.outgoing_phase_stderr,
            "incoming_over_outgoing": self.ratio,
            "incoming_over_outgoing_stderr": self.ratio_stderr,
            "rings": int(self.radii.size),
            "r_range_m": [float(self.radii[0]), float(self.radii[-1])],
            "rms_residual_m": self.rms_residual,
        }


@dataclass(frozen=True)
class Tone:
    """One tone refined from lock-ins at a comb of frequencies (:func:`refine_tone`).

    Attributes
    ----------
    frequency, frequency_stderr : float
        Hz.
    phase_stderr : float
        Standard error of a phase common to every ring's amplitude, rad: a frequency off
        by ``df`` turns the amplitudes (referred to ``t = 0``) by ``2 pi df t_mean``,
        ``t_mean`` the lock-in weights' mean time.
    profile : ndarray of complex, shape (R,)
        The tone's amplitude on every ring, m (NaN where the ring had none).
    """

    frequency: float
    frequency_stderr: float
    phase_stderr: float
    profile: NDArray[np.complex128]


@dataclass(frozen=True)
class Unsteady:
    """Lock-ins around a tone that one steady tone does not explain (:func:`unsteady_tone`).

    Attributes
    ----------
    excess : float
        What the tone leaves of the lock-ins, over its expectation from the noise.
    second : float
        Hz: the other tone of the best fit of two.
    shift : float
        How far that fit moves the tone's profile, rms over the rings, relative.
    """

    excess: float
    second: float
    shift: float


def _solve(
    radii: np.ndarray, profile: np.ndarray, m: int, k: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """Weighted complex least squares: coefficients (out, in), design, weighted RSS."""
    design = np.column_stack([special.hankel1(m, k * radii), special.hankel2(m, k * radii)])
    root = np.sqrt(radii)
    coefficients, *_ = np.linalg.lstsq(design * root[:, None], profile * root, rcond=None)
    residual = (profile - design @ coefficients) * root
    return coefficients, design, float(np.sum(np.abs(residual) ** 2))


def _jacobian(
    radii: np.ndarray,
    design: np.ndarray,
    coefficients: np.ndarray,
    m: int,
    k: float,
    *,
    fit_wavenumber: bool,
) -> np.ndarray:
    """The weighted model's derivatives in (Re out, Im out, Re in, Im in[, k]), real
    and imaginary parts of the rings stacked: shape (2 R, 4 or 5)."""
    columns = [design[:, 0], 1j * design[:, 0], design[:, 1], 1j * design[:, 1]]
    if fit_wavenumber:
        out, inc = coefficients
        columns.append(
            radii * (out * special.h1vp(m, k * radii) + inc * special.h2vp(m, k * radii))
        )
    weighted = np.column_stack(columns) * np.sqrt(radii)[:, None]
    return np.vstack([weighted.real, weighted.imag])


def _radial(value: complex) -> np.ndarray:
    """The unit vector (Re, Im) along ``value`` (along the real axis for 0)."""
    modulus = abs(value)
    return np.array([value.real, value.imag]) / modulus if modulus > 0 else np.array([1.0, 0.0])


def _polar_errors(value: complex, covariance: np.ndarray) -> tuple[float, float]:
    """Standard errors of the modulus and the phase (rad, inf for 0) of ``value``, given
    the covariance of its real and imaginary parts."""
    radial = _radial(value)
    across = np.array([-radial[1], radial[0]])
    spread = math.sqrt(max(float(across @ covariance @ across), 0.0))
    return (
        math.sqrt(max(float(radial @ covariance @ radial), 0.0)),
        spread / abs(value) if abs(value) > 0 else math.inf,
    )


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
    phase_stderr: float = 0.0,
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
    phase_stderr : float
        Standard error of a phase common to every ring of the profile, rad (a lock-in's,
        from its frequency's error: :attr:`Tone.phase_stderr`); added to the errors of
        the coefficients' phases.

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
    coefficients, design, rss = _solve(r, a, m, k)
    outgoing, incoming = complex(coefficients[0]), complex(coefficients[1])
    jacobian = _jacobian(r, design, coefficients, m, k, fit_wavenumber=fit_wavenumber)
    step = float(np.median(np.diff(r)))
    correlation = 1.0 if k_cut is None else max(1.0, math.pi / (k_cut * step))
    variance = rss / max(jacobian.shape[0] - jacobian.shape[1], 1) * correlation
    try:  # of (Re out, Im out, Re in, Im in[, k])
        covariance = np.linalg.inv(jacobian.T @ jacobian) * variance
    except np.linalg.LinAlgError as exc:
        raise InputError(f"partial wave m={m} at {frequency:.4g} Hz: singular fit") from exc
    k_err = math.sqrt(max(covariance[4, 4], 0.0)) if fit_wavenumber else 0.0
    out_err, out_phase_err = _polar_errors(outgoing, covariance[:2, :2])
    in_err, in_phase_err = _polar_errors(incoming, covariance[2:4, 2:4])
    # a phase common to the rings turns both coefficients, and changes no modulus
    out_phase_err = math.hypot(out_phase_err, phase_stderr)
    in_phase_err = math.hypot(in_phase_err, phase_stderr)
    if abs(outgoing) > 0:
        ratio = abs(incoming) / abs(outgoing)
        gradient = np.concatenate([-ratio * _radial(outgoing), _radial(incoming)]) / abs(outgoing)
        ratio_err = math.sqrt(max(float(gradient @ covariance[:4, :4] @ gradient), 0.0))
    else:
        ratio, ratio_err = math.inf, math.inf
    if not all(math.isfinite(v) for v in (out_err, in_err, k_err)):
        raise InputError(f"partial wave m={m} at {frequency:.4g} Hz: the fit did not converge")
    model = design @ coefficients
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
        incoming_phase_stderr=in_phase_err,
        outgoing_phase_stderr=out_phase_err,
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


def _comb_correlation(comb: np.ndarray, t: np.ndarray, w: np.ndarray) -> NDArray[np.complex128]:
    """The correlation ``S`` (C, C) of white noise's lock-ins at ``comb`` (Hz) with weights
    ``w`` at ``t``: ``E[dL dL^H] = 2 s^2 S``, ``s^2`` a lock-in's variance in each part."""
    offsets = np.subtract.outer(comb, comb)
    return lock_in_response(t, w**2, offsets.ravel()).reshape(offsets.shape)


def refine_tone(
    comb: ArrayLike,
    lock_ins: ArrayLike,
    times: ArrayLike,
    weights: ArrayLike,
) -> Tone:
    """Fit one tone's frequency and profile to lock-ins at a comb of frequencies.

    Parameters
    ----------
    comb : array_like of float, shape (C,)
        The lock-in frequencies, Hz, ascending, around the tone.
    lock_ins : array_like of complex, shape (C, R)
        The lock-in amplitudes of every ring (m; NaN rings left out).
    times, weights : array_like of float, shape (N,)
        The frame times (s) and their lock-in weights.

    Returns
    -------
    Tone
        The frequency (within the comb) and the profile at it. The frequency's error is
        the linear response of the fit to the lock-ins' noise, correlated along the comb
        as the weights make white noise, each ring's noise measured from its residual
        (inf when the fit is flat). It wants several rings: one ring's residual holds
        about 2.7 degrees of freedom of its noise (with one ring the frequencies scatter
        2.2 times as widely as their errors say, with six 1.1 times).

    Raises
    ------
    InputError
        Fewer than three distinct frequencies or no finite ring, or lock-ins whose power
        rises to an end of the comb (the tone lies beyond it).
    """
    f = np.asarray(comb, dtype=np.float64)
    a = np.asarray(lock_ins, dtype=np.complex128)
    t = np.asarray(times, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    rings = np.all(np.isfinite(a), axis=0)
    distinct = np.unique(f)  # a comb clipped at Nyquist repeats its last frequency
    if distinct.size < 3 or not np.any(rings):
        raise InputError("a tone needs lock-ins at three frequencies or more, on finite rings")
    data = a[:, rings]
    power = np.sum(np.abs(data) ** 2, axis=1)
    best = int(np.argmax(power))
    if (best == 0 and power[0] > power[1]) or (best == f.size - 1 and power[-1] > power[-2]):
        raise InputError(
            f"the lock-ins' power rises to {f[best]:.4g} Hz, the end of their comb "
            f"({f[0]:.4g} to {f[-1]:.4g} Hz): the tone lies beyond it"
        )

    def unit(f0: float) -> np.ndarray:
        """The comb's response to a tone at ``f0``, of unit norm."""
        response = lock_in_response(t, w, f - f0)
        return response / np.linalg.norm(response)

    def rss(f0: float) -> float:
        u = unit(f0)
        return float(np.sum(np.abs(data - np.outer(u, u.conj() @ data)) ** 2))

    result = minimize_scalar(
        rss,
        bounds=(f[max(best - 1, 0)], f[min(best + 1, f.size - 1)]),
        method="bounded",
        options={"xatol": 1e-9},
    )
    frequency = float(result.x)
    step = 1e-3 * float(np.median(np.diff(distinct)))
    values = [rss(frequency + d) for d in (-step, 0.0, step)]
    curvature = (values[0] - 2.0 * values[1] + values[2]) / step**2
    response = lock_in_response(t, w, f - frequency)
    u = response / np.linalg.norm(response)
    du = (unit(frequency + step) - unit(frequency - step)) / (2.0 * step)
    along = u.conj() @ data  # (R,)
    # the response of the rss's slope in f0 to each ring's lock-ins, d slope / d conj(L)
    score = -(np.outer(u, du.conj() @ data) + np.outer(du, along))
    # white noise gives the lock-ins E[dL dL^H] = 2 s^2 shape, s^2 a lock-in's variance
    # in each of its real and imaginary parts
    shape = _comb_correlation(f, t, w)
    off_tone = np.eye(f.size) - np.outer(u, u.conj())
    residual = np.sum(np.abs(off_tone @ data) ** 2, axis=0)
    noise = residual / (2.0 * float(np.trace(off_tone @ shape).real))  # s^2 of each ring
    spread = np.real(np.einsum("cr,cd,dr->r", score.conj(), shape, score))
    slope_variance = 4.0 * float(np.sum(noise * spread))
    stderr = math.sqrt(slope_variance) / curvature if curvature > 0 else math.inf
    profile = np.full(a.shape[1], np.nan + 0j)
    profile[rings] = along / np.linalg.norm(response)
    mean_time = float(np.sum(w * t) / np.sum(w))
    return Tone(frequency, stderr, 2.0 * math.pi * abs(mean_time) * stderr, profile)


def unsteady_tone(
    comb: ArrayLike,
    lock_ins: ArrayLike,
    times: ArrayLike,
    weights: ArrayLike,
    *,
    tone: Tone,
    noise: ArrayLike,
    level: bool = False,
) -> Unsteady | None:
    """Say whether one steady tone explains the lock-ins it was refined from.

    Two tones of the same ``m`` closer than the comb's reach, or a mode that grows or
    decays, fit as one tone between them, with an amplitude that is neither's and errors
    measured from what the fit leaves (two tones of 10 and 8 nm 0.4 Hz apart, resolved
    by 0.39 Hz: one of 7.4 nm, 30 standard errors off). The comb's own residual cannot
    tell: it holds two or three degrees of freedom a ring, which a second tone takes
    up. The noise beside the tone in each ring's (m, f) spectrum can: the residual off
    the tone, against its expectation from that noise (``2 s^2 tr((I - u u^H) S)`` a
    ring, ``S`` the lock-ins' correlation), is the test; where it stands out
    (:data:`UNSTEADY_EXCESS`, :data:`UNSTEADY_Z`), two tones are fitted (one in the comb,
    the other within four resolutions of it), and where the second moves the tone's
    profile by :data:`UNSTEADY_SHIFT` or more, the tone is not one.

    Parameters
    ----------
    comb, lock_ins, times, weights
        As :func:`refine_tone` took them.
    tone : Tone
        What :func:`refine_tone` made of them.
    noise : array_like of float, shape (R,)
        Each ring's noise variance in each of the real and imaginary parts of a lock-in
        (NaN where unknown: the ring is left out).
    level : bool
        The lock-ins are m = 0's, which hold each frame's level (the maps' piston, the
        same on every ring): what the tone leaves that is common to every ring is left
        out of the test. A second wave is not the same on every ring; the piston is not
        white, and near the tone it left 2.0 and 5.2 times the noise beside it
        (``accuracy_waves.py``'s seeds 8 and 10, steady m = 0 waves at 14 Hz), 0.004
        and 0.06 times without it. The noise beside holds the piston too, so at m = 0 a
        second tone must stand out of the piston's level.

    Returns
    -------
    Unsteady or None
        None where one steady tone explains them.
    """
    f = np.asarray(comb, dtype=np.float64)
    a = np.asarray(lock_ins, dtype=np.complex128)
    t = np.asarray(times, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    s2 = np.asarray(noise, dtype=np.float64)
    rings = np.all(np.isfinite(a), axis=0) & np.isfinite(s2) & (s2 > 0)
    if not np.any(rings):
        return None
    data, s2 = a[:, rings], s2[rings]
    response = lock_in_response(t, w, f - tone.frequency)
    u = response / np.linalg.norm(response)
    off_tone = np.eye(f.size) - np.outer(u, u.conj())
    shape = _comb_correlation(f, t, w)
    spread = off_tone @ shape
    alone = tone.profile[rings]
    rings_tested = s2.size
    if level and s2.size > 1:  # the part common to every ring (whitened) left out
        common = 1.0 / np.sqrt(s2)
        common /= np.linalg.norm(common)
        whitened = data / np.sqrt(s2)
        data = (whitened - np.outer(whitened @ common, common)) * np.sqrt(s2)
        alone = (response.conj() @ data) / float(np.sum(np.abs(response) ** 2))
        rings_tested -= 1
    mean = 2.0 * float(np.trace(spread).real) * rings_tested
    variance = 4.0 * float(np.trace(spread @ spread).real) * rings_tested
    left = float(np.sum(np.sum(np.abs(off_tone @ data) ** 2, axis=0) / s2))
    if left < UNSTEADY_EXCESS * mean or left - mean < UNSTEADY_Z * math.sqrt(variance):
        return None
    first, second, coefficients = _two_tones(f, data, t, w)
    main = 0 if abs(first - tone.frequency) <= abs(second - tone.frequency) else 1
    shift = float(np.linalg.norm(coefficients[main] - alone) / np.linalg.norm(alone))
    if shift < UNSTEADY_SHIFT:
        return None
    return Unsteady(left / mean, (second, first)[main], shift)


def _two_tones(
    f: np.ndarray, data: np.ndarray, t: np.ndarray, w: np.ndarray
) -> tuple[float, float, np.ndarray]:
    """The two tones (Hz) that best fit the lock-ins ``data`` (C, R) at the comb ``f``,
    one within the comb, the other within four resolutions of it and at least three
    quarters of a resolution from the first (closer, the two are too alike to part),
    with their profiles (2, R)."""
    weighted = t[w > 0]
    resolution = 1.0 / max(float(np.ptp(weighted)), 1e-300)
    total = float(np.sum(np.abs(data) ** 2))

    # the comb's lock-in of each frame, so that a tone's response is one product:
    # lock_in_response(t, w, f - g) = comb @ exp(-2 pi i g t)
    comb = np.exp(2j * np.pi * np.outer(f, t)) * (w / np.sum(w))

    def responses(frequencies: np.ndarray) -> np.ndarray:
        """The comb's responses (C, K) to tones at ``frequencies`` (K,)."""
        return comb @ np.exp(-2j * np.pi * np.outer(t, frequencies))

    def left(pair: np.ndarray, model: np.ndarray | None = None) -> float:
        if abs(pair[0] - pair[1]) < 0.75 * resolution:
            return total
        basis, _ = np.linalg.qr(responses(pair) if model is None else model)
        return total - float(np.sum(np.abs(basis.conj().T @ data) ** 2))

    # a grid of pairs from responses made once, then refined
    inside = np.linspace(f[0], f[-1], 9)
    around = np.linspace(f[0] - 4 * resolution, f[-1] + 4 * resolution, 73)
    grid = responses(np.concatenate([inside, around]))
    pairs = [(i, j) for i in range(inside.size) for j in range(around.size)]
    i, j = min(
        pairs,
        key=lambda ij: left(
            np.array([inside[ij[0]], around[ij[1]]]),
            grid[:, [ij[0], inside.size + ij[1]]],
        ),
    )
    best = minimize(
        left,
        np.array([inside[i], around[j]]),
        method="Nelder-Mead",
        options={"xatol": 1e-4 * resolution, "fatol": 1e-12 * total},
    )
    pair = np.asarray(best.x, dtype=np.float64)
    coefficients = np.linalg.lstsq(responses(pair), data, rcond=None)[0]
    return float(pair[0]), float(pair[1]), coefficients
