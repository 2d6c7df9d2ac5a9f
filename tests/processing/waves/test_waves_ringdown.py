"""The damped-mode fit against the simulator's mode, through the azimuthal decomposition."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import special
from waves_synth import sample

from holoview.errors import InputError
from holoview.optics.wave_fields import DampedMode
from holoview.processing.waves.azimuthal import AzimuthalAccumulator, polar_grid
from holoview.processing.waves.ringdown import band_pass_taps, fit_ringdown

SIZE, PIXEL, FPS = 64, 0.6e-3, 100.0
CENTRE = (19.1e-3, 18.7e-3)
RADII = np.arange(1e-3, 17e-3, 0.6e-3)


def ring_series(
    decay: float,
    *,
    onset: float = 0.0,
    noise: float = 2e-9,
    seed: int = 0,
    tone: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``h_2(r, t)`` on ``RADII`` of a 12 Hz mode of 60 nm switched on at ``onset`` (s),
    400 frames, with white noise (``noise`` per pixel of 0.6 mm) and, with ``tone`` (Hz),
    a steady wave of the same shape and amplitude."""
    times = np.arange(400) / FPS
    after = np.clip(times - onset, 0.0, None)
    envelope = np.where(times >= onset, np.exp(-(decay + 2j * np.pi * 12.0) * after), 0.0)
    if tone is not None:
        envelope = envelope + np.exp(-2j * np.pi * tone * times + 0.7j)
    series = 60e-9 * np.outer(envelope, special.jv(2, 480.0 * RADII))
    rng = np.random.default_rng(seed)
    sd = noise / np.sqrt(2 * np.pi * RADII / 0.6e-3)  # a ring's pixels averaged
    series += (rng.normal(size=series.shape) + 1j * rng.normal(size=series.shape)) * sd / 2**0.5
    return times, series


@pytest.fixture(scope="module")
def ringing():
    mode = DampedMode(2, 12.0, 0.8, 60e-9, centre=CENTRE, depth=5e-3)
    times = np.delete(np.arange(400) / FPS, np.s_[150:160])  # ten frames lost
    maps = sample(mode, times, SIZE, PIXEL, noise=2e-9, seed=4)
    g = polar_grid((SIZE, SIZE), PIXEL, CENTRE, r_min=1e-3, r_max=17e-3, m_max=3)
    acc = AzimuthalAccumulator(g, 1 / FPS, segment=64, series=(2, -2))
    acc.push_block(maps, times)
    return mode, g, acc


def test_frequency_and_decay_come_back_within_their_targets(ringing):
    mode, g, acc = ringing
    times, series = acc.series()
    fit = fit_ringdown(times, series[:, :, 0], (9.0, 15.0), m=2, radii=g.radii)
    assert fit.frequency == pytest.approx(mode.frequency, rel=0.005)
    assert fit.decay == pytest.approx(mode.decay, rel=0.05)
    assert abs(fit.frequency - mode.frequency) < 4 * fit.frequency_stderr + 1e-4
    assert abs(fit.decay - mode.decay) < 4 * fit.decay_stderr + 1e-3
    assert fit.quality == pytest.approx(np.pi * mode.frequency / mode.decay, rel=0.06)
    assert fit.as_dict()["frequency_stderr_hz"] > 0


def test_a_band_without_the_mode_is_refused(ringing):
    _, g, acc = ringing
    times, series = acc.series()
    with pytest.raises(InputError, match="no damped mode stands out of the noise"):
        fit_ringdown(times, series[:, :, 1], (9.0, 15.0), m=-2, radii=g.radii)


