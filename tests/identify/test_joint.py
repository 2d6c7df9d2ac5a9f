"""Joint per-frame estimation: peaks aliasing in time unwrapped by the others, vibration out."""

from __future__ import annotations

import math

import numpy as np
import pytest
from identify_model import N_AIR, WAVELENGTH, ModelPeak, simulate
from lattice_recording import injection_setup, record

from holoview.errors import InputError
from holoview.optics.scenarios import ScenarioConfig
from holoview.optics.setup import Setup
from holoview.processing.series.depth_series import track_depth
from holoview.processing.series.joint_estimation import JointEstimator, _first_of_each
from holoview.processing.series.joint_series import estimate_joint
from holoview.processing.series.phase_series import unwrap_in_time

N2 = 1.333
#: RB1, RF, FB1, RB2, FB2, RB3, FB3: prefactor, coupling, amplitude, phase noise (rad).
FAMILIES = [
    ("RB1", N2 - N_AIR, -1, 10.0, 0.004),
    ("RF", N_AIR, 1, 3.0, 0.01),
    ("FB1", N2, 0, 2.0, 0.01),
    ("RB2", 2 * N2 - N_AIR, -1, 0.6, 0.05),
    ("FB2", 2 * N2, 0, 0.3, 0.08),
    ("RB3", 3 * N2 - N_AIR, -1, 0.2, 0.1),
    ("FB3", 3 * N2, 0, 0.1, 0.15),
]
ALPHAS = np.array([f[1] for f in FAMILIES])
COUPLINGS = np.array([f[2] for f in FAMILIES])


def model(rate: float, vibration: float, *, seconds: float = 12.0, seed: int = 3):
    peaks = [ModelPeak(k, a, c * N_AIR, amp, noise) for k, a, c, amp, noise in FAMILIES]
    return simulate(peaks, rate, fps=25.0, duration=seconds, vibration=vibration, seed=seed)


def test_peaks_stepping_past_pi_are_unwrapped_by_the_others():
    """2.5 um/s at 25 frames/s: FB2 steps 6.3 rad a frame, FB3 9.4; every peak's rate
    comes out within 1e-4, no frame flagged; the old per-peak rule drops four peaks."""
    rate = 2.5e-6
    recording = model(rate, 15e-9)
    steps = 4 * np.pi * ALPHAS * rate / 25 / WAVELENGTH
    assert steps[4] > 2 * np.pi and steps[6] > 3 * np.pi
    series = estimate_joint(recording.values, recording.times, ALPHAS, COUPLINGS, WAVELENGTH)
    assert not series.flagged.any()
    assert np.min(series.margins[1:]) > 5
    assert series.fit.relative_error(rate) < 1e-4
    for fit in series.peak_fits:
        assert fit.relative_error(rate) < 1e-4
    truth = [f[4] for f in FAMILIES]
    np.testing.assert_allclose(series.sigma[1:], truth[1:], rtol=0.25)  # measured noise
    old = track_depth(recording.values, recording.times, ALPHAS, WAVELENGTH)
    assert old.aliasing.aliased.sum() >= 4


def test_lost_frames_are_stepped_over_in_as_many_intervals():
    """A recording that lost 40 frames (1.6 s) at 0.5 um/s: across the gap the height
    moves 0.84 um, RB1 turns 10 times. Predicted over the 41 intervals it spans, the
    rate comes out within 1e-4 (fused) and 1e-3 (each peak's); predicted as one step,
    the series broke there."""
    rate = 5e-7
    recording = model(rate, 15e-9)
    keep = np.r_[0:100, 140 : recording.times.size]
    series = estimate_joint(
        recording.values[keep], recording.times[keep], ALPHAS, COUPLINGS, WAVELENGTH
    )
    assert series.fit.relative_error(rate) < 1e-4
    for fit in series.peak_fits:
        assert fit.relative_error(rate) < 1e-3


