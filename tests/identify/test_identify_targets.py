"""Issue 5 targets on synthesised recordings with known truth, through the real demodulator.

Frames come from :func:`holoview.optics.scenarios.simulate` (128 x 128, Poisson shot
noise, an Ornstein-Uhlenbeck jitter of the reference air path), peaks from
``find_peaks`` and the model labelling, carrier values from
:class:`holoview.processing.maps.demodulate.Demodulator`.
"""

from __future__ import annotations

import numpy as np
import pytest
from identify_model import SynthesisedRecording, synthesise

from holoview.optics.families import alpha_of, predict_families
from holoview.optics.scenarios import ScenarioConfig
from holoview.optics.setup import FLUIDS, Setup
from holoview.optics.surfaces import Mode, StandingWaves
from holoview.optics.synthesis import HologramSynthesizer, pixel_coordinates
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.naming.identify import identify_peaks
from holoview.processing.naming.labelling import label_peaks
from holoview.processing.naming.pca import spatial_phase_pca
from holoview.processing.naming.prefactors import PeakKind
from holoview.processing.peaks.detection import find_peaks
from holoview.processing.series.depth_series import track_depth
from holoview.processing.series.phase_series import check_aliasing, unwrap_in_time
from holoview.processing.series.rate_fits import compare_rate

SHAPE = (128, 128)
INJECTION_AREA = 70.6e-4  # m^2
INJECTION_RATE = 12.3e-9  # m^3/s


@pytest.fixture(scope="module")
def evaporation() -> tuple[Setup, SynthesisedRecording]:
    """Isopropanol, 5.72 um/min, 10 fps, 60 s; reference arm jitter 10 nm rms, 0.5 s."""
    setup = Setup(shape=SHAPE, n2=FLUIDS["isopropanol"])
    config = ScenarioConfig(evaporation_rate=5.72e-6 / 60, vibration_rms=10e-9, vibration_time=0.5)
    return setup, synthesise(setup, "evaporation", config, fps=10.0, frames=600, seed=11)


@pytest.fixture(scope="module")
def injection() -> tuple[Setup, SynthesisedRecording]:
    """Water, 12.3 uL/s into 70.6 cm^2, 25 fps, 24 s; reference arm jitter 3 nm rms, 0.5 s."""
    setup = Setup(shape=SHAPE, n2=FLUIDS["water"])
    config = ScenarioConfig(
        injection_rate=INJECTION_RATE,
        basin_area=INJECTION_AREA,
        vibration_rms=3e-9,
        vibration_time=0.5,
    )
    return setup, synthesise(setup, "injection", config, fps=25.0, frames=600, seed=12)


def model_alphas(setup: Setup, recording: SynthesisedRecording) -> np.ndarray:
    """Each peak's model alpha from its label; NaN for peaks the model does not explain."""
    return np.array(
        [alpha_of(names[0], setup.n1, setup.n2) if names else np.nan for names in recording.names]
    )


def check_pca(setup: Setup, recording: SynthesisedRecording) -> None:
    ident = identify_peaks(
        unwrap_in_time(recording.values), setup.n1, setup.n2, reference=recording.reference
    )
    assert ident.confidence > 0.97
    by_label = ident.by_label()
    for label in ("RF", "RB1", "FB1", "RB2"):
        index = by_label[label]
        assert recording.names[index][0] == label  # PCA and model labelling agree
        expected = alpha_of(label, setup.n1, setup.n2)
        assert ident.alphas[index] == pytest.approx(expected, rel=0.02), label
        assert ident.peaks[index].kind is PeakKind.FAMILY


def test_evaporation_pca_confidence_and_prefactors(evaporation):
    check_pca(*evaporation)


def test_injection_pca_confidence_and_prefactors(injection):
    check_pca(*injection)


