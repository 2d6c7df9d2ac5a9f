"""The fast synthesiser against the analytic model: carriers, prefactors, amplitudes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.optics.families import coherent_amplitude, predict_families
from holoview.optics.setup import Ghost, Setup
from holoview.optics.synthesis import HologramSynthesizer, pixel_coordinates

from .benches import integer_bin_setup, random_setup
from .spectra import bin_of, demodulate, peak_near, spectrum

#: Integer-bin bench, 256 x 256: RF at (30, 17) bins, FB1 at (-9, 25).
BINS = {"shape": (256, 256), "rf_bins": (30, 17), "fb1_bins": (-9, 25)}


def _isolated(setup: Setup, families: list, floor: float) -> list:
    """Families whose peak is above ``floor`` and that no other family nearly overlaps.

    A peak's size is the coherent sum of every pair on its carrier: near the etalon's
    cancellation (FB1, and the probe ghost's copies of it) it is far below each pair's.
    """
    rows, cols = setup.shape
    chosen = []
    for family in families:
        if family.amplitude < floor or coherent_amplitude(setup, family.label) < floor:
            continue
        f = np.array(family.observed_carrier) * (cols, rows)
        if np.abs(f).max() < 4:
            continue
        clash = False
        for other in families:
            if other.amplitude < floor / 10:
                continue
            g = np.array(other.observed_carrier) * (cols, rows)
            for h in (g, -g):
                distance = np.abs(((f - h) + np.array([cols, rows]) / 2) % (cols, rows))
                distance = np.abs(distance - np.array([cols, rows]) / 2).max()
                if 0.01 < distance < 6:
                    clash = True
        if not clash:
            chosen.append(family)
    return chosen


def _check_carriers(setup: Setup, rng: np.random.Generator, required: set[str]) -> list[str]:
    """Assert every isolated family above noise peaks within 0.5 bin of its carrier."""
    frame = HologramSynthesizer(setup).render(0.0, rng=rng)
    rows, cols = setup.shape
    hann = np.outer(np.hanning(rows), np.hanning(cols))
    spec = spectrum(frame * hann)
    noise = 1 / math.sqrt(setup.photons_per_pixel * frame.size)
    families = predict_families(setup, max_order=3, second_order=False)
    checked = _isolated(setup, families, floor=40 * noise)
    labels = [f.label for f in checked]
    assert required <= set(labels)
    for family in checked:
        fx, fy, _ = peak_near(spec, family.observed_carrier)
        error = np.array([fx - family.observed_carrier[0], fy - family.observed_carrier[1]])
        error = (error + 0.5) % 1.0 - 0.5
        assert np.abs(error * (cols, rows)).max() <= 0.5, family.label
    return labels


@pytest.mark.parametrize("seed", range(6))
def test_carriers_match_fft_peaks_for_random_tilts(seed: int) -> None:
    rng = np.random.default_rng(seed)
    setup = random_setup(rng, shape=(256, 256))
    _check_carriers(setup, rng, {"RF", "RB1", "RB2"})


def test_ghost_carriers_match_fft_peaks() -> None:
    ghosts = (Ghost("reference", (1.2e-3, -0.9e-3), 0.05), Ghost("probe", (-1.0e-3, -1.3e-3), 0.04))
    setup = integer_bin_setup(**BINS, ghosts=ghosts).replace(
        m_r=(1.9e-3, 1.4e-3), m_b=(-0.6e-3, 1.3e-3)
    )  # off the FFT bins
    labels = _check_carriers(setup, np.random.default_rng(8), {"RF", "RB1"})
    assert {"R~g0F", "R~g0B1", "RB1~g1", "RF~g1"} <= set(labels)


def test_second_order_peaks_appear_at_twice_the_carrier() -> None:
    rng = np.random.default_rng(7)
    setup = integer_bin_setup(**BINS, gamma=0.6)
    frame = HologramSynthesizer(setup).render(0.0, rng=rng)
    spec = spectrum(frame)
    families = {f.label: f for f in predict_families(setup)}
    second = families["2RB1"]
    assert second.kind == "second-order"
    _, _, magnitude = peak_near(spec, second.observed_carrier, search=0)
    assert magnitude > 5 / math.sqrt(setup.photons_per_pixel * frame.size)
    # the single-family response predicts its size to within the cross terms it leaves
    # out (RB2 against RF also lands on 2RB1)
    assert 2 * magnitude == pytest.approx(second.amplitude, rel=0.1)
    first = families["RB1"]
    _, _, magnitude = peak_near(spec, first.observed_carrier, search=0)
    assert 2 * magnitude == pytest.approx(first.amplitude, rel=0.1)


@pytest.mark.parametrize("label", ["RF", "RB1", "FB1", "RB2", "FB2", "RB3"])
def test_prefactor_matches_the_phase_response_to_a_height_step(label: str) -> None:
    setup = integer_bin_setup(**BINS)
    synthesizer = HologramSynthesizer(setup, noise="none")
    family = {f.label: f for f in predict_families(setup, max_order=3)}[label]
    step = setup.wavelength / (4 * math.pi * family.alpha)  # one radian, if alpha is right
    row, col = bin_of(family.carrier, setup.shape)
    before = spectrum(synthesizer.intensity(0.0))[row, col]
    after = spectrum(synthesizer.intensity(step))[row, col]
    response = np.angle(after * np.conj(before))
    assert response == pytest.approx(1.0, rel=1e-3)  # also: the stored twin grows with h
    # the map path (a flat map) agrees, to the phase table's 1e-4 rad steps
    flat = np.full(setup.shape, step)
    mapped = spectrum(synthesizer.intensity(flat))[row, col]
    assert np.angle(mapped * np.conj(before)) == pytest.approx(1.0, rel=1e-3)


def test_reference_jitter_moves_rf_and_rb_but_not_fb() -> None:
    setup = integer_bin_setup(**BINS)
    synthesizer = HologramSynthesizer(setup, noise="none")
    still = spectrum(synthesizer.intensity(0.0))
    shaken = spectrum(synthesizer.intensity(0.0, reference_phase=0.4))
    families = {f.label: f for f in predict_families(setup)}
    expected = {"RF": 0.4, "RB1": -0.4, "RB2": -0.4, "FB1": 0.0, "FB2": 0.0}
    for label, shift in expected.items():
        index = bin_of(families[label].carrier, setup.shape)
        measured = np.angle(shaken[index] * np.conj(still[index]))
        assert measured == pytest.approx(shift, abs=1e-5), label


@pytest.mark.parametrize("reflectivity", [1.0, 0.85, 0.5])
def test_fb1_amplitude_is_the_field_sum(reflectivity: float) -> None:
    setup = integer_bin_setup(**BINS, mirror_reflectivity=reflectivity)
    synthesizer = HologramSynthesizer(setup, threshold=1e-12, noise="none")
    spec = spectrum(synthesizer.intensity(0.0))
    families = {f.label: f for f in predict_families(setup)}
    fb1 = 2 * abs(spec[bin_of(families["FB1"].carrier, setup.shape)])
    if reflectivity == 1.0:
        # lossless: F B1 + B2 B1 + B3 B2 + ... cancel to float32 rounding
        assert fb1 < 1e-6
        assert families["FB1"].amplitude > 0.1  # though each pair alone is strong
    else:
        assert fb1 == pytest.approx(coherent_amplitude(setup, "FB1"), rel=1e-4)
        assert fb1 < 0.7 * families["FB1"].amplitude  # summing families overstates FB1
    for label in ("RF", "RB1", "RB2"):  # alone on their carriers: the pair amplitude
        measured = 2 * abs(spec[bin_of(families[label].carrier, setup.shape)])
        assert measured == pytest.approx(families[label].amplitude, rel=1e-4), label


def test_walk_off_displaces_the_rb1_image() -> None:
    setup = integer_bin_setup((128, 128), (20, 6), (-6, 24), depth=20e-3, mirror_reflectivity=0.5)
    family = {f.label: f for f in predict_families(setup)}["RB1"]
    shift_px = np.array(family.displacement) / setup.pixel_pitch
    assert np.abs(shift_px).max() > 1.5  # a walk-off worth seeing
    x, y = pixel_coordinates(setup)
    period = 128 * setup.pixel_pitch / 4

    def surface(dx: float = 0.0, dy: float = 0.0) -> np.ndarray:
        return 20e-9 * np.sin(2 * np.pi * (x + dx) / period) * np.cos(2 * np.pi * (y + dy) / period)

    synthesizer = HologramSynthesizer(setup, noise="none")
    carrier = family.carrier
    reference = demodulate(synthesizer.intensity(0.0), carrier, 0.08)
    phase = np.angle(
        demodulate(synthesizer.intensity(surface()), carrier, 0.08) * np.conj(reference)
    )
    scale = 4 * np.pi * family.alpha / setup.wavelength
    shifted = scale * surface(*family.displacement)
    unshifted = scale * surface()
    inner = (slice(8, -8), slice(8, -8))
    rms_shifted = np.sqrt(np.mean((phase - shifted)[inner] ** 2))
    rms_unshifted = np.sqrt(np.mean((phase - unshifted)[inner] ** 2))
    assert rms_shifted < 0.02 * np.std(shifted[inner])
    assert rms_unshifted > 5 * rms_shifted


def test_camera_output_types_ranges_and_saturation() -> None:
    rng = np.random.default_rng(3)
    eight = integer_bin_setup(**BINS, bit_depth=8, saturation=2000.0)
    frame = HologramSynthesizer(eight).render(0.0, rng=rng)
    assert frame.dtype == np.uint8
    assert frame.shape == eight.shape
    twelve = integer_bin_setup(**BINS, photons_per_pixel=3000.0, saturation=2000.0)
    synthesizer = HologramSynthesizer(twelve)
    out = np.zeros(twelve.shape, dtype=np.uint16)
    result = synthesizer.render(0.0, rng=rng, out=out)
    assert result is out
    assert out.max() == twelve.max_value  # saturated pixels sit at the top code
    assert np.mean(out == twelve.max_value) > 0.2


@pytest.mark.parametrize("noise", ["poisson", "gaussian", "pooled"])
def test_shot_noise_has_poisson_variance(noise: str) -> None:
    setup = integer_bin_setup(**BINS, saturation=65535.0, bit_depth=16)
    synthesizer = HologramSynthesizer(setup, noise=noise)
    lam = synthesizer.intensity(0.0)
    rng = np.random.default_rng(5)
    frames = np.array([synthesizer.render(0.0, rng=rng) for _ in range(2)], dtype=float)
    residual = frames[0] - frames[1]  # two independent draws about the same mean
    assert np.mean(frames) == pytest.approx(lam.mean(), rel=2e-3)
    assert np.var(residual) / 2 == pytest.approx(lam.mean(), rel=0.03)


@pytest.mark.parametrize(
    ("height", "kwargs", "message"),
    [
        (math.nan, {}, "finite"),
        (np.full((256, 256), math.nan), {}, "NaN"),
        (np.zeros((10, 10)), {}, "shape"),
        (np.zeros((256, 256), complex), {}, "real"),
        (0.0, {"reference_phase": math.inf}, "reference_phase"),
    ],
)
def test_bad_frames_are_input_errors(height: object, kwargs: dict, message: str) -> None:
    synthesizer = HologramSynthesizer(integer_bin_setup(**BINS))
    with pytest.raises(InputError, match=message):
        synthesizer.render(height, rng=np.random.default_rng(0), **kwargs)


def test_noise_needs_a_generator_and_a_known_model() -> None:
    setup = integer_bin_setup(**BINS)
    with pytest.raises(InputError, match="Generator"):
        HologramSynthesizer(setup).render(0.0)
    with pytest.raises(InputError, match="noise"):
        HologramSynthesizer(setup, noise="thermal")


def test_illumination_and_field_stop_shape_the_frame() -> None:
    setup = integer_bin_setup(**BINS, beam_waist=1.5e-3, aperture_radius=2e-3)
    lam = HologramSynthesizer(setup, noise="none").intensity(0.0)
    x, y = pixel_coordinates(setup)
    radius = np.hypot(x, y)
    assert np.all(lam[radius > 2e-3] == 0)
    centre = lam[radius < 0.2e-3].mean()
    ring = lam[(radius > 1.4e-3) & (radius < 1.6e-3)].mean()
    assert ring / centre == pytest.approx(math.exp(-2), rel=0.15)  # 1/e^2 at the waist
