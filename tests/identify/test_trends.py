"""Depth tracking: temporal unwrapping, aliasing flags, fusion, rates, volumes."""

from __future__ import annotations

import numpy as np
import pytest
from identify_model import N_AIR, WAVELENGTH, ModelPeak, model_peaks, simulate

from holoview.errors import InputError
from holoview.processing.series.depth_series import (
    depth_series,
    fuse_depths,
    series_noise,
    track_depth,
)
from holoview.processing.series.phase_series import check_aliasing, phase_steps, unwrap_in_time
from holoview.processing.series.rate_fits import (
    compare_rate,
    depth_to_volume,
    fit_rate,
    volume_to_depth,
)

INJECTION_AREA = 70.6e-4  # m^2
INJECTION_RATE = 12.3e-9  # m^3/s (12.3 uL/s)


def test_unwrap_in_time_follows_a_ramp_over_many_turns():
    phase = 0.9 * np.arange(500)  # rad, about 72 turns
    unwrapped = unwrap_in_time(np.exp(1j * (phase + 1.0)) * 5)
    np.testing.assert_allclose(unwrapped[:, 0], phase, atol=1e-9)
    np.testing.assert_allclose(unwrap_in_time(np.angle(np.exp(1j * phase)))[:, 0], phase)


def test_unwrap_in_time_steps_over_missing_frames():
    phase = 0.5 * np.arange(20)
    values = np.exp(1j * phase).astype(np.complex128)
    values[5:7] = np.nan
    unwrapped = unwrap_in_time(values[:, None])[:, 0]
    assert np.all(np.isnan(unwrapped[5:7]))
    np.testing.assert_allclose(unwrapped[7:], phase[7:], atol=1e-9)


def test_phase_steps_are_wrapped():
    steps = phase_steps(np.exp(1j * 2.0 * np.arange(10)))
    np.testing.assert_allclose(steps[:, 0], 2.0 - 0.0, atol=1e-12)
    steps = phase_steps(np.exp(1j * 4.0 * np.arange(10)))
    np.testing.assert_allclose(steps[:, 0], 4.0 - 2 * np.pi, atol=1e-12)


def test_aliasing_flags_steps_near_pi_and_past_it():
    rng = np.random.default_rng(0)
    true_steps = np.array([0.5, 3.05, 4.4])  # rad per frame; the last is past pi
    phases = np.cumsum(true_steps + rng.normal(0, 0.05, (400, 3)), axis=0)
    measured = check_aliasing(np.exp(1j * phases))
    assert measured.aliased.tolist() == [False, True, False]  # 4.4 looks like -1.88
    assert measured.measured_step[2] == pytest.approx(4.4 - 2 * np.pi, abs=0.02)
    assert measured.noise == pytest.approx([0.05, 0.05, 0.05], rel=0.2)
    predicted = check_aliasing(np.exp(1j * phases), predicted_step=true_steps)
    assert predicted.aliased.tolist() == [False, True, True]
    assert np.all((predicted.margin < 0) == predicted.aliased)


def test_depth_series_converts_phase_with_alpha():
    phases = np.array([[0.0, 0.0], [4 * np.pi, 2 * np.pi]])
    depths = depth_series(phases, [1.0, 0.5], WAVELENGTH)
    np.testing.assert_allclose(depths[1], [WAVELENGTH, WAVELENGTH])
    with pytest.raises(InputError, match="alpha must be finite and nonzero"):
        depth_series(phases, [1.0, 0.0], WAVELENGTH)
    with pytest.raises(InputError, match="wavelength must be > 0"):
        depth_series(phases, [1.0, 1.0], -1.0)


def test_series_noise_measures_each_peak():
    rng = np.random.default_rng(1)
    times = np.arange(2000) * 0.1
    depth = 1e-8 * times[:, None] + rng.normal(0, 1.0, (2000, 2)) * [1e-9, 4e-9]
    residual = series_noise(depth, times)
    assert residual == pytest.approx([1e-9, 4e-9], rel=0.05)
    assert series_noise(depth, times, "difference") == pytest.approx([1e-9, 4e-9], rel=0.05)
    # A slow oscillation counts in the residual, hardly in the differences.
    wavy = depth + 5e-9 * np.sin(2 * np.pi * times / 50)[:, None]
    assert series_noise(wavy, times)[0] > 3e-9
    assert series_noise(wavy, times, "difference")[0] < 1.2e-9
    with pytest.raises(InputError, match="unknown noise method"):
        series_noise(depth, times, "spectral")


