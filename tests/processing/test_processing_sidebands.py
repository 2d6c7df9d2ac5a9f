"""The surface's own spectrum: sidebands around the carriers are not peaks (issue 23)."""

from __future__ import annotations

import numpy as np
import pytest
from wavy_scene import LABELS, render, travelling_waves, true_peaks, wavy_setup

from holoview.processing.fourier.windows import wrap_frequency
from holoview.processing.peaks.detection import find_peaks
from holoview.processing.peaks.sidebands import surface_sidebands


def _bins(delta: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    d = wrap_frequency(np.asarray(delta))
    return np.hypot(d[..., 0] * shape[1], d[..., 1] * shape[0])


def _nearest(peaks, carrier, shape):
    """The detected peak on ``carrier`` (either twin) and its distance, bins."""
    c = np.asarray(carrier)
    distance = [
        min(_bins(np.subtract(p.carrier, c), shape), _bins(np.add(p.carrier, c), shape))
        for p in peaks
    ]
    j = int(np.argmin(distance))
    return peaks[j], float(distance[j])


def test_wave_sidebands_are_recognised_and_carriers_are_not() -> None:
    setup = wavy_setup()
    waves = travelling_waves(1)
    frames, _ = render(setup, waves, 1, seed=3)
    peaks = find_peaks(frames[0])
    shape = setup.shape
    truth = true_peaks(setup)
    families = {}
    for p in truth:
        found, distance = _nearest(peaks, p.carrier, shape)
        assert distance < 1.0, (p.label, distance)
        assert "surface" not in found.flags and found.sideband_of is None, (p.label, found)
        assert "overlap" not in found.flags, (p.label, found.flags)
        families[p.label] = found
    sidebands = [p for p in peaks if "surface" in p.flags]
    # the strongest waves show around RB1, RF and RB2, brighter than FB1's own peak
    assert len(sidebands) >= 8
    assert max(p.amplitude for p in sidebands) > families["FB1"].amplitude
    q_true = waves.q
    rb1 = np.asarray(truth[LABELS.index("RB1")].carrier)
    around_rb1 = 0
    for p in sidebands:
        parent = np.asarray(p.sideband_of)
        # the parent is a true carrier (on either twin), the offset a wave's +-q
        assert (
            min(
                min(
                    _bins(parent - np.asarray(t.carrier), shape),
                    _bins(parent + np.asarray(t.carrier), shape),
                )
                for t in truth
            )
            < 1.0
        )
        # the offset is a wave's +-q, or (second order) a sum or difference of two,
        # or lies within the surface's band (the strongly modulated weak carriers)
        q = np.asarray(p.surface_offset)
        sums = [a + s * b for a in q_true for b in q_true for s in (1, -1)]
        off = [min(_bins(q - w, shape), _bins(q + w, shape)) for w in (*q_true, *sums)]
        band = 2 * max(_bins(w, shape) for w in q_true) + 1.5
        assert min(off) < 1.5 or _bins(q, shape) <= band, (p, off)
        around_rb1 += min(_bins(parent - rb1, shape), _bins(parent + rb1, shape)) < 1.0
    assert around_rb1 >= 4


def test_a_flat_surface_has_no_sidebands() -> None:
    setup = wavy_setup()
    frames, _ = render(setup, travelling_waves(1, rms=0.0), 1, seed=3)
    peaks = find_peaks(frames[0])
    assert peaks and not any("surface" in p.flags for p in peaks)


def test_a_lattice_line_is_not_a_sideband_pair() -> None:
    # -RF, RB1, RB2 lie on a line spaced f_FB1, the ends weaker than RB1 and alike:
    # the pattern of a sideband pair, a whole lattice vector wide
    shape = (512, 512)
    rb1, rf, rb2, rb3 = (-0.2206, -0.0201), (0.1504, 0.0903), (-0.2907, 0.0501), (-0.3609, 0.1202)
    fb1 = (-0.0702, 0.0702)
    with_fb1 = np.array([rb1, rf, rb2, fb1, rb3])
    amplitudes = np.array([0.49, 0.075, 0.06, 0.01, 0.0068])
    assert surface_sidebands(with_fb1, amplitudes, shape) == [None] * 5
    # a lossless mirror: FB1 cancels, only the span rule tells the line from a pair
    without = np.array([rb1, rf, rb2, rb3])
    assert surface_sidebands(without, amplitudes[[0, 1, 2, 4]], shape) == [None] * 4


def test_a_pair_around_one_carrier_is_a_sideband_pair() -> None:
    shape = (256, 256)
    carrier = np.array([0.2, 0.1])
    q = np.array([6.0, -3.0]) / 256
    points = np.array([carrier, (0.05, -0.3), carrier + q, carrier - q])
    found = surface_sidebands(points, np.array([0.3, 0.1, 0.01, 0.012]), shape)
    assert found[0] is None and found[1] is None
    assert found[2] is not None and found[2].parent == 0 and found[2].sign == 1
    assert found[2].offset == pytest.approx(tuple(q), abs=1e-9)
    assert found[3] is not None and found[3].offset == pytest.approx(tuple(-q), abs=1e-9)
    # too bright against the carrier: a peak of its own
    bright = surface_sidebands(points, np.array([0.3, 0.1, 0.2, 0.2]), shape)
    assert bright == [None] * 4


def test_sidebands_bound_no_window_unless_the_lattice_places_them() -> None:
    from holoview.processing.peaks.detection import Peak
    from holoview.processing.peaks.radii import window_neighbours

    carrier = Peak((0.2, 0.1), 0.3, 100.0)
    sideband = Peak((0.22, 0.1), 0.01, 20.0, frozenset({"surface"}), sideband_of=(0.2, 0.1))
    other = Peak((0.05, -0.3), 0.1, 50.0)
    assert sideband.surface_offset == pytest.approx((0.02, 0.0))
    assert sideband.flipped().surface_offset == pytest.approx((-0.02, 0.0))
    assert window_neighbours([carrier, sideband, other]) == [carrier.carrier, other.carrier]
    placed = window_neighbours([carrier, sideband, other], [True, True, False])
    assert placed == [carrier.carrier, sideband.carrier, other.carrier]
