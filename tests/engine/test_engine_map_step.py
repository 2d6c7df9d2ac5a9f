"""The maps step and the joint setup: the one rule for which maps are fused, and with what."""

from __future__ import annotations

import numpy as np
import pytest

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FrameCore
from holoview.engine.map_step import Coregistration, MapStep, frame_shift, fuse_maps, pixel_step
from holoview.engine.series import JointSetup
from holoview.optics.families import alpha_of
from holoview.processing.maps.coregister import Displacement
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.matched import Window

N1, N2 = 1.0, 1.333


def test_the_fused_peaks_are_the_joint_estimate_s_else_every_peak_with_alpha() -> None:
    labels = ["RB1", "RF", "G1", "FB1", "P4"]
    alphas = [alpha_of("RB1", N1, N2), alpha_of("RF", N1, N2), 0.7, alpha_of("FB1", N1, N2), None]
    joint = JointSetup.of(labels, alphas, wavelength_m=532e-9, n1=N1, n2=N2)
    assert joint.couplings == (-1, 1, None, 0, None)
    assert joint.columns == (0, 1, 3)
    assert joint.fused() == (True, True, False, True, False)  # G1 has no place on the lattice
    left_out = JointSetup.of(
        labels,
        alphas,
        wavelength_m=532e-9,
        n1=N1,
        n2=N2,
        exclude=[False, True, False, False, False],
    )
    assert left_out.fused() == (True, False, False, True, False)
    custom = JointSetup.of(["G1", "G2", "G3"], [0.5, None, 0.9], wavelength_m=532e-9, n1=N1, n2=N2)
    assert custom.columns == () and custom.fused() == (True, False, True)
    assert JointSetup.of(labels, alphas, wavelength_m=None, n1=N1, n2=N2).columns == ()


def test_shifts_in_camera_pixels() -> None:
    step = pixel_step((1024, 512), (256, 64))
    assert step == (4.0, 8.0)
    d = Displacement((0.5, -0.25), (0.01, 0.01), True, 30)
    assert frame_shift(d, (1024, 512), (256, 64)) == (2.0, -2.0)


def _frames(shape: tuple[int, int], peaks: list[Peak], phases: list[list[float]]) -> list:
    """Noise-free fringes of each peak's carrier at the given uniform phases."""
    y, x = np.mgrid[: shape[0], : shape[1]]
    out = []
    for frame_phases in phases:
        image = np.full(shape, 1000.0)
        for p, phi in zip(peaks, frame_phases, strict=True):
            fx, fy = p.carrier
            image += 200 * np.cos(2 * np.pi * (fx * x + fy * y) + phi)
        out.append(image)
    return out


def test_a_peak_whose_mean_phase_stepped_is_left_out_of_the_fused_map() -> None:
    """RB1's mean phase steps by 2.6 rad (past 0.8 pi) at the third frame: that frame's fused
    map is RF's and FB1's alone; RF's steps at the fourth, whose map is RB1's and FB1's."""
    shape = (128, 128)
    experiment = Experiment(n1=N1, n2=N2, wavelength_m=532e-9, reference="relative")
    peaks = [
        Peak((0.2, 0.1), 0.2, 100.0, label="RB1", alpha=alpha_of("RB1", N1, N2)),
        Peak((0.05, 0.3), 0.2, 100.0, label="RF", alpha=alpha_of("RF", N1, N2)),
        Peak((-0.25, 0.2), 0.2, 100.0, label="FB1", alpha=alpha_of("FB1", N1, N2)),
    ]
    steps = [[0.0, 0.0, 0.0], [0.1, 0.1, 0.1], [2.7, 0.2, 0.2], [2.8, 2.9, 0.3]]
    step = MapStep(FrameCore(shape, experiment, peaks))
    made = [step.process(f) for f in _frames(shape, peaks, steps)]
    stepped = [["phase_step" in flags for flags in m.peak_flags] for m in made]
    assert stepped == [[False] * 3, [False] * 3, [True, False, False], [False, True, False]]
    for k, left_out in ((2, 0), (3, 1)):
        result = made[k].result
        assert result is not None
        noise = [r.noise_height for r in result.peaks]
        chosen = [None if j == left_out else m for j, m in enumerate(made[k].maps)]
        expected = fuse_maps(chosen, noise, [False] * 3)
        assert expected is not None
        np.testing.assert_array_equal(made[k].fused, expected)