def test_evaporation_fused_rate(evaporation):
    setup, recording = evaporation
    alphas = model_alphas(setup, recording)
    known = np.isfinite(alphas)
    track = track_depth(
        recording.values[:, known], recording.times, alphas[known], setup.wavelength
    )
    assert not np.any(track.aliasing.aliased)
    error = track.fit.relative_error(recording.rate)
    assert error < 0.003
    worst_error = max(f.relative_error(recording.rate) for f in track.peak_fits)
    worst_stderr = max(f.stderr for f in track.peak_fits)
    assert worst_error > 3 * error
    assert worst_stderr > 3 * track.fit.stderr


def test_injection_fused_rate_with_aliasing_peaks_excluded(injection):
    setup, recording = injection
    alphas = model_alphas(setup, recording)
    known = np.isfinite(alphas)
    track = track_depth(
        recording.values[:, known], recording.times, alphas[known], setup.wavelength
    )
    # At 25 fps, 70 nm per frame: a peak with alpha above about 2.7 steps past pi.
    step = 4 * np.pi * alphas[known] * recording.rate / 25.0 / setup.wavelength
    should_alias = np.abs(step) > np.pi
    assert np.any(should_alias)
    np.testing.assert_array_equal(track.aliasing.aliased[should_alias], True)
    assert not np.any(track.fused.used[track.aliasing.aliased])
    comparison = compare_rate(track.fit, INJECTION_AREA, INJECTION_RATE)
    assert abs(comparison.relative_error) < 0.005


def test_injection_pca_identifies_the_peaks_that_alias(injection):
    setup, recording = injection
    steps = check_aliasing(recording.values).measured_step
    ident = identify_peaks(
        unwrap_in_time(recording.values),
        setup.n1,
        setup.n2,
        reference=recording.reference,
        steps=steps,
    )
    aliased = [p for p in ident.peaks if p.aliased]
    assert aliased, "RB3 steps 4.9 rad per frame at 25 fps and should alias"
    for peak in aliased:
        assert peak.label == recording.names[peak.index][0]
        assert peak.alpha == pytest.approx(peak.expected_alpha, rel=0.02)


def test_spatial_pca_on_a_synthesised_frame_of_standing_waves():
    """Phase maps of one frame against a flat first frame: the pixels are the samples."""
    setup = Setup(shape=(256, 256))
    side = 256 * setup.pixel_pitch
    modes = (Mode(2, 3, 30e-9, 0.0), Mode(5, 1, 20e-9, 1.0), Mode(1, 4, 25e-9, 2.0))
    waves = StandingWaves(modes, side, depth=5e-3)
    synthesiser = HologramSynthesizer(setup)
    rng = np.random.default_rng(4)
    flat = synthesiser.render(0.0, rng=rng)
    truth = {f.label: f for f in predict_families(setup, max_order=3)}
    anchors = {k: truth[k].observed_carrier for k in ("RB1", "FB1")}
    detected = find_peaks(flat)
    labelling = label_peaks(
        [p.carrier for p in detected], anchors, setup.n1, setup.n2, setup.shape, max_order=3
    )
    chosen = {name: labelling.prediction(name) for name in ("RB1", "RF", "RB2")}
    peaks = [detected[p.peak].flipped() if p.twin else detected[p.peak] for p in chosen.values()]
    # the raised cosine passes the least noise per pixel: the PCA's prefactors are its test
    demodulator = Demodulator(
        setup.shape, peaks, reference="absolute", unwrap="never", window="raised-cosine"
    )
    demodulator.process(flat)
    x, y = pixel_coordinates(setup)
    result = demodulator.process(synthesiser.render(waves(0.013, x, y), rng=rng))
    mask = np.all([r.mask for r in result.peaks], axis=0)
    border = 4  # box pixels next to the frame edge carry the FFT's wrap-around
    mask[:border] = mask[-border:] = False
    mask[:, :border] = mask[:, -border:] = False
    maps = np.array([r.phase for r in result.peaks])
    pca = spatial_phase_pca(maps, mask)
    assert pca.confidence > 0.97
    alphas = pca.prefactors(0, alpha_of("RB1", setup.n1, setup.n2))
    for alpha, label in zip(alphas, chosen, strict=True):
        assert alpha == pytest.approx(alpha_of(label, setup.n1, setup.n2), rel=0.02), label
