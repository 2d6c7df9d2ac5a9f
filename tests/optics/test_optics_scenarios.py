"""Surfaces with a known truth and the simulated sequences built on them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.optics.families import predict_families
from holoview.optics.scenarios import ScenarioConfig, simulate, vibration
from holoview.optics.surfaces import (
    Mode,
    StandingWaves,
    SurfaceSum,
    UserSurface,
    dispersion_omega,
    evaporation,
    injection,
)

from .benches import integer_bin_setup
from .spectra import bin_of

SMALL = {"shape": (128, 128), "rf_bins": (15, 8), "fb1_bins": (-5, 12)}


def test_dispersion_has_the_gravity_and_capillary_limits() -> None:
    k = np.array([1.0, 10.0])
    deep_gravity = dispersion_omega(k, depth=100.0, sigma=0.0)
    np.testing.assert_allclose(deep_gravity, np.sqrt(9.81 * k), rtol=1e-9)
    k_short = 1e5
    capillary = dispersion_omega(k_short, depth=1.0, sigma=0.0728, rho=998.2)
    assert capillary == pytest.approx(math.sqrt(0.0728 * k_short**3 / 998.2), rel=1e-3)
    shallow = dispersion_omega(0.1, depth=1e-3, sigma=0.0)
    assert shallow == pytest.approx(0.1 * math.sqrt(9.81 * 1e-3), rel=1e-3)
    with pytest.raises(InputError, match="depth"):
        dispersion_omega(1.0, depth=-1.0)
    with pytest.raises(InputError, match="wavenumber"):
        dispersion_omega(np.array([1.0, math.nan]), depth=1.0)


def test_standing_waves_oscillate_at_the_dispersion_frequency() -> None:
    side, depth = 0.05, 5e-3
    waves = StandingWaves((Mode(3, 2, 1e-7, 0.0),), basin_side=side, depth=depth)
    omega = dispersion_omega(math.pi * math.hypot(3, 2) / side, depth)
    x = np.linspace(-side / 2, side / 2, 201)[None, :]
    y = np.linspace(-side / 2, side / 2, 201)[:, None]
    now = waves(0.0, x, y)
    assert np.abs(now).max() == pytest.approx(1e-7, rel=1e-6)
    quarter = waves(math.pi / (2 * omega), x, y)
    assert np.abs(quarter).max() < 1e-13  # a node in time
    period = waves(2 * math.pi / omega, x, y)
    np.testing.assert_allclose(period, now, atol=1e-15)
    steps = np.abs(np.diff(now, axis=1))
    assert steps[:, 0].max() < 0.05 * steps.max()  # free-slip walls: flat across them
    with pytest.raises(InputError, match="mode"):
        StandingWaves((Mode(0, 0, 1e-7),), basin_side=side, depth=depth)


def test_level_changes_follow_their_rates() -> None:
    rate = 1e-8
    falling = evaporation(rate, level0=2e-6)
    assert falling.mean_level(10.0) == pytest.approx(2e-6 - 1e-7)
    assert falling(10.0, np.zeros((2, 3)), np.zeros((2, 3))).shape == (2, 3)
    rising = injection(12.3e-9, 70.6e-4)
    assert rising.mean_level(1.0) == pytest.approx(12.3e-9 / 70.6e-4)
    both = SurfaceSum((falling, rising))
    assert both.is_uniform
    assert both.mean_level(1.0) == pytest.approx(falling.mean_level(1.0) + rising.mean_level(1.0))
    with pytest.raises(InputError, match="area"):
        injection(1e-9, 0.0)
    with pytest.raises(InputError, match="evaporation"):
        evaporation(-1.0)


def test_user_surfaces_are_checked() -> None:
    good = UserSurface(lambda t, x, y: t * x + y)
    assert good(2.0, np.ones((1, 4)), np.zeros((3, 1))).shape == (3, 4)
    bad = UserSurface(lambda t, x, y: np.full(np.shape(x), math.nan), name="broken")
    with pytest.raises(InputError, match="broken"):
        bad(0.0, np.zeros(3), np.zeros(3))


def test_same_seed_same_sequence() -> None:
    setup = integer_bin_setup(**SMALL)
    runs = [list(simulate(setup, "waves", frames=3, fps=30.0, seed=5)) for _ in range(2)]
    for (a, ta), (b, tb) in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(ta.height, tb.height)
        assert ta.reference_phase == tb.reference_phase
    other = next(simulate(setup, "waves", frames=1, fps=30.0, seed=6))
    assert not np.array_equal(other[0], runs[0][0][0])
    frame, truth = runs[0][1]
    assert frame.dtype == np.uint16 and frame.shape == setup.shape
    assert truth.height.shape == setup.shape
    assert truth.mean_height == pytest.approx(truth.height.mean())
    assert truth.time == pytest.approx(1 / 30)


def _peak_phases(frames: list[np.ndarray], setup, labels: list[str]) -> dict[str, np.ndarray]:
    families = {f.label: f for f in predict_families(setup)}
    spectra = np.fft.fft2(np.array(frames, dtype=float), axes=(1, 2))
    return {
        label: np.unwrap(
            np.angle(spectra[(slice(None), *bin_of(families[label].carrier, setup.shape))])
        )
        for label in labels
    }


def test_injection_rate_is_recovered_from_rb1_and_fb1() -> None:
    setup = integer_bin_setup(**SMALL)
    config = ScenarioConfig(vibration_rms=1e-9)
    pairs = list(simulate(setup, "injection", frames=120, fps=100.0, seed=2, config=config))
    truth = np.array([t.mean_height for _, t in pairs])
    times = np.array([t.time for _, t in pairs])
    rate = config.injection_rate / config.basin_area
    np.testing.assert_allclose(truth, rate * times, rtol=1e-12, atol=1e-18)
    phases = _peak_phases([f for f, _ in pairs], setup, ["RB1", "FB1"])
    families = {f.label: f for f in predict_families(setup)}
    for label, phase in phases.items():
        slope = np.polyfit(times, phase, 1)[0]
        measured = slope * setup.wavelength / (4 * math.pi * families[label].alpha)
        assert measured == pytest.approx(rate, rel=0.01), label


def test_vibration_moves_rf_and_rb1_but_not_fb1() -> None:
    setup = integer_bin_setup(**SMALL)
    config = ScenarioConfig(evaporation_rate=0.0, vibration_rms=20e-9, vibration_time=0.02)
    pairs = list(simulate(setup, "evaporation", frames=60, fps=50.0, seed=4, config=config))
    jitter = np.array([t.reference_phase for _, t in pairs])
    assert np.std(jitter) > 0.3
    phases = _peak_phases([f for f, _ in pairs], setup, ["RF", "RB1", "FB1"])
    np.testing.assert_allclose(phases["RF"] - phases["RF"][0], jitter - jitter[0], atol=0.03)
    np.testing.assert_allclose(phases["RB1"] - phases["RB1"][0], -(jitter - jitter[0]), atol=0.03)
    assert np.std(phases["FB1"]) < 0.05


def test_vibration_is_stationary_with_the_asked_rms() -> None:
    path = vibration(20000, 100.0, 3e-9, 0.05, np.random.default_rng(1))
    assert np.std(path) == pytest.approx(3e-9, rel=0.1)
    lag = np.corrcoef(path[:-5], path[5:])[0, 1]
    assert lag == pytest.approx(math.exp(-5 / (100 * 0.05)), abs=0.05)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"frames": 0}, "frames"),
        ({"fps": -1.0}, "fps"),
        ({"scenario": "tsunami"}, "scenario"),
    ],
)
def test_bad_sequences_are_input_errors(kwargs: dict, message: str) -> None:
    args = {"scenario": "waves", "frames": 2, "fps": 10.0} | kwargs
    scenario = args.pop("scenario")
    with pytest.raises(InputError, match=message):
        next(simulate(integer_bin_setup(**SMALL), scenario, **args))
    with pytest.raises(InputError, match="wave_rms"):
        ScenarioConfig(wave_rms=math.nan)
