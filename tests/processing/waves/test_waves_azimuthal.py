"""Azimuthal decomposition, the (m, f) spectrum, the centre, and the Hankel fit of partial waves."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import special
from waves_synth import grid, sample

from holoview.errors import InputError
from holoview.optics.surfaces import dispersion_k
from holoview.optics.wave_fields import PartialWave, PartialWaves
from holoview.processing.waves.azimuthal import AzimuthalAccumulator, polar_grid
from holoview.processing.waves.centre import find_centre
from holoview.processing.waves.lockin import LockIn
from holoview.processing.waves.partial_waves import fit_partial_wave, refine_tone

SIZE, PIXEL, FPS, FRAMES = 96, 0.5e-3, 100.0, 256
CENTRE_MAP = (24.3e-3, 22.8e-3)  # map coordinates, m (off the pixel grid)
WAVES = (
    PartialWave(0, 14.3, 20e-9, 12e-9),
    PartialWave(2, 22.1, 8e-9 + 6e-9j, 15e-9),
    PartialWave(-1, 30.7, 10e-9, 5e-9j),
)


@pytest.fixture(scope="module")
def field():
    surface = PartialWaves(WAVES, centre=CENTRE_MAP, core_radius=3e-3, depth=5e-3)
    times = np.arange(FRAMES) / FPS
    maps = sample(surface, times, SIZE, PIXEL, noise=0.3e-9)
    x, y = grid(SIZE, PIXEL)
    maps[:, np.hypot(x - CENTRE_MAP[0], y - CENTRE_MAP[1]) < 4.5e-3] = np.nan  # the core
    return surface, times, maps


def test_the_modes_of_a_known_pattern_match_a_plain_sum():
    x, y = grid(SIZE, PIXEL)
    r = np.hypot(x - CENTRE_MAP[0], y - CENTRE_MAP[1])
    theta = np.arctan2(y - CENTRE_MAP[1], x - CENTRE_MAP[0])
    pattern = np.cos(200 * r) * (1 + 0.5 * np.cos(3 * theta - 0.4)) + 0.2 * np.sin(theta)
    g = polar_grid((SIZE, SIZE), PIXEL, CENTRE_MAP, r_min=2e-3, r_max=20e-3, m_max=4)
    modes = g.modes(pattern)
    ring = np.cos(200 * g.radii)
    # plain reference: cos(3 theta - 0.4)/2 -> m = +-3; sin(theta) -> m = +-1
    np.testing.assert_allclose(modes[:, 4], ring, atol=0.005)
    np.testing.assert_allclose(modes[:, 4 + 3], 0.25 * ring * np.exp(-0.4j), atol=0.01)
    np.testing.assert_allclose(modes[:, 4 - 3], 0.25 * ring * np.exp(0.4j), atol=0.01)
    np.testing.assert_allclose(modes[:, 4 + 1], -0.1j * np.ones(g.radii.size), atol=0.01)
    np.testing.assert_allclose(modes[:, 4 + 2], 0.0, atol=0.01)


def test_the_modes_sampled_in_threads_are_those_sampled_in_one(field):
    _, _, maps = field
    g = polar_grid((SIZE, SIZE), PIXEL, CENTRE_MAP, r_min=5e-3, r_max=18e-3, m_max=6)
    alone = g.modes(maps[:70])  # five chunks, the last one short
    assert alone.shape == (70, g.radii.size, 13)
    np.testing.assert_array_equal(g.modes(maps[:70], workers=3), alone)


def test_the_centre_is_found_from_the_field(field):
    _, times, maps = field
    lockin = LockIn((SIZE, SIZE), 14.3, (1,), span=(0.0, times[-1]))
    lockin.push_block(maps, times)
    centre = find_centre(lockin.result().amplitude[0], PIXEL, radius=18e-3, r_min=5e-3)
    assert np.hypot(centre[0] - CENTRE_MAP[0], centre[1] - CENTRE_MAP[1]) < 0.1 * PIXEL


def test_a_centre_beyond_where_the_rings_fit_is_refused_not_held_at_its_edge(field):
    # rings to 22.3 mm fit around centres from 23.3 to 24.2 mm along each axis: the waves'
    # centre (24.3, 22.8) mm lies a pixel beyond along y. Held at the edge, a centre a
    # pixel off took 2 to 3 % of the partial waves' amplitudes (J_0(k delta),
    # benchmarks/accuracy_waves.py on 180-pixel maps with rings to 38 mm).
    _, times, maps = field
    lockin = LockIn((SIZE, SIZE), 14.3, (1,), span=(0.0, times[-1]))
    lockin.push_block(maps, times)
    amplitude = lockin.result().amplitude[0]
    # the room around the true centre: 22.8 mm to the nearest edge less two pixels
    with pytest.raises(InputError, match=r"near \(24\.3\d*, 22\.8\d*\) mm.*up to 21\.[78] mm"):
        find_centre(amplitude, PIXEL, radius=22.3e-3, r_min=5e-3)
    centre = find_centre(amplitude, PIXEL, radius=21.5e-3, r_min=5e-3)
    assert np.hypot(centre[0] - CENTRE_MAP[0], centre[1] - CENTRE_MAP[1]) < 0.1 * PIXEL


def test_the_mf_spectrum_peaks_at_the_true_modes_and_amplitudes_come_back(field):
    surface, times, maps = field
    g = polar_grid((SIZE, SIZE), PIXEL, CENTRE_MAP, r_min=5e-3, r_max=21e-3, m_max=4)
    duration = times[-1]
    combs = [w.frequency + (np.arange(9) - 4) * 0.25 / duration for w in WAVES]
    acc = AzimuthalAccumulator(
        g, 1 / FPS, segment=128, lock_in=np.concatenate(combs), span=(0.0, duration)
    )
    for start in range(0, FRAMES, 64):
        acc.push_block(maps[start : start + 64], times[start : start + 64])
    mf = acc.spectrum()
    strongest = mf.strongest(3)
    assert {m for m, _ in strongest} == {w.m for w in WAVES}
    for m, f in strongest:
        truth = next(w for w in WAVES if w.m == m)
        assert f == pytest.approx(truth.frequency, abs=mf.frequency[1] / 4)
    profiles = acc.profiles()
    weights = np.sin(np.pi * times / duration) ** 2
    for i, wave in enumerate(WAVES):
        comb = combs[i]
        block = profiles[i * 9 : (i + 1) * 9, :, wave.m + 4]
        tone = refine_tone(comb, block, times, weights)
        assert tone.frequency == pytest.approx(wave.frequency, abs=1e-3)
        assert 0 < tone.frequency_stderr < 1e-3
        k = dispersion_k(
            2 * math.pi * tone.frequency, surface.depth, sigma=surface.sigma, rho=surface.rho
        )
        fit = fit_partial_wave(
            g.radii, tone.profile, wave.m, tone.frequency, k, k_cut=math.pi / PIXEL
        )
        assert abs(fit.incoming) == pytest.approx(abs(wave.incoming), rel=0.03)
        assert abs(fit.outgoing) == pytest.approx(abs(wave.outgoing), rel=0.03)
        truth_ratio = abs(wave.incoming) / abs(wave.outgoing)
        assert fit.ratio == pytest.approx(truth_ratio, rel=0.03)
        assert fit.wavenumber == pytest.approx(k, rel=0.01)
        assert 0 < fit.ratio_stderr < 0.1 * fit.ratio


def test_the_mf_spectrum_sums_to_the_mean_square_over_the_annulus():
    rng = np.random.default_rng(3)
    maps = rng.normal(0, 2e-9, (256, SIZE, SIZE))
    g = polar_grid((SIZE, SIZE), PIXEL, CENTRE_MAP, r_min=3e-3, r_max=20e-3, m_max=200)
    acc = AzimuthalAccumulator(g, 1 / FPS, segment=64)
    acc.push_block(maps, np.arange(256) / FPS)
    mf = acc.spectrum()
    total = mf.power.sum() * mf.frequency[1]
    # interpolated samples of white noise have a smaller variance than the pixels
    samples = g.matrix @ maps[0].ravel()
    assert total == pytest.approx(np.mean(samples**2), rel=0.1)


def test_the_profiles_noise_is_the_scatter_of_their_lock_ins_over_seeds():
    """profile_noise, from each ring's (m, f) power beside a frequency, is the variance
    of each part of that ring's lock-in over 24 seeds of noise maps (the steady-tone
    check's yardstick: a factor wrong there refuses good tones or passes bad ones)."""
    g = polar_grid((SIZE, SIZE), PIXEL, CENTRE_MAP, r_min=5e-3, r_max=20e-3, m_max=3)
    times = np.arange(FRAMES) / FPS
    span = (float(times[0]), float(times[-1]))
    values, noise = [], []
    for seed in range(24):
        maps = np.random.default_rng(seed).normal(0, 2e-9, (FRAMES, SIZE, SIZE))
        acc = AzimuthalAccumulator(g, 1 / FPS, segment=64, lock_in=[21.3], span=span)
        acc.push_block(maps, times)
        values.append(acc.profiles()[0, :, 2 + g.m_max])  # m = 2
        noise.append(acc.profile_noise(2, 21.3))
    scatter = np.var(np.concatenate([np.real(values), np.imag(values)]), axis=0)  # (R,)
    ratio = np.mean(noise, axis=0) / scatter
    assert np.median(ratio) == pytest.approx(1.0, abs=0.15), np.median(ratio)


