"""Numerical phase tracing against the fast synthesis (supplement, section II).

What differs between the two, and why:

- constant phases of the B_j beams: the tracer follows the exact paths in the wedge
  between the tilted mirror and the surface, which lag behind ``2 j n2 d`` by a term
  growing like ``j**3 m_b**2 d`` (Brossel's multiple-beam Fizeau lag); the paper's
  model, and so the synthesiser, leaves it out. Relative and absolute reconstructions
  cancel constants, so the demodulated phases agree; but the etalon sums at FB_j do
  not cancel in the tracer even for a lossless mirror, unless the wedge is thin;
- amplitudes: the tracer's Fresnel coefficients use the local angle (s polarisation);
  at these tilts they equal the normal-incidence ones to about 1e-6;
- the B_j height terms: the tracer samples the surface at every internal reflection,
  the synthesiser at their weighted centroid (first order in the walk-off).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.optics.beams import field_beams
from holoview.optics.families import predict_families
from holoview.optics.setup import Setup
from holoview.optics.synthesis import HologramSynthesizer, pixel_coordinates
from holoview.optics.tracing import trace_fields, trace_frame

from .benches import integer_bin_setup, random_setup
from .spectra import bin_of, demodulate, peak_near, spectrum
from .test_optics_synthesis import _isolated

SMALL = {"shape": (128, 128), "rf_bins": (15, 8), "fb1_bins": (-5, 12)}


def test_traced_fields_are_the_model_beams_up_to_constant_phases() -> None:
    setup = integer_bin_setup(**SMALL)
    result = trace_fields(setup, 0.0)
    synthesizer = HologramSynthesizer(setup, noise="none")
    assert result.passes == max(b.passes for b in field_beams(setup))  # 5e-4 threshold
    for index, beam in enumerate(synthesizer.beams):
        model = np.outer(synthesizer._u[:, index], synthesizer._v[index])
        traced = result.fields[beam.name]
        assert np.abs(traced).mean() == pytest.approx(abs(beam.amplitude), rel=1e-4)
        difference = np.angle(traced * np.conj(model))
        assert np.std(difference) < 5e-3, beam.name  # only a constant differs


def test_traced_frame_carriers_match_the_model() -> None:
    rng = np.random.default_rng(21)
    setup = random_setup(rng, shape=(256, 256))
    frame = trace_frame(setup, 0.0, rng)
    rows, cols = setup.shape
    spec = spectrum(frame * np.outer(np.hanning(rows), np.hanning(cols)))
    noise = 1 / math.sqrt(setup.photons_per_pixel * frame.size)
    families = predict_families(setup, max_order=3, second_order=False)
    checked = _isolated(setup, families, floor=40 * noise)
    assert {"RF", "RB1", "RB2"} <= {f.label for f in checked}
    for family in checked:
        fx, fy, _ = peak_near(spec, family.observed_carrier)
        error = np.array([fx - family.observed_carrier[0], fy - family.observed_carrier[1]])
        error = (error + 0.5) % 1.0 - 0.5
        assert np.abs(error * (cols, rows)).max() <= 0.5, family.label


@pytest.mark.parametrize("label", ["RB1", "RF"])
def test_tracing_and_synthesis_agree_on_a_weakly_sloped_surface(label: str) -> None:
    # the default bench's carriers are far apart: no neighbour's sidebands in the window
    setup = Setup(shape=(128, 128))

    def surface(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return 30e-9 * np.cos(2 * np.pi * x / 1.5e-3) * np.cos(2 * np.pi * y / 2e-3)

    x, y = pixel_coordinates(setup)
    synthesizer = HologramSynthesizer(setup, noise="none")
    family = {f.label: f for f in predict_families(setup)}[label]
    frames = {
        "synthesis": (synthesizer.intensity(0.0), synthesizer.intensity(surface(x, y))),
        "tracing": (trace_fields(setup, 0.0).intensity, trace_fields(setup, surface).intensity),
    }
    phases = {}
    for name, (flat, waved) in frames.items():
        reference = demodulate(flat, family.carrier, 0.05)
        phases[name] = np.angle(demodulate(waved, family.carrier, 0.05) * np.conj(reference))
    inner = (slice(16, -16), slice(16, -16))
    signal = np.std(phases["synthesis"][inner])
    truth = 4 * np.pi * family.alpha * surface(x, y) / setup.wavelength
    assert signal == pytest.approx(np.std(truth[inner]), rel=0.1)  # a real phase signal
    difference = phases["tracing"] - phases["synthesis"]
    assert np.sqrt(np.mean(difference[inner] ** 2)) < 0.02 * signal


def test_a_wedge_breaks_the_lossless_cancellation_in_proportion_to_its_lag() -> None:
    amplitudes = {}
    for depth in (5e-3, 0.2e-3):
        setup = integer_bin_setup(**SMALL, mirror_reflectivity=1.0, depth=depth)
        fb1 = {f.label: f for f in predict_families(setup)}["FB1"]
        result = trace_fields(setup, 0.0, threshold=1e-6)
        amplitudes[depth] = 2 * abs(spectrum(result.intensity)[bin_of(fb1.carrier, setup.shape)])
        pair = fb1.amplitude
    assert amplitudes[5e-3] > 0.3 * pair  # 5 mm of wedge: the j**3 lag is about 1 rad
    assert amplitudes[0.2e-3] < 0.05 * pair  # 0.2 mm: nearly plane-parallel, it cancels


def test_tracer_rejects_bad_input() -> None:
    setup = integer_bin_setup(**SMALL)
    with pytest.raises(InputError, match="threshold"):
        trace_fields(setup, 0.0, threshold=0.0)
    with pytest.raises(InputError, match="finite"):
        trace_fields(setup, math.nan)
    with pytest.raises(InputError, match="NaN"):
        trace_fields(setup, lambda x, y: np.full(np.shape(x), math.nan))
