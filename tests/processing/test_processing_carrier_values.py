"""The carrier probe: exact values, leakage, noise, the map path's series, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from processing_synth import frame, intensity

from holoview.engine.experiment import MAX_PEAKS
from holoview.errors import InputError
from holoview.optics.families import predict_families
from holoview.optics.scenarios import ScenarioConfig, simulate
from holoview.optics.setup import Setup
from holoview.optics.synthesis import HologramSynthesizer
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.peaks.detection import Peak
from holoview.processing.series import carrier_probe
from holoview.processing.series.carrier_probe import (
    TAPER_CYCLES,
    CarrierProbe,
    auto_taper,
    nearest_term,
    structure,
    tukey,
)
from holoview.processing.series.phase_series import check_aliasing, unwrap_in_time
from holoview.processing.series.rate_fits import fit_rate

#: Off-bin carriers (cycles/pixel), amplitudes and phases (rad) of a three-peak frame.
CARRIERS = ((-0.2013, 0.0617), (0.1507, 0.0911), (-0.0498, 0.1523))
AMPLITUDES = (0.3, 0.05, 0.04)
PHASES = (0.3, -1.2, 2.0)
MEAN = 1000.0


def plane_waves(shape: tuple[int, int]) -> np.ndarray:
    """Noise-free ``MEAN (1 + sum 2 A cos(2 pi f.r + phi))``, float64."""
    return MEAN * intensity(shape, CARRIERS, AMPLITUDES, PHASES)


def expected() -> np.ndarray:
    return MEAN * np.array(AMPLITUDES) * np.exp(1j * np.array(PHASES))


def simulator_peaks(setup: Setup, count: int = 5) -> list[Peak]:
    """The ``count`` brightest first-order families with distinct carriers, as peaks."""
    peaks: list[Peak] = []
    for family in predict_families(setup, second_order=False):
        c = family.observed_carrier
        if family.alpha <= 0 or any(math.dist(c, p.carrier) < 1e-6 for p in peaks):
            continue
        peaks.append(Peak(c, family.amplitude, 100.0, label=family.label, alpha=family.alpha))
        if len(peaks) == count:
            break
    return peaks


@pytest.mark.parametrize("dtype", [np.uint16, np.uint8, np.float32, np.float64, np.int32])
def test_values_are_exact_for_plane_waves_of_any_dtype(dtype: type) -> None:
    shape = (96, 130)  # rows not a multiple of the block, columns not of anything
    image = plane_waves(shape)
    if dtype == np.uint8:
        image = image / 8  # fits in 0..255
    probe = CarrierProbe(shape, CARRIERS)
    if np.dtype(dtype).kind in "ui":
        image = np.rint(image)
    result = probe.measure(image.astype(dtype))
    scale = 1 / 8 if dtype == np.uint8 else 1.0
    truth = expected() * scale
    # leakage under 1e-4 on so small a frame (3e-5 measured), plus the rounding to integers
    tolerance = 2e-3 if np.dtype(dtype).kind in "ui" else 1e-4
    np.testing.assert_allclose(np.angle(result.values / truth), 0, atol=tolerance)
    np.testing.assert_allclose(np.abs(result.values) / np.abs(truth), 1, atol=tolerance)
    assert result.mean_counts == pytest.approx(MEAN * scale, rel=1e-3)
    assert result.flags == frozenset()


def test_the_other_twin_gives_the_conjugate_and_peaks_work_like_pairs() -> None:
    shape = (128, 128)
    image = plane_waves(shape)
    direct = CarrierProbe(shape, CARRIERS).measure(image).values
    twins = [Peak((-fx, -fy), 0.1, 10.0, label=f"P{i}") for i, (fx, fy) in enumerate(CARRIERS)]
    flipped = CarrierProbe(shape, twins).measure(image).values
    np.testing.assert_allclose(flipped, np.conj(direct), rtol=1e-6)


def test_strided_views_and_inputs_are_not_modified() -> None:
    big = plane_waves((160, 200)).astype(np.float32)
    view = big[10:138, 20:180]  # not contiguous
    frozen = big.copy()
    probe = CarrierProbe(view.shape, CARRIERS)
    np.testing.assert_allclose(
        probe.measure(view).values, probe.measure(np.ascontiguousarray(view)).values, rtol=1e-6
    )
    np.testing.assert_array_equal(big, frozen)


def test_the_taper_keeps_neighbours_and_the_zero_order_out() -> None:
    """Noise-free simulated frames of a uniform level swept over 5 um: every relative phase
    turns, so the phase error against the level is the leakage of every other term."""
    setup = Setup(shape=(128, 128), m_r=(1.0e-3, 0.6e-3), m_b=(-0.3e-3, 0.8e-3))
    peaks = simulator_peaks(setup)
    synthesizer = HologramSynthesizer(setup, noise="none")
    levels = np.random.default_rng(1).uniform(0, 5e-6, 32)
    tapered = CarrierProbe(setup.shape, peaks, noise=False)
    uniform = CarrierProbe(setup.shape, peaks, taper=0.0, noise=False)
    demod = Demodulator(setup.shape, peaks, reference="synthetic", unwrap="never", threads=1)
    alphas = np.array([p.alpha for p in peaks])
    errors: dict[str, list[np.ndarray]] = {"tapered": [], "uniform": [], "map path": []}
    for level in levels:
        photons = synthesizer.intensity(level).astype(np.float64)
        image = np.clip(photons / setup.saturation, 0, 1) ** setup.gamma * setup.max_value
        truth = np.exp(1j * 4 * np.pi / setup.wavelength * alphas * level)
        errors["tapered"].append(tapered.measure(image).values / truth)
        errors["uniform"].append(uniform.measure(image).values / truth)
        map_values = np.array([r.carrier_value for r in demod.process(image).peaks])
        errors["map path"].append(map_values / truth)
    worst = {}
    for name, ratios in errors.items():
        z = np.array(ratios)
        deviation = np.angle(z * np.conj(np.mean(z / np.abs(z), axis=0)))
        worst[name] = float(np.abs(deviation).max())
    # measured: tapered 4.0e-4 rad, uniform weights 0.53 rad, the map path 0.18 rad
    assert worst["tapered"] < 2e-3
    assert worst["uniform"] > 20 * worst["tapered"]
    assert worst["map path"] > 20 * worst["tapered"]


def test_an_aperture_keeps_the_field_stop_out() -> None:
    setup = Setup(shape=(256, 256), aperture_radius=0.45 * 256 * 20e-6)
    peaks = simulator_peaks(setup)
    rows, cols = setup.shape
    y, x = np.mgrid[:rows, :cols]
    aperture = np.hypot(y - (rows - 1) / 2, x - (cols - 1) / 2) <= 0.45 * 256
    synthesizer = HologramSynthesizer(setup, noise="none")
    alphas = np.array([p.alpha for p in peaks])
    plain = CarrierProbe(setup.shape, peaks, noise=False)
    stopped = CarrierProbe(setup.shape, peaks, noise=False, aperture=aperture)
    worst = {}
    for name, probe in (("plain", plain), ("aperture", stopped)):
        ratios = []
        for level in np.random.default_rng(2).uniform(0, 5e-6, 24):
            truth = np.exp(1j * 4 * np.pi / setup.wavelength * alphas * level)
            ratios.append(probe.measure(synthesizer.intensity(level)).values / truth)
        z = np.array(ratios)
        deviation = np.angle(z * np.conj(np.mean(z / np.abs(z), axis=0)))
        worst[name] = float(np.abs(deviation).max())
    # measured: 0.32 rad with the frame's taper (the stop is an edge inside it), 1.7e-5 with it
    assert worst["aperture"] < 1e-3
    assert worst["plain"] > 20 * worst["aperture"]


def test_the_noise_estimate_matches_the_spread_of_the_phases() -> None:
    shape = (128, 128)
    mean = MEAN * intensity(shape, CARRIERS, AMPLITUDES, PHASES)
    rng = np.random.default_rng(3)
    probe = CarrierProbe(shape, CARRIERS)
    values, noise = [], []
    for _ in range(150):
        result = probe.measure(rng.poisson(mean).astype(np.uint16))
        values.append(result.values)
        noise.append(result.noise)
    z = np.array(values)
    spread = np.angle(z * np.conj(z.mean(axis=0))).std(axis=0)
    estimate = np.median(np.array(noise), axis=0)
    np.testing.assert_allclose(estimate, spread, rtol=0.25)
    # and the floor is the shot noise of the whole frame, times the taper's noise gain
    floor = probe.noise_gain / (np.array(AMPLITUDES) * np.sqrt(2 * MEAN * shape[0] * shape[1]))
    np.testing.assert_allclose(spread, floor, rtol=0.25)


def test_series_equal_the_map_path_on_a_simulated_evaporation() -> None:
    """Unwrapped mean-phase series and fitted rates from the probe and from the maps."""
    setup = Setup(shape=(128, 128))
    peaks = simulator_peaks(setup)
    probe = CarrierProbe(setup.shape, peaks)
    demod = Demodulator(setup.shape, peaks, reference="relative", unwrap="never", threads=1)
    fps, rate = 20.0, -3e-7  # m/s: FB2 steps 0.95 rad a frame
    config = ScenarioConfig(evaporation_rate=-rate)
    times, probed, mapped, noise = [], [], [], []
    for image, truth in simulate(setup, "evaporation", frames=120, fps=fps, seed=3, config=config):
        result = probe.measure(image)
        times.append(truth.time)
        probed.append(result.values)
        noise.append(result.noise)
        mapped.append([r.carrier_value for r in demod.process(image).peaks])
    up, um = unwrap_in_time(np.array(probed)), unwrap_in_time(np.array(mapped))
    difference = (up - um) - (up - um).mean(axis=0)
    rms = np.sqrt(np.mean(difference**2, axis=0))
    own = np.median(np.array(noise), axis=0)
    # measured: 0.43 to 1.04 of the probe's own per-frame noise (the two weightings share
    # most of the photons, not all)
    assert np.all(rms < 1.5 * own), (rms, own)
    for j, peak in enumerate(peaks):
        to_height = setup.wavelength / (4 * np.pi * peak.alpha)
        fp, fm = fit_rate(times, up[:, j] * to_height), fit_rate(times, um[:, j] * to_height)
        assert abs(fp.rate - fm.rate) < 2 * math.hypot(fp.stderr, fm.stderr), peak.label
        assert abs(fp.rate - rate) < 4 * fp.stderr + 1e-3 * abs(rate), peak.label


def test_series_rates_equal_the_map_path_on_simulated_waves() -> None:
    setup = Setup(shape=(128, 128))
    peaks = simulator_peaks(setup)
    probe = CarrierProbe(setup.shape, peaks, noise=False)
    demod = Demodulator(setup.shape, peaks, reference="relative", unwrap="never", threads=1)
    times, probed, mapped = [], [], []
    for image, truth in simulate(setup, "waves", frames=120, fps=240.0, seed=4):
        times.append(truth.time)
        probed.append(probe.measure(image).values)
        mapped.append([r.carrier_value for r in demod.process(image).peaks])
    aliased = check_aliasing(np.array(mapped)).aliased  # steps near pi: no series to compare
    up, um = unwrap_in_time(np.array(probed)), unwrap_in_time(np.array(mapped))
    compared = 0
    for j, peak in enumerate(peaks):
        if aliased[j]:
            continue
        to_height = setup.wavelength / (4 * np.pi * peak.alpha)
        fp, fm = fit_rate(times, up[:, j] * to_height), fit_rate(times, um[:, j] * to_height)
        assert abs(fp.rate - fm.rate) < math.hypot(fp.stderr, fm.stderr), peak.label
        compared += 1
    assert compared >= 3


def test_with_carriers_equals_a_new_probe_and_keeps_an_explicit_taper() -> None:
    shape = (100, 120)
    image = plane_waves(shape)
    probe = CarrierProbe(shape, CARRIERS, taper=0.3, saturation=1500)
    other = probe.with_carriers(CARRIERS[:2])
    assert other.taper == (0.3, 0.3) and other.saturation == 1500
    np.testing.assert_allclose(
        other.measure(image).values,
        CarrierProbe(shape, CARRIERS[:2], taper=0.3).measure(image).values,
        rtol=1e-12,
    )
    auto = CarrierProbe(shape, CARRIERS).with_carriers(CARRIERS[:1])
    assert auto.taper == (auto_taper(100, auto.spacing), auto_taper(120, auto.spacing))


def test_the_automatic_taper_holds_its_beat_periods() -> None:
    f = np.array(CARRIERS)
    spacing = nearest_term(f)
    assert spacing == pytest.approx(min(np.hypot(*(f[0] - f[2])), np.hypot(*f[2])), rel=1e-9)
    assert auto_taper(1024, spacing) * 1024 / 2 * spacing == pytest.approx(TAPER_CYCLES)
    assert auto_taper(32, spacing) == 1.0  # a small frame: a Hann window
    w = tukey(101, 0.2)
    assert w[0] == 0 and w[50] == 1 and np.all(w[10:91] == 1) and np.all(w[1:10] < 1)
    points = structure(f)
    assert any(np.allclose(p, f[0] + f[1]) for p in points)
    assert any(np.allclose(p, [0, 0]) for p in points)


def test_flagged_frames_keep_the_stream_going() -> None:
    shape = (64, 64)
    probe = CarrierProbe(shape, CARRIERS, saturation=1500)
    image = plane_waves(shape)
    assert "saturated" in probe.measure(image).flags  # 1000 (1 + 2 x 0.39) reaches 1500
    for bad in (np.nan, np.inf, -np.inf, 1e39):
        broken = image.copy()
        broken[17, 5] = bad
        result = probe.measure(broken)
        assert "nonfinite" in result.flags
        assert np.isnan(result.values).all() and np.isnan(result.noise).all()
        assert math.isnan(result.mean_counts)
    assert probe.measure(image).flags == frozenset({"saturated"})


@pytest.mark.parametrize(
    ("carriers", "kwargs", "message"),
    [
        ([], {}, "no carriers"),
        ([(0.6, 0.1)], {}, "outside the spectrum"),
        ([(np.nan, 0.1)], {}, "non-finite"),
        ([(0.001, 0.0)], {}, "zero frequency"),
        ([(0.1,)], {}, "must be \\(fx, fy\\)"),
        ([(0.1, 0.2)], {"taper": 1.5}, "taper"),
        ([(0.1, 0.2)], {"aperture": np.ones((8, 8), bool)}, "aperture mask has shape"),
        ([(0.1, 0.2)], {"aperture": np.zeros((64, 64), bool)}, "no pixel"),
    ],
)
def test_bad_configurations(carriers: list, kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        CarrierProbe((64, 64), carriers, **kwargs)


def test_bad_shapes_and_frames() -> None:
    with pytest.raises(InputError, match="frame shape"):
        CarrierProbe((8, 64), CARRIERS)
    probe = CarrierProbe((64, 64), CARRIERS)
    rng = np.random.default_rng(0)
    good = frame((64, 64), CARRIERS, AMPLITUDES, PHASES, rng=rng)
    with pytest.raises(InputError, match=r"shape \(64, 65\); this probe expects \(64, 64\)"):
        probe.measure(np.zeros((64, 65)))
    with pytest.raises(InputError, match="2-D"):
        probe.measure(np.zeros((64, 64, 3)))
    with pytest.raises(InputError, match="dtype complex"):
        probe.measure(good.astype(np.complex64))
    with pytest.raises(InputError, match="dtype bool"):
        probe.measure(good > 800)


def _noise_rows_plainly(carriers: np.ndarray, which: int) -> np.ndarray:
    """One carrier's noise rows: every candidate's distance to every term."""
    terms = carrier_probe.structure(carriers)
    n = carrier_probe.NOISE_CANDIDATES
    candidates = (np.arange(n) + 0.5) / n - 0.5
    dx = (carriers[which, 0] - terms[:, 0] + 0.5) % 1.0 - 0.5
    dy = (candidates[:, None] - terms[None, :, 1] + 0.5) % 1.0 - 0.5
    clearance = np.hypot(dx[None, :], dy).min(axis=1)
    order = np.argsort(-clearance, kind="stable")[: carrier_probe.NOISE_POINTS]
    return candidates[np.sort(order)]


def test_noise_rows_are_the_farthest_from_every_term_for_any_number_of_peaks() -> None:
    rng = np.random.default_rng(3)
    # up to the most peaks an experiment holds: 197121 terms, whose distances to every
    # candidate of every carrier at once took 24 GiB (the live window at 256 peaks)
    for n in (1, 2, 6, 20, MAX_PEAKS):
        carriers = rng.uniform(-0.45, 0.45, (n, 2))
        rows = carrier_probe._noise_rows(carriers)
        assert rows.shape == (n, carrier_probe.NOISE_POINTS)
        for which in range(min(n, 3)):
            np.testing.assert_array_equal(rows[which], _noise_rows_plainly(carriers, which))
