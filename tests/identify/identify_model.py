"""Mean-phase series from the analytic model, with known truth, for the identify tests.

Per peak ``m`` and frame ``t``: ``phase = 2 k0 (alpha_m h(t) + c_m dH(t)) + noise``, with
``h`` the surface height, ``dH`` the reference-arm length (vibration), ``c_m`` the
peak's coupling to the reference arm (``+n1`` for RF, ``-n1`` for RB_j on the twin where
alpha is positive, 0 for FB_j; doubled for a second order), and white noise per peak.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

WAVELENGTH = 532e-9
N_AIR = 1.000293


@dataclass(frozen=True)
class ModelPeak:
    """One peak of the analytic model: its prefactor, reference coupling, amplitude, noise."""

    name: str
    alpha: float
    coupling: float
    amplitude: float
    noise: float  # rad per frame, white


def model_peaks(n1: float, n2: float) -> list[ModelPeak]:
    """The brightest families, a ghost of RB1, RB1's second order and a stray peak."""
    return [
        ModelPeak("RB1", n2 - n1, -n1, 10.0, 0.004),
        ModelPeak("RF", n1, n1, 3.0, 0.01),
        ModelPeak("FB1", n2, 0.0, 2.0, 0.01),
        ModelPeak("RB1 ghost", n2 - n1, -n1, 1.0, 0.03),
        ModelPeak("RB2", 2 * n2 - n1, -n1, 0.6, 0.05),
        ModelPeak("2RB1", 2 * (n2 - n1), -2 * n1, 0.4, 0.06),
    ]


@dataclass(frozen=True)
class Recording:
    """Complex peak values over time with the truth they came from."""

    times: np.ndarray
    values: np.ndarray  # (frames, peaks) complex
    height: np.ndarray  # (frames,) m
    peaks: list[ModelPeak]
    rate: float  # true dh/dt, m/s


def simulate(
    peaks: list[ModelPeak],
    rate: float,
    *,
    fps: float,
    duration: float,
    vibration: float,
    seed: int,
) -> Recording:
    """Simulate the peaks' complex values: a linear depth change, vibration on the reference arm.

    ``vibration`` is the RMS reference-arm motion in m: a sum of a few tones of random
    phase between 0.3 and 3 Hz, as a table's vibration would be.
    """
    rng = np.random.default_rng(seed)
    times = np.arange(round(duration * fps)) / fps
    height = rate * times
    tones = rng.uniform(0.3, 3.0, 5)
    shifts = rng.uniform(0, 2 * np.pi, 5)
    arm = np.sum(np.sin(2 * np.pi * tones[:, None] * times + shifts[:, None]), axis=0)
    arm *= vibration / np.std(arm)
    k0 = 2 * np.pi / WAVELENGTH
    values = np.empty((times.size, len(peaks)), dtype=np.complex128)
    for m, peak in enumerate(peaks):
        phase = 2 * k0 * (peak.alpha * height + peak.coupling * arm)
        phase += rng.normal(0.0, peak.noise, times.size) + rng.uniform(0, 2 * np.pi)
        values[:, m] = peak.amplitude * np.exp(1j * phase)
    return Recording(times=times, values=values, height=height, peaks=peaks, rate=rate)