def test_fusion_weights_by_inverse_variance_and_excludes():
    depths = np.array([[0.0, 0.0, 5.0], [1.0, 3.0, 5.0]])
    fused = fuse_depths(depths, [1.0, 2.0, 1.0], exclude=[False, False, True])
    np.testing.assert_allclose(fused.weights, [0.8, 0.2, 0.0])
    np.testing.assert_allclose(fused.depth, [0.0, 0.8 * 1 + 0.2 * 3])
    assert fused.used.tolist() == [True, True, False]
    np.testing.assert_allclose(fused.spread[1], np.sqrt(0.8 * 0.4**2 + 0.2 * 1.6**2))


def test_fusion_renormalises_over_the_peaks_a_frame_has():
    depths = np.array([[1.0, 3.0], [np.nan, 3.0], [np.nan, np.nan]])
    fused = fuse_depths(depths, [1.0, 1.0])
    np.testing.assert_allclose(fused.depth[:2], [2.0, 3.0])
    assert np.isnan(fused.depth[2])
    with pytest.raises(InputError, match="no peak left"):
        fuse_depths(depths, [1.0, 1.0], exclude=[True, True])
    with pytest.raises(InputError, match="no peak left"):
        fuse_depths(depths, [np.nan, 0.0])


def test_rate_standard_error_matches_the_scatter_of_fits():
    rng = np.random.default_rng(2)
    times = np.arange(300) * 0.1
    fits = [fit_rate(times, 2e-8 * times + rng.normal(0, 1e-9, 300)) for _ in range(300)]
    rates = np.array([f.rate for f in fits])
    assert np.mean(rates) == pytest.approx(2e-8, rel=0.01)
    assert np.mean([f.stderr for f in fits]) == pytest.approx(np.std(rates), rel=0.15)


def test_rate_standard_error_allows_for_correlated_noise():
    rng = np.random.default_rng(3)
    times = np.arange(400) * 0.1
    rates, errors = [], []
    for _ in range(200):
        red = np.zeros(400)
        kicks = rng.normal(0, 1e-9, 400)
        for i in range(1, 400):
            red[i] = 0.8 * red[i - 1] + kicks[i]
        fit = fit_rate(times, red)
        assert fit.lag1 > 0.5
        rates.append(fit.rate)
        errors.append(fit.stderr)
    # Ignoring the correlation would understate the error by sqrt(9) = 3.
    assert np.mean(errors) == pytest.approx(np.std(rates), rel=0.3)


@pytest.mark.parametrize("correlation", [0.4, 0.7])
def test_rate_standard_error_holds_on_a_short_record_of_correlated_noise(correlation):
    # 20 frames of AR(1) noise: the residuals' own lag-1 correlation falls short of the
    # noise's by (2 + 3 rho) / n and more on few frames, which left the error 20-35 % small.
    rng = np.random.default_rng(4)
    trials, n = 1000, 20
    kicks = rng.normal(0, 1e-9, (trials, n))
    kicks[:, 0] /= np.sqrt(1 - correlation**2)  # start in the stationary state
    noise = np.zeros_like(kicks)
    noise[:, 0] = kicks[:, 0]
    for i in range(1, n):
        noise[:, i] = correlation * noise[:, i - 1] + kicks[:, i]
    times = np.arange(n) / 20.0
    fits = [fit_rate(times, 3e-8 * times + row) for row in noise]
    rates = np.array([f.rate for f in fits])
    errors = np.array([f.stderr for f in fits])
    assert np.mean([f.lag1 for f in fits]) == pytest.approx(correlation, abs=0.08)
    assert np.median(errors) / np.std(rates) == pytest.approx(1.0, abs=0.13)
    assert np.mean(np.abs(rates - 3e-8) < 2 * errors) > 0.85


def test_a_rate_fitted_after_another_is_that_of_its_own_times():
    # the residual model of the last times fitted is kept for the next fit on the same
    # times (the peaks of a series): times of the same length but other values (uneven,
    # or a lost frame) must not take it
    rng = np.random.default_rng(5)
    even = np.arange(40) / 20.0
    uneven = even + np.r_[0.0, np.cumsum(rng.uniform(0, 0.02, 39))]
    gapped = np.delete(np.arange(41) / 20.0, 17)
    depth = 3e-8 * even + rng.normal(0, 1e-9, 40)
    short = np.arange(30) / 20.0

    def other_times_first() -> None:
        fit_rate(short, depth[:30])  # a model of another length kept

    other_times_first()
    alone = fit_rate(even, depth)
    for other in (uneven, gapped):
        other_times_first()
        assert fit_rate(other, depth).stderr != alone.stderr  # a model of these kept
        assert fit_rate(even, depth) == alone


