"""Wave fields with a known truth: travelling waves on a flow, partial waves, a damped mode."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import special

from holoview.errors import InputError
from holoview.optics.scenarios import ScenarioConfig, make_surface
from holoview.optics.setup import Setup
from holoview.optics.surfaces import dispersion_k, dispersion_omega
from holoview.optics.wave_fields import (
    DampedMode,
    PartialWave,
    PartialWaves,
    SwitchedOn,
    TravellingWaves,
    WaveConfig,
    random_travelling_waves,
)

X = np.linspace(-0.02, 0.02, 81)[np.newaxis, :]
Y = np.linspace(-0.015, 0.015, 61)[:, np.newaxis]


def test_dispersion_k_inverts_dispersion_omega() -> None:
    for k in (50.0, 700.0, 3000.0):
        omega = dispersion_omega(k, 3e-3, sigma=0.06, rho=1000.0)
        assert dispersion_k(omega, 3e-3, sigma=0.06, rho=1000.0) == pytest.approx(k, rel=1e-10)
    with pytest.raises(InputError, match="omega"):
        dispersion_k(0.0, 3e-3)


def test_a_travelling_wave_moves_at_its_phase_speed_shifted_by_the_flow() -> None:
    k, flow = 600.0, (0.03, 0.0)
    wave = TravellingWaves(np.array([[k, 0.0]]), np.array([1e-8]), np.array([0.3]), 3e-3, flow)
    omega0 = dispersion_omega(k, 3e-3)
    assert wave.omegas[0] == pytest.approx(omega0 + k * 0.03)
    dt = 1e-3
    shift = wave.omegas[0] / k * dt  # the crest moves by c dt, c = omega / k
    later = wave(dt, X, Y)
    np.testing.assert_allclose(later, wave(0.0, X - shift, Y), atol=1e-14)  # complex64 sums
    truth_attrs, truth_data = wave.truth()
    assert truth_attrs["flow_m_per_s"] == [0.03, 0.0]
    np.testing.assert_allclose(truth_data["omega_rad_per_s"][0], wave.omegas)


def test_the_fast_grid_path_equals_the_plain_sum() -> None:
    waves = random_travelling_waves(
        np.random.default_rng(1),
        k_range=(300, 1500),
        components=40,
        rms=3e-8,
        depth=3e-3,
        flow=(0.01, -0.02),
    )
    fast = waves(0.37, X, Y)
    plain = np.zeros(np.broadcast_shapes(X.shape, Y.shape))
    for (kx, ky), a, p, w in zip(
        waves.wavevectors, waves.amplitudes, waves.phases, waves.omegas, strict=True
    ):
        plain += a * np.cos(kx * X + ky * Y - w * 0.37 + p)
    np.testing.assert_allclose(fast, plain, atol=1e-5 * 3e-8)
    scattered = waves(0.37, X + 0 * Y, Y + 0 * X)  # full arrays: the general path
    np.testing.assert_allclose(scattered, plain, atol=1e-15)
    assert np.sqrt(0.5 * np.sum(waves.amplitudes**2)) == pytest.approx(3e-8)


def test_a_flow_faster_than_the_waves_is_refused() -> None:
    with pytest.raises(InputError, match="sweeps some waves backwards"):
        TravellingWaves(
            np.array([[-300.0, 0.0]]), np.array([1e-9]), np.array([0.0]), 3e-3, (1.0, 0.0)
        )


def test_partial_waves_are_the_hankel_sum_outside_the_core() -> None:
    centre = (2e-3, -1e-3)
    waves = (PartialWave(2, 20.0, 1e-8 + 2e-9j, 3e-9), PartialWave(-1, 13.0, 0.0, 5e-9j))
    field = PartialWaves(waves, centre=centre, core_radius=3e-3, depth=4e-3)
    t = 0.031
    r = np.hypot(X - centre[0], Y - centre[1])
    theta = np.arctan2(Y - centre[1], X - centre[0])
    expected = np.zeros(r.shape)
    for wave, k in zip(waves, field.wavenumbers, strict=True):
        assert k == pytest.approx(dispersion_k(2 * math.pi * wave.frequency, 4e-3))
        radial = wave.outgoing * special.hankel1(wave.m, k * r) + wave.incoming * special.hankel2(
            wave.m, k * r
        )
        expected += (radial * np.exp(1j * (wave.m * theta - 2 * math.pi * wave.frequency * t))).real
    outside = r >= 4.5e-3
    np.testing.assert_allclose(field(t, X, Y)[outside], expected[outside], atol=1e-20)
    assert np.all(field(t, X, Y)[r < 3e-3] == 0.0)
    _, data = field.truth()
    np.testing.assert_array_equal(data["m"][0], [2, -1])


def test_an_outgoing_wave_moves_out_and_an_incoming_one_in() -> None:
    k = dispersion_k(2 * math.pi * 20.0, 4e-3)
    r = np.linspace(0.01, 0.02, 400)[np.newaxis, :]
    for incoming, outgoing, sign in ((0.0, 1e-8, 1), (1e-8, 0.0, -1)):
        field = PartialWaves(
            (PartialWave(0, 20.0, incoming, outgoing),), core_radius=0.0, depth=4e-3
        )
        crest = [r[0, np.argmax(field(t, r, 0 * r)[0, :150])] for t in (0.0, 0.002)]
        assert np.sign(crest[1] - crest[0]) == sign
        assert abs(crest[1] - crest[0]) == pytest.approx(2 * math.pi * 20.0 / k * 0.002, rel=0.1)


def test_a_damped_mode_decays_at_its_rate_and_turns_at_its_frequency() -> None:
    mode = DampedMode(1, 12.0, 0.8, 5e-8, centre=(0.0, 0.0), depth=5e-3)
    period = 1 / 12.0
    now, later = mode(0.2, X, Y), mode(0.2 + 3 * period, X, Y)
    np.testing.assert_allclose(later, now * math.exp(-0.8 * 3 * period), atol=1e-20)
    r = np.hypot(X, Y)
    expected = 5e-8 * special.jv(1, mode.wavenumber * r) * np.cos(np.arctan2(Y, X))
    np.testing.assert_allclose(mode(0.0, X, Y), expected, atol=1e-20)
    assert mode.truth()[0]["decay_per_s"] == 0.8


def test_switched_on_waves_rest_until_they_start() -> None:
    mode = DampedMode(0, 10.0, 1.0, 1e-8, depth=5e-3)
    late = SwitchedOn(mode, start=0.1)
    assert np.all(late(0.05, X, Y) == 0.0)
    np.testing.assert_allclose(late(0.1, X, Y), mode(0.0, X, Y))  # excited at the start
    waves = random_travelling_waves(
        np.random.default_rng(0), k_range=(300, 900), components=5, rms=1e-8, depth=3e-3
    )
    rising = SwitchedOn(waves, start=0.01, rise=0.1)
    np.testing.assert_allclose(rising(0.06, X, Y), 0.5 * waves(0.06, X, Y), atol=1e-22)
    np.testing.assert_allclose(rising(0.2, X, Y), waves(0.2, X, Y))
    assert rising.truth()[0]["rise_s"] == 0.1
    with pytest.raises(InputError, match="start"):
        SwitchedOn(waves, start=-1.0)


@pytest.mark.parametrize("scenario", ["travelling", "partial-waves", "ringdown"])
def test_the_wave_scenarios_are_made_from_the_config(scenario: str) -> None:
    setup = Setup(shape=(64, 64), depth=4e-3)
    config = WaveConfig(start=0.05)
    surface = make_surface(
        setup, scenario, ScenarioConfig(sigma=0.06), np.random.default_rng(2), config
    )
    assert isinstance(surface, SwitchedOn)
    attrs, _ = surface.truth()
    assert attrs["depth_m"] == 4e-3 and attrs["sigma_n_per_m"] == 0.06 and attrs["start_s"] == 0.05
