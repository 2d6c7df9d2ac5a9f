"""Classification of prefactors into families, repeats, second orders, weak, unexplained."""

from __future__ import annotations

import numpy as np
import pytest
from identify_model import N_AIR, ModelPeak, model_peaks, simulate

from holoview.errors import InputError
from holoview.processing.naming.identify import identify_peaks
from holoview.processing.naming.prefactors import PeakKind, classify_prefactors, family_alphas
from holoview.processing.series.phase_series import check_aliasing, unwrap_in_time

N1, N2 = 1.0, 1.333


def test_family_alphas_follow_the_paper():
    table = family_alphas(N1, N2, max_order=2)
    assert table == pytest.approx(
        {"RF": N1, "RB1": N2 - N1, "FB1": N2, "RB2": 2 * N2 - N1, "FB2": 2 * N2}
    )


def test_each_kind_is_recognised():
    alphas = [0.333, 1.002, 1.33, 0.335, 0.668, -1.668, 1.15, 0.2]
    explained = [1, 1, 1, 1, 1, 1, 1, 0.3]
    peaks = classify_prefactors(alphas, N1, N2, explained=explained)
    kinds = [(p.kind, p.label) for p in peaks]
    assert kinds == [
        (PeakKind.FAMILY, "RB1"),
        (PeakKind.FAMILY, "RF"),
        (PeakKind.FAMILY, "FB1"),
        (PeakKind.REPEAT, "RB1"),
        (PeakKind.SECOND_ORDER, "2RB1"),
        (PeakKind.FAMILY, "RB2"),
        (PeakKind.UNEXPLAINED, None),
        (PeakKind.WEAK, None),
    ]
    assert peaks[5].flipped and not peaks[0].flipped
    assert peaks[1].mismatch == pytest.approx(0.002)
    assert peaks[6].mismatch is None


def test_the_tolerance_decides_a_match():
    assert classify_prefactors([1.04], N1, N2)[0].kind is PeakKind.UNEXPLAINED
    assert classify_prefactors([1.04], N1, N2, tolerance=0.05)[0].label == "RF"


def test_second_order_of_fb1_is_fb2():
    # 2 * FB1 has the alpha (and the carrier) of FB2: reported as that family.
    assert classify_prefactors([2 * N2], N1, N2)[0].label == "FB2"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n1": 1.4, "n2": 1.3}, "must exceed n1"),
        ({"tolerance": 0.7}, "tolerance"),
        ({"explained": [1.0]}, "explained has shape"),
    ],
)
def test_bad_classification_input(kwargs, message):
    args = {"alphas": [0.3, 1.0], "n1": N1, "n2": N2} | kwargs
    with pytest.raises(InputError, match=message):
        classify_prefactors(**args)


def test_identify_peaks_labels_the_brightest_as_rb1(evaporation):
    phases = unwrap_in_time(evaporation.values)
    amplitudes = [p.amplitude for p in evaporation.peaks]
    ident = identify_peaks(phases, N_AIR, 1.377, amplitudes=amplitudes)
    assert ident.reference == 0
    labels = [(p.kind, p.label) for p in ident.peaks]
    assert labels == [
        (PeakKind.FAMILY, "RB1"),
        (PeakKind.FAMILY, "RF"),
        (PeakKind.FAMILY, "FB1"),
        (PeakKind.REPEAT, "RB1"),
        (PeakKind.FAMILY, "RB2"),
        (PeakKind.SECOND_ORDER, "2RB1"),
    ]
    assert ident.by_label() == {"RB1": 0, "RF": 1, "FB1": 2, "RB2": 4}


def test_a_dimmer_peak_with_a_family_alpha_is_the_repeat(evaporation):
    phases = unwrap_in_time(evaporation.values)
    # Make the ghost (index 3) brighter than RB1's own peak, and label the ghost.
    amplitudes = [10.0, 3.0, 2.0, 20.0, 0.6, 0.4]
    ident = identify_peaks(phases, N_AIR, 1.377, amplitudes=amplitudes)
    assert ident.reference == 3
    assert ident.peaks[3].kind is PeakKind.FAMILY
    assert ident.peaks[0].kind is PeakKind.REPEAT


def test_identify_needs_a_reference_and_a_known_label(evaporation):
    phases = unwrap_in_time(evaporation.values)
    with pytest.raises(InputError, match="labelled peak's index or the peak amplitudes"):
        identify_peaks(phases, N_AIR, 1.377)
    with pytest.raises(InputError, match="'XB1' is not a family label"):
        identify_peaks(phases, N_AIR, 1.377, reference=0, reference_label="XB1")
    with pytest.raises(InputError, match="carries no height"):
        identify_peaks(phases, N_AIR, 1.377, reference=0, reference_label="RR~g0")
    with pytest.raises(InputError, match="3 amplitudes given for 6 peaks"):
        identify_peaks(phases, N_AIR, 1.377, amplitudes=[1, 2, 3])


def test_another_labelled_family_gives_the_same_prefactors(evaporation):
    phases = unwrap_in_time(evaporation.values)
    from_rb1 = identify_peaks(phases, N_AIR, 1.377, reference=0).alphas
    from_fb1 = identify_peaks(phases, N_AIR, 1.377, reference=2, reference_label="FB1").alphas
    assert np.allclose(from_rb1, from_fb1, rtol=0.02)
    # A second order works as the label too (any label the model knows).
    from_2rb1 = identify_peaks(phases, N_AIR, 1.377, reference=5, reference_label="2RB1").alphas
    assert np.allclose(from_rb1, from_2rb1, rtol=0.02)


def test_a_peak_aliasing_in_time_is_identified_from_its_steps():
    """Water at 25 fps, 70 nm per frame: FB2's phase steps 4.4 rad, seen as -1.9 rad."""
    n2 = 1.333
    peaks = [*model_peaks(N_AIR, n2), ModelPeak("FB2", 2 * n2, 0.0, 0.3, 0.05)]
    recording = simulate(peaks, 12.3e-9 / 70.6e-4, fps=25.0, duration=20.0, vibration=3e-9, seed=9)
    phases = unwrap_in_time(recording.values)
    steps = check_aliasing(recording.values).measured_step
    plain = identify_peaks(phases, N_AIR, n2, reference=0)
    assert plain.peaks[6].kind is PeakKind.UNEXPLAINED
    resolved = identify_peaks(phases, N_AIR, n2, reference=0, steps=steps)
    fb2 = resolved.peaks[6]
    assert (fb2.kind, fb2.label, fb2.aliased) == (PeakKind.FAMILY, "FB2", True)
    assert fb2.alpha == pytest.approx(2 * n2, rel=0.02)
    assert not any(p.aliased for p in resolved.peaks[:6])
    assert [p.label for p in resolved.peaks[:6]] == [p.label for p in plain.peaks[:6]]


def test_alias_resolution_needs_a_moving_level(evaporation):
    phases = unwrap_in_time(evaporation.values)
    with pytest.raises(InputError, match="2 phase steps given for 6 peaks"):
        identify_peaks(phases, N_AIR, 1.377, reference=0, steps=[0.1, 0.2])
    still = identify_peaks(phases, N_AIR, 1.377, reference=0, steps=np.full(6, 1e-3))
    assert not any(p.aliased for p in still.peaks)


def test_a_negative_reference_index_counts_from_the_end(evaporation):
    phases = unwrap_in_time(evaporation.values)
    from_end = identify_peaks(phases, N_AIR, 1.377, reference=-6)
    assert from_end.reference == 0
    assert [p.index for p in from_end.peaks] == list(range(6))
    assert from_end.peaks[0].kind is PeakKind.FAMILY