def test_a_hankel_fit_of_a_plain_profile():
    r = np.linspace(5e-3, 30e-3, 60)
    k = 700.0
    rng = np.random.default_rng(0)
    profile = (3 - 1j) * special.hankel1(2, k * r) + (1 + 2j) * special.hankel2(2, k * r)
    profile += rng.normal(0, 0.01, r.size) + 1j * rng.normal(0, 0.01, r.size)
    fit = fit_partial_wave(r, profile, 2, 20.0, 0.95 * k)
    assert fit.outgoing == pytest.approx(3 - 1j, abs=0.05)
    assert fit.incoming == pytest.approx(1 + 2j, abs=0.05)
    assert fit.wavenumber == pytest.approx(k, rel=1e-3)
    fixed = fit_partial_wave(r, profile, 2, 20.0, k, fit_wavenumber=False)
    assert fixed.wavenumber_stderr == 0.0
    with pytest.raises(InputError, match="rings with data"):
        fit_partial_wave(r[:4], profile[:4], 2, 20.0, k)


def test_rings_outside_the_maps_and_centres_outside_are_refused():
    with pytest.raises(InputError, match="outside the maps"):
        polar_grid((SIZE, SIZE), PIXEL, (-1e-3, 10e-3))
    with pytest.raises(InputError, match="leave the maps"):
        polar_grid((SIZE, SIZE), PIXEL, (10e-3, 10e-3), r_max=20e-3)
    with pytest.raises(InputError, match="no room"):
        polar_grid((SIZE, SIZE), PIXEL, (1e-3, 1e-3))
    g = polar_grid((SIZE, SIZE), PIXEL, (10e-3, 10e-3), m_max=2)
    assert g.radii[-1] <= 10e-3 - PIXEL + 1e-12
    with pytest.raises(InputError, match="beyond"):
        AzimuthalAccumulator(g, 0.01, series=(3,))


def test_a_tone_at_the_nyquist_frequency_is_refused_not_divided_by_zero():
    """A comb clipped at the Nyquist frequency holds fewer than three frequencies: one line."""
    times = np.arange(64) / 100.0
    comb = np.array([49.8, 49.9, 50.0, 50.0, 50.0])
    lock_ins = np.ones((comb.size, 3), dtype=np.complex128)
    with pytest.raises(InputError, match="three frequencies or more"):
        refine_tone(comb[1:], lock_ins[1:], times, np.ones(times.size))
    assert 49.8 <= refine_tone(comb, lock_ins, times, np.ones(times.size)).frequency <= 50.0
