"""The dispersion relation with a flow, and its fit to the simulator's travelling waves."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from waves_synth import sample, travelling

from holoview.errors import InputError
from holoview.optics.surfaces import dispersion_omega
from holoview.optics.wave_fields import random_travelling_waves
from holoview.processing.waves.dispersion import (
    Fluid,
    _fit_once,
    _sharp_cells,
    fit_dispersion,
    wave_omega,
)
from holoview.processing.waves.omega_k import OmegaKAccumulator, OmegaKSpectrum
from holoview.processing.waves.ridge import Ridge

SIZE, PIXEL, FPS, FRAMES = 64, 1e-3, 250.0, 384


def spectrum_of(surface, *, frames=FRAMES, noise=0.3e-9, seed=0, segment=128):
    maps = sample(surface, np.arange(frames) / FPS, SIZE, PIXEL, noise=noise, seed=seed)
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=segment)
    acc.extend(maps, np.arange(frames) / FPS)
    return acc.spectrum()


@pytest.fixture(scope="module")
def waves():
    return travelling(seed=3)


@pytest.fixture(scope="module")
def spectrum(waves):
    return spectrum_of(waves)


def test_the_doppler_shift_is_k_dot_u():
    k = np.array([500.0, 800.0])
    plain = dispersion_omega(k, 3e-3, sigma=0.07, rho=998.0)
    shifted = wave_omega(
        k, 0 * k, surface_tension=0.07, depth=3e-3, flow=(0.02, 0.5), fluid=Fluid(998.0, 0.07)
    )
    np.testing.assert_allclose(shifted, plain + k * 0.02)
    against = wave_omega(
        -k, 0 * k, surface_tension=0.07, depth=3e-3, flow=(0.02, 0.0), fluid=Fluid(998.0, 0.07)
    )
    np.testing.assert_allclose(against, plain - k * 0.02)


def test_sigma_depth_and_flow_come_back_within_their_errors(waves, spectrum):
    fit = fit_dispersion(spectrum, Fluid(waves.rho, 0.06), depth=5e-3)
    assert fit.surface_tension == pytest.approx(waves.sigma, rel=0.03)
    assert fit.depth == pytest.approx(waves.depth, rel=0.1)
    for axis in (0, 1):
        assert fit.flow[axis] == pytest.approx(waves.flow[axis], abs=1e-3)
    # within three standard errors (which are not vanishingly small)
    assert abs(fit.surface_tension - waves.sigma) < 3 * fit.surface_tension_stderr + 1e-4
    assert abs(fit.depth - waves.depth) < 3 * fit.depth_stderr + 1e-5
    assert 0 < fit.surface_tension_stderr < 0.01 * waves.sigma
    assert fit.ridge.omega.size >= 20
    assert set(fit.free) == {"sigma", "depth", "flow_x", "flow_y"}
    assert fit.as_dict()["held"] == []


def test_the_ridge_sits_on_the_true_relation(waves, spectrum):
    fit = fit_dispersion(spectrum, Fluid(waves.rho, waves.sigma), depth=waves.depth)
    truth = wave_omega(
        fit.ridge.kx,
        fit.ridge.ky,
        surface_tension=waves.sigma,
        depth=waves.depth,
        flow=waves.flow,
        fluid=Fluid(waves.rho, waves.sigma),
    )
    assert np.median(np.abs(fit.ridge.omega / truth - 1)) < 0.01


def test_held_parameters_stay_and_have_no_error(waves, spectrum):
    fit = fit_dispersion(
        spectrum, Fluid(waves.rho, 0.06), depth=waves.depth, flow=(0.0, 0.0), hold=["depth"]
    )
    assert fit.depth == waves.depth and fit.depth_stderr == 0.0
    assert fit.surface_tension == pytest.approx(waves.sigma, rel=0.03)
    wrong = fit_dispersion(
        spectrum, Fluid(waves.rho, 0.06), hold=["flow", "depth"], depth=waves.depth
    )
    assert wrong.flow == (0.0, 0.0)
    assert wrong.rms_residual > 2 * fit.rms_residual  # a flow left out shows


def test_noise_alone_has_no_waves_to_fit():
    rng = np.random.default_rng(5)
    fine = 40e-6  # a bench's pixel: wavenumbers up to 78540 rad/m
    acc = OmegaKAccumulator((SIZE, SIZE), fine, 1 / FPS, segment=64)
    acc.extend(rng.normal(0, 1e-9, (128, SIZE, SIZE)), np.arange(128) / FPS)
    with pytest.raises(InputError, match="no waves there") as raised:
        fit_dispersion(acc.spectrum())
    assert "e+" not in str(raised.value)  # wavenumbers written out, as the axes give them


@pytest.mark.parametrize("segments", [1, 2])
def test_noise_of_few_segments_is_not_taken_for_waves(segments: int) -> None:
    """The live Waves panel's first seconds, or a surface at rest: one or two segments of
    180^2 maps of noise. Ten times the median power let 11 to 24 cells through and the
    fit said 'the sigma ran to its bound; check the fluid and the maps'; the contrast is
    now what noise seldom reaches with so few segments."""
    rng = np.random.default_rng(segments)
    frames = 16 + 16 * segments  # 32-frame segments, half overlapping
    acc = OmegaKAccumulator((180, 180), 1e-4, 1 / 30, segment=32)
    acc.extend(rng.normal(0, 1e-9, (frames, 180, 180)), np.arange(frames) / 30)
    assert acc.spectrum().segments == segments
    with pytest.raises(InputError, match="too few: the maps show no waves there") as raised:
        fit_dispersion(acc.spectrum())
    plural = "s" if segments > 1 else ""
    assert f"which noise alone seldom reaches in {segments} segment{plural})" in str(raised.value)


def test_a_cut_off_below_the_first_wavenumber_fitted_is_said() -> None:
    """A small field and a narrow window: nothing lies between four wave-vector steps and
    the cut-off, and the line says why rather than naming an empty range alone."""
    rng = np.random.default_rng(6)
    step = 2 * np.pi / (SIZE * PIXEL)  # rad/m
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=64, k_cut=3 * step)
    acc.extend(rng.normal(0, 1e-9, (128, SIZE, SIZE)), np.arange(128) / FPS)
    with pytest.raises(InputError, match="is not above the first wavenumber fitted"):
        fit_dispersion(acc.spectrum())


def test_deep_water_does_not_fix_the_depth():
    deep = travelling(seed=4, depth=0.05, k_range=(600.0, 1600.0), flow=(0.0, 0.0))
    spectrum = spectrum_of(deep, frames=256)
    with pytest.raises(InputError, match=r"the depth is not determined.*hold it") as said:
        fit_dispersion(spectrum, Fluid(deep.rho, deep.sigma), depth=0.05)
    # 600 rad/m waves feel a bottom deeper than 1/k = 1.7 mm little
    assert re.search(
        r"the longest waves fitted, 6\d\d rad/m, feel a bottom deeper than 1.[5-7] mm",
        str(said.value),
    )
    assert "blend" not in str(said.value)
    held = fit_dispersion(spectrum, Fluid(deep.rho, 0.05), depth=0.05, hold=["depth"])
    assert held.surface_tension == pytest.approx(deep.sigma, rel=0.03)


@pytest.mark.parametrize(
    ("hold", "message"), [(["mass"], "cannot hold mass"), (["sigma", "depth", "flow"], "nothing")]
)
def test_bad_holds_are_refused(spectrum, hold, message):
    with pytest.raises(InputError, match=message):
        fit_dispersion(spectrum, hold=hold)


def test_fluids_by_name():
    water = Fluid.named("water")
    assert water.density == pytest.approx(998.2) and water.surface_tension == pytest.approx(0.0728)
    assert Fluid.named("ethanol").surface_tension < 0.03
    with pytest.raises(InputError, match="unknown fluid"):
        Fluid.named("mercury")
    with pytest.raises(InputError, match="density"):
        Fluid(density=-1.0)
    assert math.isfinite(Fluid().gravity)


def _dense_spectrum(waves) -> OmegaKSpectrum:
    """512 frames of 128 x 128 truth maps of an 84 mm field at 250 frames/s."""
    size, pixel = 128, 84e-3 / 128
    x, y = (np.arange(size) * pixel)[np.newaxis], (np.arange(size) * pixel)[:, np.newaxis]
    acc = OmegaKAccumulator((size, size), pixel, 1 / FPS, segment=128)
    for t in np.arange(512) / FPS:
        acc.push(waves(t, x, y).astype(np.float32), t)
    return acc.spectrum()


@pytest.mark.parametrize("seed", [2, 4])
def test_a_dense_field_of_waves_does_not_pull_the_depth(seed: int) -> None:
    """300 waves in an 84 mm field, one to every six cells of the spectrum: the spatial
    taper blends neighbouring waves into a cell, and below 700 rad/m, where the depth is
    measured, the blend pulls the ridge up (its neighbours lie outward). Fitted on every
    cell, these seeds gave the depth 5.6 % and 6.0 % too deep (3.0 and 2.7 standard
    errors); on the cells whose line is one wave's, 0.8 % and 0.4 %."""
    rng = np.random.default_rng(seed)
    waves = random_travelling_waves(
        rng, k_range=(300.0, 1800.0), components=300, rms=10e-9, depth=3e-3,
        flow=(0.02, 0.01), sigma=0.065,
    )  # fmt: skip
    fit = fit_dispersion(_dense_spectrum(waves), Fluid(), depth=5e-3)
    assert abs(fit.depth / waves.depth - 1) < 0.03
    assert abs(fit.depth - waves.depth) < 2 * fit.depth_stderr
    assert fit.surface_tension == pytest.approx(waves.sigma, rel=0.003)
    assert np.all(fit.ridge.sharp)