def test_the_fused_map_weighs_each_map_by_its_expected_error() -> None:
    """A window that cuts 0.5 rad of the surface's change weighs its map down in the fused
    map (noise and cut in quadrature, PeakResult.error_height), not by its noise alone."""
    shape = (128, 128)
    experiment = Experiment(n1=N1, n2=N2, wavelength_m=532e-9, reference="relative")
    peaks = [
        Peak((0.2, 0.1), 0.2, 100.0, label="RB1", alpha=alpha_of("RB1", N1, N2)),
        Peak((0.05, 0.3), 0.2, 100.0, label="RF", alpha=alpha_of("RF", N1, N2)),
        Peak((-0.25, 0.2), 0.2, 100.0, label="FB1", alpha=alpha_of("FB1", N1, N2)),
    ]
    windows = [Window(0.05, "tukey", 0.25, "matched", 0.07, "test", 0.05, c) for c in (0.5, 0, 0)]
    step = MapStep(FrameCore(shape, experiment, peaks, windows=windows))
    rng = np.random.default_rng(3)
    frames = _frames(shape, peaks, [[0.0, 0.0, 0.0], [0.1, 0.2, 0.3]])
    made = [step.process(f + rng.normal(0.0, 20.0, shape)) for f in frames]
    demod = step.core.demodulator
    assert demod is not None and demod.windows == tuple(windows)
    result = made[1].result
    assert result is not None
    noise = [r.noise_height for r in result.peaks]
    errors = [r.error_height for r in result.peaks]
    scale = 532e-9 / (4 * np.pi * abs(peaks[0].alpha))  # m per rad of RB1's map
    assert errors[0] == pytest.approx(np.hypot(noise[0], 0.5 * scale), rel=1e-6)
    assert errors[1:] == pytest.approx(noise[1:], rel=1e-9)
    expected = fuse_maps(made[1].maps, errors, [False] * 3)
    assert expected is not None and made[1].fused is not None
    np.testing.assert_array_equal(made[1].fused, expected)
    by_noise = fuse_maps(made[1].maps, noise, [False] * 3)
    assert by_noise is not None and not np.array_equal(made[1].fused, by_noise)


def test_fixed_displacements_are_not_measured_again() -> None:
    fixed = [
        Displacement((0.0, 0.0), (0.0, 0.0), True, 0),
        Displacement((0.3, 0.1), (0.01,) * 2, True, 9),
    ]
    coregistration = Coregistration((["RB1", "RF"], (64, 64), fixed))
    rng = np.random.default_rng(0)
    coregistration.add_maps(["RB1", "RF"], (64, 64), [rng.normal(size=(64, 64))] * 2)
    assert coregistration.displacements(["RB1", "RF"], (64, 64)) == fixed
    assert coregistration.displacements(["RB1", "FB1"], (64, 64)) is None  # other peaks
    assert Coregistration(None).displacements() is None


@pytest.mark.parametrize("damaged", [True, False])
def test_a_damaged_frame_makes_no_maps(damaged: bool) -> None:
    shape = (64, 64)
    peaks = [Peak((0.2, 0.1), 0.2, 100.0, label="RB1", alpha=alpha_of("RB1", N1, N2))]
    step = MapStep(FrameCore(shape, Experiment(n1=N1, n2=N2), peaks))
    made = step.process(_frames(shape, peaks, [[0.0]])[0], damaged=damaged)
    assert made.demodulated is not damaged
    assert bool(made.maps) is not damaged and made.fused is None  # one peak: nothing fused
