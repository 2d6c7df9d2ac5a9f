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


def reference_arm(
    times: np.ndarray, vibration: float, drift: float, rng: np.random.Generator
) -> np.ndarray:
    """Reference-arm length over time, m: table vibration plus a slow air-path drift.

    ``vibration`` is the RMS of a sum of five tones of random phase between 0.3 and 3 Hz;
    ``drift`` the RMS of a random walk (thermal drift of the air path), both in m.
    """
    tones = rng.uniform(0.3, 3.0, 5)
    shifts = rng.uniform(0, 2 * np.pi, 5)
    arm = np.sum(np.sin(2 * np.pi * tones[:, None] * times + shifts[:, None]), axis=0)
    arm *= vibration / np.std(arm)
    walk = np.cumsum(rng.normal(size=times.size))
    walk -= walk.mean()
    return arm + walk * (drift / np.std(walk)) if drift > 0 else arm


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
    drift: float = 0.0,
    seed: int,
) -> Recording:
    """Simulate the peaks' complex values: a linear depth change, vibration on the reference arm.

    The reference arm moves as :func:`reference_arm` says (``vibration`` and ``drift``
    RMS, m).
    """
    rng = np.random.default_rng(seed)
    times = np.arange(round(duration * fps)) / fps
    height = rate * times
    arm = reference_arm(times, vibration, drift, rng)
    k0 = 2 * np.pi / WAVELENGTH
    values = np.empty((times.size, len(peaks)), dtype=np.complex128)
    for m, peak in enumerate(peaks):
        phase = 2 * k0 * (peak.alpha * height + peak.coupling * arm)
        phase += rng.normal(0.0, peak.noise, times.size) + rng.uniform(0, 2 * np.pi)
        values[:, m] = peak.amplitude * np.exp(1j * phase)
    return Recording(times=times, values=values, height=height, peaks=peaks, rate=rate)


@dataclass(frozen=True)
class SynthesisedRecording:
    """Carrier values of every detected peak over synthesised frames, and the truth.

    ``peaks`` are the detected peaks on the twin the model labelling says is stored
    (phase growing with the height); ``names`` their model labels (empty: unexplained).
    """

    times: np.ndarray
    values: np.ndarray  # (frames, peaks) complex
    peaks: list
    names: tuple[tuple[str, ...], ...]
    reference: int  # index of the peak labelled RB1
    rate: float  # true dh/dt, m/s


def synthesise(
    setup,
    scenario: str,
    config,
    *,
    fps: float,
    frames: int,
    seed: int,
) -> SynthesisedRecording:
    """Demodulate a recording of :func:`holoview.optics.scenarios.simulate`.

    The operator's procedure: peaks found in the first frame, RB1 and FB1 named where the
    model puts them, the model labels the rest and says which twin to keep; then every
    detected peak is demodulated (synthetic reference) and its carrier value kept. The
    true rate is the slope of the frames' true mean heights.
    """
    from holoview.optics.families import predict_families
    from holoview.optics.scenarios import simulate
    from holoview.processing.maps.demodulate import Demodulator
    from holoview.processing.naming.labelling import label_peaks
    from holoview.processing.peaks.detection import find_peaks

    stream = simulate(setup, scenario, frames=frames, fps=fps, seed=seed, config=config)
    first, first_truth = next(stream)
    detected = find_peaks(first)
    truth = {f.label: f for f in predict_families(setup, max_order=3)}
    anchors = {label: truth[label].observed_carrier for label in ("RB1", "FB1")}
    labelling = label_peaks(
        [p.carrier for p in detected], anchors, setup.n1, setup.n2, setup.shape, max_order=3
    )
    twins = {p.peak: p.twin for p in labelling.predictions if p.peak is not None}
    peaks = [p.flipped() if twins.get(i, False) else p for i, p in enumerate(detected)]
    demodulator = Demodulator(setup.shape, peaks, reference="synthetic", unwrap="never", threads=1)
    values = np.empty((frames, len(peaks)), dtype=np.complex128)
    times, heights = np.empty(frames), np.empty(frames)
    frame, frame_truth = first, first_truth
    for i in range(frames):
        if i > 0:
            frame, frame_truth = next(stream)
        values[i] = [r.carrier_value for r in demodulator.process(frame).peaks]
        times[i], heights[i] = frame_truth.time, frame_truth.mean_height
    return SynthesisedRecording(
        times=times,
        values=values,
        peaks=peaks,
        names=labelling.names,
        reference=labelling.anchors["RB1"],
        rate=float(np.polyfit(times, heights, 1)[0]),
    )