def test_rate_needs_three_frames_and_ordered_times():
    with pytest.raises(InputError, match="at least three"):
        fit_rate([0.0, 1.0], [0.0, 1.0])
    with pytest.raises(InputError, match="strictly increasing"):
        fit_rate([0.0, 2.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(InputError, match="true rate is zero"):
        fit_rate([0.0, 1.0, 2.0], [0.0, 1.0, 2.0]).relative_error(0.0)


def test_volume_and_depth_convert_with_the_basin_area():
    assert float(depth_to_volume(1e-6, INJECTION_AREA)) == pytest.approx(7.06e-9)
    assert float(volume_to_depth(12.3e-9, INJECTION_AREA)) == pytest.approx(1.7422e-6, rel=1e-4)
    with pytest.raises(InputError, match="area must be positive"):
        depth_to_volume(1.0, 0.0)


def test_compare_rate_against_a_known_injection():
    times = np.arange(100) * 0.04
    depth = INJECTION_RATE / INJECTION_AREA * 1.01 * times
    depth += np.random.default_rng(4).normal(0, 1e-10, 100)
    result = compare_rate(fit_rate(times, depth), INJECTION_AREA, INJECTION_RATE)
    assert result.relative_error == pytest.approx(0.01, abs=1e-3)
    assert result.z_score > 10


@pytest.mark.parametrize(
    ("values", "message"),
    [
        (np.ones((1, 3), dtype=complex), "1 frame"),
        (np.full((5, 2), np.nan + 0j), "no measured frame"),
        (np.ones((2, 2, 2), dtype=complex), r"\(frames, peaks\)"),
    ],
)
def test_bad_series_are_clear_errors(values, message):
    with pytest.raises(InputError, match=message):
        unwrap_in_time(values)


def test_track_depth_rejects_mismatched_inputs(evaporation):
    alphas = [p.alpha for p in evaporation.peaks]
    with pytest.raises(InputError, match="time stamps"):
        track_depth(evaporation.values, evaporation.times[:-1], alphas, WAVELENGTH)
    with pytest.raises(InputError, match="do not match"):
        track_depth(evaporation.values, evaporation.times, alphas[:-1], WAVELENGTH)
    with pytest.raises(InputError, match="every peak aliases"):
        track_depth(evaporation.values, evaporation.times, alphas, WAVELENGTH, exclude=[True] * 6)


# -- targets on the analytic model (mean phase per peak and frame) ---------------------------


def test_evaporation_target_on_the_analytic_model(evaporation):
    """Isopropanol, 5.72 um/min, 10 fps, 60 s, vibration on the reference arm."""
    alphas = [p.alpha for p in evaporation.peaks]
    track = track_depth(evaporation.values, evaporation.times, alphas, WAVELENGTH)
    assert not np.any(track.aliasing.aliased)
    assert track.fit.relative_error(evaporation.rate) < 0.003
    worst_error = max(f.relative_error(evaporation.rate) for f in track.peak_fits)
    worst_stderr = max(f.stderr for f in track.peak_fits)
    assert worst_stderr > 3 * track.fit.stderr
    assert worst_error > 3 * track.fit.relative_error(evaporation.rate)
    # FB1 does not see the reference arm: it carries the most weight.
    assert int(np.argmax(track.fused.weights)) == 2


def test_injection_target_on_the_analytic_model():
    """Water, 12.3 uL/s into 70.6 cm^2, 25 fps: FB2 and FB1's second order alias."""
    n2 = 1.333
    peaks = [
        *model_peaks(N_AIR, n2),
        ModelPeak("FB2", 2 * n2, 0.0, 0.3, 0.05),
        ModelPeak("2FB1", 2 * n2, 0.0, 0.2, 0.08),
        ModelPeak("2RF", 2 * N_AIR, 2 * N_AIR, 0.2, 0.08),
    ]
    rate = INJECTION_RATE / INJECTION_AREA
    recording = simulate(peaks, rate, fps=25.0, duration=30.0, vibration=3e-9, seed=5)
    alphas = [p.alpha for p in peaks]
    track = track_depth(recording.values, recording.times, alphas, WAVELENGTH)
    assert np.flatnonzero(track.aliasing.aliased).tolist() == [6, 7, 8]
    assert not np.any(track.fused.used[6:])
    comparison = compare_rate(track.fit, INJECTION_AREA, INJECTION_RATE)
    assert abs(comparison.relative_error) < 0.005
    # Without the exclusion the aliased peaks would spoil the fusion.
    naive = fit_rate(recording.times, fuse_depths(track.depths, track.fused.noise).depth)
    assert naive.relative_error(rate) > 0.05
