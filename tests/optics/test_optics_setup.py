"""The setup's validation and the family model (carriers, alpha, inference)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.optics.families import (
    alpha_of,
    coherent_amplitude,
    infer_carriers,
    predict_carriers,
    predict_families,
)
from holoview.optics.setup import FLUIDS, Ghost, Setup

from .benches import random_setup


@pytest.mark.parametrize(
    ("changes", "named"),
    [
        ({"wavelength": -532e-9}, "wavelength"),
        ({"wavelength": math.nan}, "wavelength"),
        ({"n2": 0.9}, "n2"),
        ({"n1": math.inf}, "n1"),
        ({"depth": 0.0}, "depth"),
        ({"mirror_reflectivity": 1.2}, "mirror_reflectivity"),
        ({"m_r": (math.nan, 0.0)}, "m_r"),
        ({"m_b": (0.2, 0.0)}, "m_b"),
        ({"m_r": (8e-3, 0.0)}, "m_r"),  # RF at 0.6 cycles/pixel: past Nyquist
        ({"m_b": (0.0, -6e-3)}, "m_b"),  # FB1 at -0.6
        ({"m_r": (-3.5e-3, 0.0), "m_b": (3.5e-3, 0.0)}, "m_r and m_b"),  # RB1 at 0.88
        ({"pixel_pitch": -1e-6}, "pixel_pitch"),
        ({"shape": (1, 100)}, "shape"),
        ({"bit_depth": 17}, "bit_depth"),
        ({"photons_per_pixel": math.nan}, "photons_per_pixel"),
        ({"gamma": 0.0}, "gamma"),
        ({"beam_waist": -1.0}, "beam_waist"),
        ({"ghosts": ("reference",)}, "ghosts"),
    ],
)
def test_bad_setup_names_the_parameter(changes: dict, named: str) -> None:
    with pytest.raises(InputError, match=named):
        Setup(**changes)


def test_aliasing_is_reported_not_folded() -> None:
    with pytest.raises(InputError, match=r"Nyquist"):
        Setup(m_r=(8e-3, 0.0))


@pytest.mark.parametrize(
    ("ghost", "named"),
    [
        ({"arm": "sample"}, "arm"),
        ({"amplitude": 1.5}, "amplitude"),
        ({"tilt": (math.nan, 0.0)}, "tilt"),
    ],
)
def test_bad_ghost_names_the_parameter(ghost: dict, named: str) -> None:
    with pytest.raises(InputError, match=named):
        Ghost(**ghost)


def test_setup_round_trips_through_a_dict() -> None:
    setup = Setup(ghosts=(Ghost("probe", (1e-3, -2e-3), 0.04),), beam_waist=5e-3)
    assert Setup.from_dict(setup.to_dict()) == setup
    with pytest.raises(InputError, match="colour"):
        Setup.from_dict({**setup.to_dict(), "colour": "green"})
    attrs = setup.as_attributes()
    assert attrs["wavelength_m"] == setup.wavelength
    assert attrs["pixel_pitch_m"] == setup.pixel_pitch
    assert attrs["ghost0_arm"] == "probe"


def test_presets_are_the_papers() -> None:
    assert FLUIDS["water"] == 1.333
    assert FLUIDS["isopropanol"] == 1.377
    assert 1.0 < FLUIDS["air"] < 1.001


@pytest.mark.parametrize("seed", range(4))
def test_predicted_carriers_follow_the_model_relations(seed: int) -> None:
    setup = random_setup(np.random.default_rng(seed))
    families = {f.label: f for f in predict_families(setup, max_order=3)}
    scale = 2 * setup.pixel_pitch / setup.wavelength
    rf = np.array(setup.m_r) * setup.n1 * scale
    fb1 = np.array(setup.m_b) * setup.n2 * scale
    np.testing.assert_allclose(families["RF"].carrier, rf)
    for j in (1, 2, 3):
        np.testing.assert_allclose(families[f"FB{j}"].carrier, j * fb1)
        np.testing.assert_allclose(families[f"RB{j}"].carrier, j * fb1 - rf)
        np.testing.assert_allclose(families[f"2RB{j}"].carrier, 2 * (j * fb1 - rf))
    np.testing.assert_allclose(families["B3B1"].carrier, families["FB2"].carrier)
    np.testing.assert_allclose(families["B3B2"].carrier, families["FB1"].carrier)
    for family in families.values():
        assert family.alpha > 0
        assert family.alpha == pytest.approx(alpha_of(family.label, setup.n1, setup.n2))


def test_alpha_of_follows_the_design_conventions() -> None:
    n1, n2 = 1.0003, 1.377
    assert alpha_of("RF", n1, n2) == pytest.approx(n1)
    assert alpha_of("RB1", n1, n2) == pytest.approx(n2 - n1)
    assert alpha_of("RB3", n1, n2) == pytest.approx(3 * n2 - n1)
    assert alpha_of("FB2", n1, n2) == pytest.approx(2 * n2)
    assert alpha_of("B3B1", n1, n2) == pytest.approx(2 * n2)
    assert alpha_of("2RB1", n1, n2) == pytest.approx(2 * (n2 - n1))
    assert alpha_of("R~g0F", n1, n2) == alpha_of("RF", n1, n2)
    assert alpha_of("RB1~g2", n1, n2) == alpha_of("RB1", n1, n2)
    assert alpha_of("RR~g0", n1, n2) == 0
    for bad in ("XY", "RB", "B0F", "", "RFB1"):
        with pytest.raises(InputError, match=r"label|beam"):
            alpha_of(bad, n1, n2)
    with pytest.raises(InputError, match="n2"):
        alpha_of("RF", 1.4, 1.3)


@pytest.mark.parametrize(
    "pair", [("RB1", "FB1"), ("RF", "RB1"), ("RF", "FB1"), ("RB2", "FB1"), ("RB1", "RB2")]
)
def test_two_labelled_peaks_fix_every_carrier(pair: tuple[str, str]) -> None:
    setup = random_setup(np.random.default_rng(11))
    truth = predict_carriers(setup, max_order=3)
    inferred = infer_carriers({k: truth[k] for k in pair}, setup.n1, setup.n2, max_order=3)
    for label, carrier in inferred.items():
        np.testing.assert_allclose(carrier, truth[label], atol=1e-12, err_msg=label)
    assert {"RF", "RB1", "FB1", "RB3", "FB3", "B3B1", "2RB1"} <= set(inferred)


@pytest.mark.parametrize(
    ("labelled", "message"),
    [
        ({"FB1": (0.1, 0.1)}, "two labelled"),
        ({"FB1": (0.1, 0.1), "FB2": (0.2, 0.2)}, "two labelled"),
        ({"FB1": (0.1, 0.1), "B2B1": (0.1, 0.1)}, "two labelled"),
        ({"RB1~g0": (0.1, 0.1), "FB1": (0.2, 0.0)}, "ghost"),
        ({"RB1": (math.nan, 0.1), "FB1": (0.2, 0.0)}, "finite"),
        ({"RB1": (0.1,), "FB1": (0.2, 0.0)}, "carrier"),
        ({"RQ": (0.1, 0.1), "FB1": (0.2, 0.0)}, "label"),
    ],
)
def test_inference_rejects_what_cannot_fix_the_model(labelled: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        infer_carriers(labelled, 1.0, 1.333)


def test_lossless_mirror_cancels_fb1_in_the_field_sum() -> None:
    lossless = Setup(mirror_reflectivity=1.0)
    # the series is cut where the fields fall under 1e-12: the residue is about that
    assert coherent_amplitude(lossless, "FB1") < 1e-10
    assert coherent_amplitude(lossless, "FB2") < 1e-10
    pair = {f.label: f.amplitude for f in predict_families(lossless)}["FB1"]
    assert pair > 0.1  # each pair alone is strong: only their sum cancels
    # with reflectance 0.85 the closed form of the geometric sum (beams.py docstring)
    setup = Setup(mirror_reflectivity=0.85)
    R, rho = setup.surface_reflection, math.sqrt(0.85)
    fields = [1.0, R**2] + [((1 - R * R) * rho**j * R ** (j - 1)) ** 2 for j in range(1, 60)]
    expected = 2 * abs((1 - R * R) * rho * R * (rho * rho - 1) / (1 - rho * rho * R * R))
    assert coherent_amplitude(setup, "FB1") == pytest.approx(expected / sum(fields), rel=1e-9)


def test_ghost_families_copy_alpha_and_shift_the_carrier() -> None:
    tilt = (1.0e-3, -0.5e-3)
    setup = Setup(ghosts=(Ghost("reference", tilt, 0.05), Ghost("probe", tilt, 0.03)))
    families = {f.label: f for f in predict_families(setup)}
    scale = 2 * setup.pixel_pitch / setup.wavelength * setup.n1
    shift = np.array(tilt) * scale
    np.testing.assert_allclose(families["R~g0F"].carrier, np.array(families["RF"].carrier) + shift)
    np.testing.assert_allclose(
        families["R~g0B1"].carrier, np.array(families["RB1"].carrier) - shift
    )
    np.testing.assert_allclose(
        families["RB1~g1"].carrier, np.array(families["RB1"].carrier) + shift
    )
    assert families["R~g0B1"].alpha == families["RB1"].alpha
    assert families["R~g0B1"].kind == "ghost"
    assert families["RR~g0"].alpha == 0
    assert families["R~g0B1"].amplitude == pytest.approx(0.05 * families["RB1"].amplitude)


def test_displacements_follow_the_walk_off() -> None:
    setup = Setup(depth=8e-3, m_b=(1e-3, -0.5e-3))
    families = {f.label: f for f in predict_families(setup)}
    d, (mx, my) = setup.depth, setup.m_b
    assert families["RF"].displacement == (0.0, 0.0)
    # RB1 samples h at the entry point and the exit point, equally: their midpoint
    np.testing.assert_allclose(families["RB1"].displacement, (-d * mx, -d * my))
    n1, n2 = setup.n1, setup.n2
    np.testing.assert_allclose(
        families["FB1"].displacement, (-d * mx * (n2 - n1) / n2, -d * my * (n2 - n1) / n2)
    )