def test_per_frame_noise_from_the_carrier_amplitudes_can_be_given():
    """A spectrum bin's noise is the same for every peak: ``noise / |value|`` per frame."""
    rate = 2.5e-6
    recording = model(rate, 15e-9)
    sigma = 0.04 / np.abs(recording.values)
    series = estimate_joint(
        recording.values, recording.times, ALPHAS, COUPLINGS, WAVELENGTH, sigma=sigma
    )
    assert not series.flagged.any()
    assert series.fit.relative_error(rate) < 1e-4
    np.testing.assert_allclose(series.sigma, np.median(sigma, axis=0))
    with pytest.raises(InputError, match="sigma has shape"):
        estimate_joint(recording.values, recording.times, ALPHAS, COUPLINGS, WAVELENGTH,
                       sigma=sigma[:, :2])  # fmt: skip


def test_the_incremental_estimator_keeps_bounded_state_and_follows_the_run():
    rate = 1.27e-6
    recording = model(rate, 3e-9, seconds=40.0)
    estimator = JointEstimator(ALPHAS, COUPLINGS, WAVELENGTH)
    heights = []
    for t, values in enumerate(recording.values):
        frame = estimator.update(values)
        heights.append(frame.height)
        if t == 50:
            sizes = {k: np.size(v) for k, v in vars(estimator).items()}
    assert {k: np.size(v) for k, v in vars(estimator).items()} == sizes
    heights = np.array(heights)
    np.testing.assert_allclose(heights, recording.height, atol=2e-9)
    estimator.reset()
    assert estimator.update(recording.values[10]).height == 0.0


def test_a_peak_missing_for_frames_is_carried_over():
    rate = 1.27e-6
    recording = model(rate, 3e-9)
    values = recording.values.copy()
    values[100:104, 6] = np.nan  # FB3, stepping 4.8 rad a frame, missed for four frames
    values[:30, 4] = np.nan  # FB2 seen first at frame 30
    series = estimate_joint(values, recording.times, ALPHAS, COUPLINGS, WAVELENGTH)
    assert not series.flagged.any()
    assert np.isnan(series.depths[:30, 4]).all() and np.isnan(series.depths[100:104, 6]).all()
    for j in (4, 6):
        assert series.peak_fits[j].relative_error(rate) < 1e-4
    # a late peak starts where the fused depth is
    assert series.depths[30, 4] == pytest.approx(series.fused[30], abs=1e-9)


def test_an_unresolvable_step_is_flagged_with_its_margin():
    """FB1 alone stepping 2.5 rad a frame: at the first frames nothing tells 2.5 from
    2.5 - 2 pi, and the frames say so; with RB1 beside it they are resolved (glycerol:
    for water in air the alphas are nearly multiples of 1/3, and a first frame with
    nothing before it stays ambiguous, as the module documentation says)."""
    n2 = 1.473
    phase = 2.5 * np.arange(6)
    alone = JointEstimator([n2], [0], WAVELENGTH)
    frames = [alone.update(np.exp(1j * np.array([p]))) for p in phase]
    assert frames[1].flagged and frames[1].margin < 3
    assert math.isinf(frames[0].margin)
    pair = JointEstimator([n2 - N_AIR, n2], [0, 0], WAVELENGTH, sigma=[0.01, 0.01])
    both = np.exp(1j * np.outer(phase / n2, [n2 - N_AIR, n2]))
    frames = [pair.update(v) for v in both]
    assert not any(f.flagged for f in frames[1:])
    assert frames[-1].phases[1] == pytest.approx(phase[-1], abs=1e-6)


