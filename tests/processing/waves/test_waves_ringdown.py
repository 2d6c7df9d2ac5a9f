"""The damped-mode fit against the simulator's mode, through the azimuthal decomposition."""

from __future__ import annotations

import numpy as np
import pytest
from waves_synth import sample

from holoview.errors import InputError
from holoview.optics.wave_fields import DampedMode
from holoview.processing.waves.azimuthal import AzimuthalAccumulator, polar_grid
from holoview.processing.waves.ringdown import band_pass_taps, fit_ringdown

SIZE, PIXEL, FPS = 64, 0.6e-3, 100.0
CENTRE = (19.1e-3, 18.7e-3)


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