def test_the_band_pass_has_unit_gain_in_its_band_and_none_outside():
    taps = band_pass_taps((9.0, 15.0), 1 / FPS)
    t = (np.arange(taps.size) - (taps.size - 1) / 2) / FPS

    def gain(f):
        return abs(np.sum(taps * np.exp(2j * np.pi * f * t)))  # on exp(-i 2 pi f t)

    assert gain(12.0) == pytest.approx(1.0)
    assert gain(11.0) == pytest.approx(1.0, abs=0.02)
    assert gain(-12.0) < 1e-3  # the other sign of frequency: the mode of -m
    assert gain(25.0) < 1e-3
    with pytest.raises(InputError, match="Nyquist"):
        band_pass_taps((9.0, 60.0), 1 / FPS)


def test_runs_too_short_for_the_filter_are_refused():
    times = np.arange(12) / FPS  # 9 taps at least: 4 samples, 8 needed
    with pytest.raises(InputError, match="runs of"):
        fit_ringdown(times, np.ones(12, complex), (11.0, 13.0))


def test_the_filter_leaves_most_of_a_short_record_to_fit(ringing):
    _, g, acc = ringing
    times, series = acc.series()
    fit = fit_ringdown(times, series[:, :, 0], (11.0, 13.0), m=2, radii=g.radii, start=0.0)
    # four periods of a 1 Hz half-width would be 401 taps, longer than the 390 frames
    assert fit.times.size > 0.5 * times.size
    longest = 240  # frames 160-399, after the gap
    taps = band_pass_taps((11.0, 13.0), 1 / FPS, max_taps=longest // 4)
    assert taps.size == 59


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("start", [None, 0.6])
def test_a_mode_that_starts_within_the_record_keeps_its_decay_rate(seed, start):
    # the filter's outputs within half its length after the onset mixed in the frames
    # before it: +7.5 % (5 standard errors) from the default start
    times, series = ring_series(3.0, onset=0.5, noise=5e-9, seed=seed)
    fit = fit_ringdown(times, series, (9.0, 15.0), m=2, radii=RADII, start=start)
    assert fit.t0 >= 0.5
    assert fit.decay == pytest.approx(3.0, rel=0.05)
    assert abs(fit.decay - 3.0) < 3 * fit.decay_stderr
    assert abs(fit.frequency - 12.0) < 3 * fit.frequency_stderr


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_decay_faster_than_the_filter_is_measured_from_its_first_frames(seed):
    # Q = 3.8: gone (e^-4.9) before the 99-tap filter's first whole output, and refused
    # as "no damped mode stands out of the noise (1.4 standard errors)"
    times, series = ring_series(10.0, seed=seed)
    fit = fit_ringdown(times, series, (9.0, 15.0), m=2, radii=RADII)
    assert fit.t0 == 0.0
    assert fit.decay == pytest.approx(10.0, rel=0.05)
    assert abs(fit.decay - 10.0) < 3 * fit.decay_stderr
    assert abs(fit.frequency - 12.0) < 3 * fit.frequency_stderr


def test_a_fast_decay_in_strong_noise_is_refused_as_not_out_of_the_noise():
    times, series = ring_series(10.0, noise=200e-9)
    with pytest.raises(InputError, match="no damped mode stands out of the noise"):
        fit_ringdown(times, series, (9.0, 15.0), m=2, radii=RADII)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_wave_outside_the_band_does_not_leak_in_where_the_filter_meets_the_start(seed):
    # the outputs that reach before the start took a steady 6.5 Hz wave as strong as the
    # mode for -8.5 % of the decay rate: they are left out where they disagree
    times, series = ring_series(3.0, noise=5e-9, seed=seed, tone=6.5)
    fit = fit_ringdown(times, series, (9.0, 15.0), m=2, radii=RADII)
    assert fit.decay == pytest.approx(3.0, rel=0.03)
    assert abs(fit.decay - 3.0) < 3 * fit.decay_stderr


def test_a_decay_rate_the_record_does_not_determine_is_refused():
    times, series = ring_series(0.003, noise=20e-9)
    with pytest.raises(InputError, match=r"decay rate is not determined: .* decay times\)"):
        fit_ringdown(times, series, (9.0, 15.0), m=2, radii=RADII)
