"""Space-time spectrum of height maps and the capillary-gravity dispersion relation."""

from __future__ import annotations

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.optics.families import predict_families
from holoview.optics.setup import Setup
from holoview.optics.surfaces import Mode, StandingWaves, dispersion_omega
from holoview.optics.synthesis import HologramSynthesizer, pixel_coordinates
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.peaks.detection import find_peaks
from holoview.processing.waves.dynamics import compare_dispersion, space_time_spectrum

WATER = {"depth": 5e-3, "surface_tension": 0.072, "density": 1000.0}
FRAMES, SIZE, INTERVAL, PIXEL = 128, 64, 0.01, 0.5e-3  # 100 fps, 32 mm field of view


def wave_field(seed: int = 0, noise: float = 1e-9, **fluid: float) -> np.ndarray:
    """A broadband field of free waves on ``fluid`` (every spatial frequency, random phase)."""
    rng = np.random.default_rng(seed)
    ky = 2 * np.pi * np.fft.fftfreq(SIZE)[:, None] / PIXEL
    kx = 2 * np.pi * np.fft.fftfreq(SIZE)[None, :] / PIXEL
    k = np.hypot(ky, kx)
    water = WATER | fluid
    omega = dispersion_omega(
        k, water["depth"], sigma=water["surface_tension"], rho=water["density"]
    )
    amplitude = (rng.normal(size=k.shape) + 1j * rng.normal(size=k.shape)) * (k > 0)
    amplitude *= np.exp(-((k / 3000) ** 2))
    times = np.arange(FRAMES)[:, None, None] * INTERVAL
    field = np.fft.ifft2(amplitude * np.exp(-1j * omega * times), axes=(1, 2)).real * 1e-6
    return field + rng.normal(0, noise, field.shape)


def test_a_plane_wave_lands_on_its_frequency_and_wavenumber():
    times = np.arange(FRAMES)[:, None, None] * INTERVAL
    x = np.arange(SIZE)[None, None, :] * PIXEL
    k = 2 * np.pi * 5 / (SIZE * PIXEL)
    omega = 2 * np.pi * 12 / (FRAMES * INTERVAL)
    field = 1e-8 * np.cos(k * x - omega * times) * np.ones((1, SIZE, 1))
    spectrum = space_time_spectrum(field, INTERVAL, PIXEL)
    assert spectrum.power.shape == (FRAMES // 2 + 1, SIZE // 2 + 1)
    row, column = np.unravel_index(np.argmax(spectrum.power), spectrum.power.shape)
    assert spectrum.omega[row] == pytest.approx(omega)
    assert spectrum.k[column] == pytest.approx(k)
    brightest = np.unravel_index(np.argmax(spectrum.cell_peak), spectrum.cell_peak.shape)
    assert spectrum.cell_k[brightest] == pytest.approx(k)
    assert spectrum.cell_omega[brightest] == pytest.approx(omega, rel=1e-6)


def test_free_waves_follow_the_dispersion_relation():
    spectrum = space_time_spectrum(wave_field(), INTERVAL, PIXEL)
    result = compare_dispersion(spectrum, **WATER)
    assert result.rms_deviation < 0.05
    assert result.power_near_model > 0.9
    assert result.k.size >= 3
    assert np.all(np.abs(result.relative_deviation) < 0.1)


def test_a_wrong_surface_tension_shows():
    spectrum = space_time_spectrum(wave_field(), INTERVAL, PIXEL)
    right = compare_dispersion(spectrum, **WATER)
    wrong = compare_dispersion(spectrum, **(WATER | {"surface_tension": 0.036}))
    assert wrong.rms_deviation > 3 * right.rms_deviation
    assert wrong.power_near_model < 0.5


def test_noise_alone_has_no_waves_to_compare():
    rng = np.random.default_rng(5)
    spectrum = space_time_spectrum(rng.normal(0, 1e-9, (64, 32, 32)), INTERVAL, PIXEL)
    with pytest.raises(InputError, match="no wave to compare"):
        compare_dispersion(spectrum, **WATER)


@pytest.mark.parametrize(
    ("shape", "interval", "message"),
    [
        ((3, 16, 16), INTERVAL, "at least 4 frames"),
        ((8, 3, 16), INTERVAL, "too small"),
        ((8, 16), INTERVAL, "stack"),
        ((8, 16, 16), 0.0, "must be positive"),
    ],
)
def test_bad_input_is_a_clear_error(shape, interval, message):
    with pytest.raises(InputError, match=message):
        space_time_spectrum(np.zeros(shape), interval, PIXEL)


def test_nan_maps_are_refused_and_input_is_not_mutated():
    field = wave_field(noise=0.0)[:16]
    before = field.copy()
    space_time_spectrum(field, INTERVAL, PIXEL)
    np.testing.assert_array_equal(field, before)
    field[0, 0, 0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        space_time_spectrum(field, INTERVAL, PIXEL)


def test_standing_waves_through_the_synthesiser_and_demodulator():
    """Delta-h maps of RB1 from synthesised frames of standing waves follow the dispersion."""
    setup = Setup(shape=(128, 128), pixel_pitch=200e-6, m_r=(2e-4, 1.2e-4), m_b=(-0.5e-4, 1.5e-4))
    side = 128 * setup.pixel_pitch  # the basin fills the frame; even modes fit the FFT grid
    indices = [(2, 4), (4, 2), (6, 2), (2, 6), (4, 6), (8, 0)]
    modes = tuple(Mode(m, n, 20e-9, 0.9 * i) for i, (m, n) in enumerate(indices))
    waves = StandingWaves(modes, side, depth=5e-3)
    synthesiser = HologramSynthesizer(setup)
    rng = np.random.default_rng(3)
    x, y = pixel_coordinates(setup)
    fps = 200.0
    first = synthesiser.render(waves(0.0, x, y), rng=rng)
    brightest = find_peaks(first)[0]
    rb1 = next(f for f in predict_families(setup) if f.label == "RB1")
    if np.dot(brightest.carrier, rb1.observed_carrier) < 0:
        brightest = brightest.flipped()
    peak = brightest.relabelled("RB1", rb1.alpha)
    demodulator = Demodulator(
        setup.shape,
        [peak],
        reference="absolute",
        unwrap="never",
        wavelength=setup.wavelength,
        threads=1,
    )
    maps = []
    for i in range(128):
        frame = first if i == 0 else synthesiser.render(waves(i / fps, x, y), rng=rng)
        maps.append(demodulator.process(frame).peaks[0].delta_h)
    box_pixel = side / demodulator.box_shape[1]
    spectrum = space_time_spectrum(np.array(maps), 1 / fps, box_pixel)
    right = compare_dispersion(spectrum, 5e-3, waves.sigma, waves.rho)
    assert right.rms_deviation < 0.06
    assert right.power_near_model > 0.9
    wrong = compare_dispersion(spectrum, 5e-3, waves.sigma / 2, waves.rho)
    assert wrong.rms_deviation > 3 * right.rms_deviation
