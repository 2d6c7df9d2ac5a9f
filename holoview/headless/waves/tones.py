"""Tones in E(omega): the frequencies a wave field rings at, for the centre and the modes.

A tone is a local maximum of E(omega) of the waves beyond :data:`UNIFORM_SPREAD_STEPS`
wave-vector steps, standing :data:`PROMINENCE` times over its surroundings, its
frequency refined between bins (a parabola on the log-energy). A mode's tone, refined
from its lock-ins, is fitted as a partial wave only if it is one steady tone
(:func:`check_steady`).
"""

from __future__ import annotations

import math

import numpy as np

from holoview.errors import InputError
from holoview.processing.waves.omega_k import OmegaKSpectrum
from holoview.processing.waves.partial_waves import Tone, unsteady_tone

__all__ = [
    "PROMINENCE",
    "TONE_SURROUNDINGS",
    "UNIFORM_SPREAD_STEPS",
    "check_steady",
    "find_tones",
    "tone_energy",
]

#: Tones (the centre's frequency, the candidates) are sought in E(omega) of the waves
#: beyond this many wave-vector steps: the spatial taper spreads a uniform oscillation
#: (the reference arm's vibration in the RF and RB maps, nanometres) over the steps next
#: to zero, where it outweighed a mode larger than the field (the ringdown simulation's
#: 12 Hz mode, 18.6 mm long in a 5.1 mm field: E(omega)'s peak had been at 6.5 Hz).
UNIFORM_SPREAD_STEPS = 1.5

#: A tone stands this many times over E(omega) around it (the median of the bins within
#: :data:`TONE_SURROUNDINGS` of it, its own two either side left out). Measured: the
#: simulated partial waves' and ringdown's tones 89 to 20000 times, the lumps of 300
#: travelling plane waves 1.3 to 2.7, noise (a surface at rest) 1.03 to 1.2.
PROMINENCE = 3.0
TONE_SURROUNDINGS = 8


def tone_energy(spectrum: OmegaKSpectrum) -> tuple[np.ndarray, np.ndarray]:
    """E(omega) of the waves beyond :data:`UNIFORM_SPREAD_STEPS` wave-vector steps, where
    tones are sought."""
    return spectrum.energy_omega(k_min=UNIFORM_SPREAD_STEPS * max(spectrum.dk))


def find_tones(
    omega: np.ndarray,
    energy: np.ndarray,
    count: int,
    low: int,
    band: tuple[float, float] | None = None,
) -> list[float]:
    """Frequencies (Hz) of the largest tones of ``energy`` above bin ``low`` (and
    within ``band``, Hz, when given): local maxima :data:`PROMINENCE` times over their
    surroundings."""
    found = []
    hz = omega / (2 * math.pi)
    for i in np.argsort(energy)[::-1]:
        if i <= max(low, 0) or i >= energy.size - 1:
            continue
        if band is not None and not band[0] <= hz[i] <= band[1]:
            continue
        if energy[i] < energy[i - 1] or energy[i] < energy[i + 1]:
            continue
        around = np.r_[
            energy[max(i - TONE_SURROUNDINGS, 1) : max(i - 2, 1)],
            energy[i + 3 : i + TONE_SURROUNDINGS + 1],
        ]
        if around.size and energy[i] < PROMINENCE * float(np.median(around)):
            continue
        logs = np.log(np.maximum(energy[i - 1 : i + 2], np.finfo(float).tiny))
        curvature = logs[0] - 2 * logs[1] + logs[2]
        shift = 0.5 * (logs[0] - logs[2]) / curvature if curvature < 0 else 0.0
        found.append(float((omega[i] + shift * (omega[1] - omega[0])) / (2 * math.pi)))
        if len(found) >= count:
            break
    return found


def check_steady(
    tone: Tone,
    comb: np.ndarray,
    lock_ins: np.ndarray,
    weights: np.ndarray,
    *,
    times: np.ndarray,
    noise: np.ndarray,
    m: int,
) -> None:
    """Refuse a tone whose lock-ins one steady tone does not explain.

    Parameters
    ----------
    tone : Tone
        What :func:`~holoview.processing.waves.partial_waves.refine_tone` made of
        ``lock_ins`` (C, R) at ``comb`` (C,), with ``weights`` at ``times`` (N,).
    noise : ndarray of float, shape (R,)
        Each ring's noise variance beside the tone
        (:meth:`~holoview.processing.waves.azimuthal.AzimuthalAccumulator.profile_noise`).
    m : int
        The tone's azimuthal number (m = 0 holds the maps' level).

    Raises
    ------
    InputError
        Not one steady tone (:func:`~holoview.processing.waves.partial_waves.unsteady_tone`),
        saying how far from one and where the other lies.
    """
    found = unsteady_tone(comb, lock_ins, times, weights, tone=tone, noise=noise, level=m == 0)
    if found is None:
        return
    duration = float(times[-1] - times[0])
    raise InputError(
        f"not one steady tone: it leaves {found.excess:.3g} times the noise beside it, and "
        f"a second tone near {found.second:.4g} Hz would move its profile by "
        f"{100 * found.shift:.3g} % (two waves of this m too close for {duration:.3g} s "
        "of record to part, or a mode that grows or decays: --ringdown)"
    )