def test_injection_on_the_simulator_every_fast_peak_named_and_used():
    """The issue's target: 25 frames/s, RB2, FB2, RB3 and FB3 stepping 2 to 5 rad a frame
    (51 nm a frame), demodulated on the simulator's frames; RB1 and FB1 labelled."""
    setup, config = injection_setup()
    rec = record(setup, "injection", config, fps=25.0, frames=150, seed=2)
    per_frame = 4 * np.pi * rec.alphas * rec.rate / 25 / setup.wavelength
    steps = dict(zip(rec.labels, per_frame, strict=True))
    for label in ("RB2", "FB2", "RB3", "FB3"):
        assert label in rec.labels, label
        assert 2.0 <= steps[label] <= 5.0, (label, steps[label])
    series = estimate_joint(rec.values, rec.times, rec.alphas, rec.couplings, setup.wavelength)
    assert not series.flagged.any()
    assert series.fit.relative_error(rec.rate) < 0.003
    for label, fit in zip(rec.labels, series.peak_fits, strict=True):
        assert fit.relative_error(rec.rate) < 0.01, label
    old = track_depth(rec.values, rec.times, rec.alphas, setup.wavelength)
    left_out = {k for k, a in zip(rec.labels, old.aliasing.aliased, strict=True) if a}
    assert {"FB2", "RB3", "FB3"} <= left_out  # the per-peak rule leaves them out


def test_evaporation_with_vibration_fused_below_fb1_and_vibration_recovered():
    """15 nm rms of reference-arm vibration: RF and the RB_j carry it, FB1 does not; the
    joint estimate takes it out of the fused depth and returns it."""
    setup = Setup(shape=(256, 256))
    config = ScenarioConfig(vibration_rms=15e-9, vibration_time=0.05)
    rec = record(setup, "evaporation", config, fps=10.0, frames=200, seed=4)
    assert {"RF", "RB1", "FB1", "RB2"} <= set(rec.labels)
    series = estimate_joint(rec.values, rec.times, rec.alphas, rec.couplings, setup.wavelength)
    truth = rec.heights - rec.heights[0]
    fb1 = list(rec.labels).index("FB1")
    alone = unwrap_in_time(rec.values[:, fb1])[:, 0] * setup.wavelength / (4 * np.pi * N2)

    def noise(x: np.ndarray) -> float:
        return float(np.std(x - truth))

    assert noise(series.fused) < noise(alone)
    psi = rec.reference_phases - rec.reference_phases[0]
    assert np.std(psi) > 0.3  # rad: 15 nm of air path
    assert np.corrcoef(series.vibration, psi)[0, 1] > 0.9
    assert series.fit.relative_error(rec.rate) < 0.003


def test_bad_input_is_a_clear_error():
    with pytest.raises(InputError, match="positive and finite"):
        JointEstimator([0.3, -1.0], [-1, 1], WAVELENGTH)
    with pytest.raises(InputError, match="couplings"):
        JointEstimator([0.3, 1.0], [-1], WAVELENGTH)
    with pytest.raises(InputError, match="whole numbers"):
        JointEstimator([0.3, 1.0], [-1, 0.5], WAVELENGTH)
    with pytest.raises(InputError, match="wavelength"):
        JointEstimator([0.3, 1.0], [-1, 1], -1.0)
    with pytest.raises(InputError, match="sigma"):
        JointEstimator([0.3, 1.0], [-1, 1], WAVELENGTH, sigma=[0.1, 0.0])
    estimator = JointEstimator([0.3, 1.0], [-1, 1], WAVELENGTH)
    with pytest.raises(InputError, match="3 values given for 2 peaks"):
        estimator.update([1, 1j, 1])
    with pytest.raises(InputError, match="increasing"):
        estimate_joint(np.ones((3, 2)), [0, 0, 1], [0.3, 1.0], [-1, 1], WAVELENGTH)
    nothing = estimator.update([np.nan, np.nan])
    assert math.isnan(nothing.height)


def test_the_search_keeps_numpys_order_of_candidate_integers():
    """The integer rows' first occurrences, in lexicographic order, as numpy's own unique gives
    them (the best solution, and so the margins, are picked from that order on ties)."""
    rng = np.random.default_rng(1)
    cases = [
        rng.integers(-3, 4, size=(rng.integers(1, 60), rng.integers(1, 9))) for _ in range(300)
    ]
    cases.append(np.array([[0, 0, 0], [2**40, 2**40, 2**40], [0, 0, 0]]))  # keys past int64
    for turns in cases:
        rows = turns.astype(np.float64)
        expected = np.unique(rows, axis=0, return_index=True)[1]
        np.testing.assert_array_equal(_first_of_each(rows), expected)