def test_a_depth_left_undetermined_by_blended_long_waves_says_so() -> None:
    """Waves from 200 rad/m, one to every three cells of the spectrum, 6 mm deep: the
    lines of the longest waves blend, the sharp ones (from 475 rad/m, k d 2.9) do not
    fix the depth, and the line says why."""
    waves = random_travelling_waves(
        np.random.default_rng(1), k_range=(200.0, 1200.0), components=300, rms=10e-9,
        depth=6e-3, flow=(0.05, 0.0), sigma=0.065,
    )  # fmt: skip
    with pytest.raises(InputError, match="the depth is not determined") as said:
        fit_dispersion(_dense_spectrum(waves), Fluid(), depth=5e-3)
    assert re.search(
        r"the longest waves fitted, 4\d\d rad/m, feel a bottom deeper than 2.\d mm little; the "
        r"lines of longer ones, from 3\d\d rad/m, blend with their neighbours' and are left out",
        str(said.value),
    )


def test_broad_lines_throughout_keep_every_cell() -> None:
    """Where most cells' lines are broader than one wave's (damped waves), the fit takes
    them all rather than the few sharp ones."""
    n = 40
    ridge = Ridge(*(np.ones(n) for _ in range(4)), sharp=np.arange(n) < 10)
    assert _sharp_cells(ridge, 8).omega.size == n
    mostly = Ridge(*(np.ones(n) for _ in range(4)), sharp=np.arange(n) < 30)
    assert _sharp_cells(mostly, 8).omega.size == 30
    assert _sharp_cells(mostly, 31).omega.size == n


