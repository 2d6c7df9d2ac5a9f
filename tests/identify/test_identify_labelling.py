"""Model-based labelling on synthesised holograms: predictions matched to detected peaks."""

from __future__ import annotations

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.optics.families import predict_families
from holoview.optics.setup import Ghost, Setup
from holoview.optics.synthesis import HologramSynthesizer
from holoview.processing.naming.labelling import label_peaks
from holoview.processing.peaks.detection import find_peaks

SETUP = Setup(shape=(256, 256))


def bins_apart(a, b, shape=SETUP.shape) -> float:
    """Distance in FFT bins between two carriers (cycles/pixel) on the periodic spectrum."""
    delta = (np.subtract(a, b) + 0.5) % 1.0 - 0.5
    return float(np.hypot(delta[0] * shape[1], delta[1] * shape[0]))


@pytest.fixture(scope="module")
def detected():
    """Peaks found in one synthesised frame of the default water setup, and the truth."""
    frame = HologramSynthesizer(SETUP).render(0.0, rng=np.random.default_rng(0))
    truth = {f.label: f for f in predict_families(SETUP, max_order=3)}
    return [p.carrier for p in find_peaks(frame)], truth


def test_from_rb1_and_fb1_every_first_order_family_within_a_bin(detected):
    carriers, truth = detected
    anchors = {"RB1": truth["RB1"].observed_carrier, "FB1": truth["FB1"].observed_carrier}
    result = label_peaks(carriers, anchors, SETUP.n1, SETUP.n2, SETUP.shape, max_order=3)
    for label in ("RF", "RB2", "FB2", "RB3", "FB3"):
        predicted = result.prediction(label).carrier
        assert bins_apart(predicted, truth[label].observed_carrier) < 1.0, label
    # The detected ones get their names; the faint ones are reported missing.
    found = {name for names in result.names for name in names}
    assert {"RB1", "FB1", "RF", "RB2", "RB3"} <= found
    assert "FB2" in result.missing  # too faint to detect at this mirror reflectivity
    assert result.unexplained == ()
    assert result.flip_hint == ()
    fb1 = result.prediction("FB1").peak
    assert result.names[fb1] == ("FB1", "B2B1", "B3B2")


def test_any_two_labels_that_fix_the_tilts_work(detected):
    carriers, truth = detected
    anchors = {"RF": truth["RF"].observed_carrier, "RB1": truth["RB1"].observed_carrier}
    result = label_peaks(carriers, anchors, SETUP.n1, SETUP.n2, SETUP.shape)
    assert bins_apart(result.prediction("FB1").carrier, truth["FB1"].observed_carrier) < 1.0


def test_a_click_near_a_peak_snaps_to_it(detected):
    carriers, truth = detected
    click = np.add(truth["RB1"].observed_carrier, [2 / 256, -1 / 256])
    anchors = {"RB1": tuple(click), "FB1": truth["FB1"].observed_carrier}
    result = label_peaks(carriers, anchors, SETUP.n1, SETUP.n2, SETUP.shape)
    assert bins_apart(result.prediction("RF").carrier, truth["RF"].observed_carrier) < 1.0


def test_a_label_on_the_wrong_twin_is_an_error_naming_it(detected):
    """With FB1 on its other twin the labels' lattice would swap RF and RB2; the lattice
    that explains the most peaks says the twins disagree. Of two labels it cannot say
    which one is wrong (the whole lattice and its negative explain the same peaks), so it
    names both: blaming the second would have the operator flip the right one, and every
    height would come out negated. A third label settles it."""
    carriers, truth = detected
    fb1 = truth["FB1"].observed_carrier
    anchors = {"RB1": truth["RB1"].observed_carrier, "FB1": (-fb1[0], -fb1[1])}
    with pytest.raises(
        InputError,
        match="labels RB1 and FB1 contradict the lattice: they are given on opposite twins; "
        "label RB1 or FB1 on its other twin",
    ):
        label_peaks(carriers, anchors, SETUP.n1, SETUP.n2, SETUP.shape, max_order=3)
    anchors["RF"] = truth["RF"].observed_carrier
    with pytest.raises(InputError, match="label FB1 contradicts the lattice of the other labels"):
        label_peaks(carriers, anchors, SETUP.n1, SETUP.n2, SETUP.shape, max_order=3)


def test_ghosts_are_found_but_not_predicted():
    setup = SETUP.replace(ghosts=(Ghost("reference", (1.1e-3, -0.6e-3), 0.3),))
    frame = HologramSynthesizer(setup).render(0.0, rng=np.random.default_rng(1))
    peaks = [p.carrier for p in find_peaks(frame)]
    truth = {f.label: f for f in predict_families(setup, max_order=3)}
    anchors = {"RB1": truth["RB1"].observed_carrier, "FB1": truth["FB1"].observed_carrier}
    result = label_peaks(peaks, anchors, setup.n1, setup.n2, setup.shape, max_order=3)
    for ghost in ("RR~g0", "R~g0B1"):
        carrier = truth[ghost].observed_carrier
        twin = (-carrier[0], -carrier[1])
        index = min(
            range(len(peaks)),
            key=lambda i: min(bins_apart(peaks[i], carrier), bins_apart(peaks[i], twin)),
        )
        assert min(bins_apart(peaks[index], carrier), bins_apart(peaks[index], twin)) < 1.0
        assert index in result.unexplained, ghost
    assert bins_apart(result.prediction("RF").carrier, truth["RF"].observed_carrier) < 1.0


def test_a_label_matching_no_peak_is_an_error(detected):
    carriers, truth = detected
    anchors = {"RB1": (0.37, -0.41), "FB1": truth["FB1"].observed_carrier}
    with pytest.raises(InputError, match=r"labelled peak RB1 at .* matches no detected peak"):
        label_peaks(carriers, anchors, SETUP.n1, SETUP.n2, SETUP.shape)


def test_bad_label_sets_are_errors(detected):
    carriers, truth = detected
    rb1 = truth["RB1"].observed_carrier
    with pytest.raises(InputError, match="at least two"):
        label_peaks(carriers, {"RB1": rb1}, SETUP.n1, SETUP.n2, SETUP.shape)
    with pytest.raises(InputError, match="name the same detected peak"):
        label_peaks(carriers, {"RB1": rb1, "FB1": rb1}, SETUP.n1, SETUP.n2, SETUP.shape)
    fb1, rb2 = truth["FB1"].observed_carrier, truth["RB2"].observed_carrier
    with pytest.raises(InputError, match="name one lattice point"):
        label_peaks(carriers, {"FB1": fb1, "B2B1": rb2}, SETUP.n1, SETUP.n2, SETUP.shape)
    rb3 = truth["RB3"].observed_carrier  # labelled FB3: FB1 and FB3 lie along one line
    with pytest.raises(InputError, match="do not fix the lattice"):
        label_peaks(carriers, {"FB1": fb1, "FB3": rb3}, SETUP.n1, SETUP.n2, SETUP.shape)
    with pytest.raises(InputError, match="no detected peaks"):
        label_peaks([], {"RB1": rb1}, SETUP.n1, SETUP.n2, SETUP.shape)
