"""Temporal and spatial PCA of peak phases: prefactor ratios, confidence, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.processing.naming.pca import phase_pca, spatial_phase_pca, temporal_phase_pca
from holoview.processing.series.phase_series import unwrap_in_time

ALPHAS = np.array([0.333, 1.0, 1.333, 1.666])


def correlated(n: int, noise: float, seed: int = 0) -> np.ndarray:
    """Phases ``alpha_m * signal + noise`` for a random signal of unit variance."""
    rng = np.random.default_rng(seed)
    signal = rng.normal(size=n)
    return signal[:, None] * ALPHAS[None, :] + rng.normal(0, noise, (n, ALPHAS.size))


def test_ratios_and_prefactors_follow_the_component():
    pca = phase_pca(correlated(4000, 0.005))
    assert np.allclose(pca.ratios(0), ALPHAS / ALPHAS[0], rtol=0.01)
    assert np.allclose(pca.prefactors(1, 1.0), ALPHAS, rtol=0.01)
    assert pca.confidence > 0.999
    assert np.all(pca.explained > 0.99)


def test_confidence_is_the_principal_eigenvalue_share():
    phases = correlated(500, 0.3, seed=3)
    eigenvalues = np.linalg.eigvalsh(np.cov(phases, rowvar=False))
    pca = phase_pca(phases)
    assert pca.confidence == pytest.approx(eigenvalues.max() / eigenvalues.sum(), rel=1e-9)
    assert np.all(np.diff(pca.eigenvalues) <= 0)


def test_an_uncorrelated_peak_lowers_confidence_and_is_not_explained():
    rng = np.random.default_rng(1)
    clean = correlated(2000, 0.01)
    stray = np.column_stack([clean, rng.normal(0, 0.5, 2000)])
    with_stray = phase_pca(stray)
    assert with_stray.confidence < phase_pca(clean).confidence - 0.03
    assert with_stray.explained[-1] < 0.05
    assert np.all(with_stray.explained[:-1] > 0.95)


def test_relative_sign_comes_from_the_component_global_sign_from_the_label():
    phases = correlated(2000, 0.01)
    phases[:, 2] *= -1  # this peak sits on the other twin
    alphas = phase_pca(phases).prefactors(0, 0.333)
    assert alphas[2] == pytest.approx(-1.333, rel=0.01)
    assert np.all(alphas[[0, 1, 3]] > 0)
    # Labelling a peak with a negative component entry still gives it the given alpha.
    assert phase_pca(phases).prefactors(2, 1.333)[0] == pytest.approx(-0.333, rel=0.01)


def test_temporal_pca_of_wrapped_values_unwrapped_in_time():
    times = np.arange(600) / 10
    ramp = 0.8 * times  # rad for alpha = 1: the phases wrap many times
    rng = np.random.default_rng(2)
    phases = ramp[:, None] * ALPHAS + rng.normal(0, 0.01, (600, 4))
    values = np.exp(1j * phases) * 3.0
    pca = temporal_phase_pca(unwrap_in_time(values))
    assert np.allclose(pca.prefactors(0, 0.333), ALPHAS, rtol=0.005)


def test_spatial_pca_on_maps_with_a_mask():
    rng = np.random.default_rng(4)
    surface = rng.normal(size=(64, 64))
    maps = ALPHAS[:, None, None] * surface + rng.normal(0, 0.01, (4, 64, 64))
    mask = np.ones((64, 64), dtype=bool)
    mask[:8] = False
    maps[0, :8] = np.nan  # not covered by peak 0, masked out anyway
    pca = spatial_phase_pca(maps, mask)
    assert pca.n_samples == 56 * 64
    assert np.allclose(pca.ratios(3), ALPHAS / ALPHAS[3], rtol=0.01)


def test_rows_with_nan_are_left_out_and_input_is_not_mutated():
    phases = correlated(300, 0.01)
    phases[:50, 1] = np.nan
    before = phases.copy()
    pca = phase_pca(phases)
    assert pca.n_samples == 250
    np.testing.assert_array_equal(phases, before)


@pytest.mark.parametrize(
    ("phases", "message"),
    [
        (np.zeros((10, 1)), "at least two peaks"),
        (np.zeros((1, 3)), "at least two frames"),
        (np.zeros(10), "2-D"),
        (np.array([[np.nan, 1.0], [2.0, np.nan], [np.nan, 3.0]]), "no common frames"),
        (np.array([[1.0, 1.0], [np.nan, 2.0], [np.nan, 3.0]]), "share only 1"),
        (np.ones((10, 3)), "do not vary"),
    ],
)
def test_bad_input_is_a_clear_error(phases, message):
    with pytest.raises(InputError, match=message):
        phase_pca(phases)


def test_a_reference_peak_that_does_not_move_cannot_fix_the_others():
    phases = correlated(500, 0.0)
    phases[:, 3] = 0.0
    pca = phase_pca(phases)
    with pytest.raises(InputError, match="uncorrelated"):
        pca.prefactors(3, 1.0)
    with pytest.raises(InputError, match="not one of the 4"):
        pca.ratios(4)


def test_spatial_pca_rejects_a_mask_of_the_wrong_shape():
    with pytest.raises(InputError, match="mask shape"):
        spatial_phase_pca(np.zeros((2, 8, 8)), np.ones((4, 4), dtype=bool))