def test_the_errors_are_the_scatter_of_independent_cells():
    """Ridge cells are local maxima, never neighbours: their residuals are independent,
    and the errors must be the scatter's. 200 ridges of 80 cells (300-1800 rad/m, every
    direction) with 0.5 rad/s of noise on the true relation: z = (fit - truth) / stderr
    has an rms of 1 (the errors were 1.5 times too large: 0.67)."""
    fluid = Fluid()
    truth = {"sigma": 0.065, "depth": 3e-3, "flow_x": 0.02, "flow_y": -0.01}
    rng = np.random.default_rng(8)
    z = []
    for _ in range(200):
        k = rng.uniform(300.0, 1800.0, 80)
        angle = rng.uniform(0.0, 2 * np.pi, 80)
        kx, ky = k * np.cos(angle), k * np.sin(angle)
        omega = wave_omega(kx, ky, surface_tension=0.065, depth=3e-3, flow=(0.02, -0.01))
        ridge = Ridge(
            kx, ky, omega + rng.normal(0.0, 0.5, k.size), np.ones(k.size), np.ones(k.size, bool)
        )
        start = {"sigma": 0.072, "depth": 5e-3, "flow_x": 0.0, "flow_y": 0.0}
        values, covariance, _, _ = _fit_once(ridge, start, (), fluid)
        errors = np.sqrt(np.diag(covariance))  # log sigma, log depth, flow x, flow y
        fitted = [
            math.log(values["sigma"]),
            math.log(values["depth"]),
            values["flow_x"],
            values["flow_y"],
        ]
        true = [
            math.log(truth["sigma"]),
            math.log(truth["depth"]),
            truth["flow_x"],
            truth["flow_y"],
        ]
        z.append((np.array(fitted) - true) / errors)
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    assert np.all((rms > 0.85) & (rms < 1.15)), rms
