"""Windows and their automatic radius; unwrapping; heights and fusion."""

from __future__ import annotations

import numpy as np
import pytest
from processing_synth import BENCH, WAVELENGTH, bench_frame, bump

from holoview.errors import InputError
from holoview.processing.fourier.resample import box_positions, resample_mask, upsample
from holoview.processing.fourier.windows import (
    DEFAULT_WINDOW,
    WINDOW_KINDS,
    area_fraction,
    auto_radii,
    auto_radius,
    radial_window,
    spacing,
)
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.maps.heights import (
    fuse,
    height_to_phase,
    phase_to_height,
    plain_average,
    rms_spread,
)
from holoview.processing.maps.unwrap import (
    aperture_mask,
    has_wraps,
    phase_ratio,
    unwrap_guided,
    unwrap_spatial,
    wrap,
)
from holoview.processing.peaks.detection import Peak


def test_window_shapes() -> None:
    rho = np.array([0.0, 0.025, 0.05, 0.075, 0.1, 0.2])
    top = radial_window("top-hat", rho, 0.1)
    cosine = radial_window("raised-cosine", rho, 0.1)
    tukey = radial_window("tukey", rho, 0.1, taper=0.5)
    np.testing.assert_allclose(top, [1, 1, 1, 1, 1, 0])
    np.testing.assert_allclose(
        cosine, [1, 0.5 * (1 + np.cos(np.pi / 4)), 0.5, 0.5 * (1 + np.cos(0.75 * np.pi)), 0, 0]
    )
    np.testing.assert_allclose(tukey, [1, 1, 1, 0.5, 0, 0], atol=1e-12)
    assert set(WINDOW_KINDS) == {"top-hat", "raised-cosine", "tukey"}
    with pytest.raises(InputError, match="unknown window"):
        radial_window("hann", rho, 0.1)
    with pytest.raises(InputError, match="taper"):
        radial_window("tukey", rho, 0.1, taper=0.0)


def test_area_fraction_of_a_disc() -> None:
    n = 512
    f = np.fft.fftfreq(n)
    rho = np.hypot(f[:, None] - 0.2, f[None, :])
    assert area_fraction(radial_window("top-hat", rho, 0.1), (n, n)) == pytest.approx(
        np.pi * 0.01, rel=0.01
    )
    # raised cosine: 2 pi r^2 int_0^1 ((1 + cos pi u) / 2)^2 u du = 0.5419 r^2
    assert area_fraction(radial_window("raised-cosine", rho, 0.1), (n, n)) == pytest.approx(
        0.5419 * 0.01, rel=0.01
    )


def test_auto_radius_from_the_nearest_peak_twin_and_zero_frequency() -> None:
    # two carriers 0.1 apart, far from zero: half the spacing
    assert auto_radius([(0.3, 0.0), (0.3, 0.1)]) == pytest.approx(0.05)
    # one carrier: half its distance to zero frequency (the zero order is a neighbour)
    assert auto_radius([(0.3, 0.0)]) == pytest.approx(0.15)
    # near Nyquist a carrier is close to its own aliased twin
    assert spacing([(0.47, 0.0)])[0] == pytest.approx(0.06)
    assert auto_radius([(0.47, 0.0)]) == pytest.approx(0.03)
    assert auto_radius([(0.3, 0.0), (0.3, 0.001)], min_radius=0.01) == 0.01
    with pytest.raises(InputError, match="zero frequency"):
        auto_radius([(0.0, 0.0)])
    with pytest.raises(InputError, match="at least one"):
        auto_radius([])


def test_auto_radii_per_peak_and_with_unselected_neighbours() -> None:
    # a tight pair and a lone carrier: the lone one is not held to the pair's spacing
    radii = auto_radii([(0.3, 0.0), (0.3, 0.04), (-0.1, 0.2)])
    np.testing.assert_allclose(radii[:2], [0.02, 0.02])
    assert radii[2] == pytest.approx(0.5 * np.hypot(0.1, 0.2))  # its zero-order bound
    assert auto_radius([(0.3, 0.0), (0.3, 0.04), (-0.1, 0.2)]) == pytest.approx(0.02)
    # a detected peak left unselected bounds the window too, and so does its twin
    assert auto_radii([(0.3, 0.0)], neighbours=[(0.3, 0.06)])[0] == pytest.approx(0.03)
    assert auto_radii([(0.3, 0.0)], neighbours=[(-0.3, 0.05)])[0] == pytest.approx(0.025)
    # the zero order counts as a neighbour: half the distance to it
    assert auto_radii([(0.06, 0.0)])[0] == pytest.approx(0.03)


def test_demodulator_windows_at_the_bound_per_peak() -> None:
    lattice = [
        Peak((0.15, 0.09), 0.1, 100.0, label="RF", alpha=1.0),
        Peak((-0.05, 0.047), 0.1, 100.0, label="FB1", alpha=1.333),
        Peak((-0.2, -0.043), 0.1, 100.0, label="RB1", alpha=0.333),
    ]
    demod = Demodulator((256, 256), lattice)
    spacing_fb1 = np.hypot(0.05, 0.047)  # the lattice's spacing: FB1 from zero and RB1 from -RF
    np.testing.assert_allclose(demod.radii, spacing_fb1 / 2, rtol=1e-9)
    assert demod.window == DEFAULT_WINDOW == "tukey"
    # one given radius serves every peak
    assert Demodulator((256, 256), lattice, radius=0.02).radii == (0.02,) * 3
    # a neighbour that is not demodulated narrows RF's window, and only RF's
    near = Demodulator((256, 256), lattice, neighbours=[(0.15, 0.13)])
    assert near.radii[0] == pytest.approx(0.02)
    assert near.radii[1:] == demod.radii[1:]
    assert near.radius == max(near.radii)
    result = near.process(bench_frame((256, 256), 0.0, rng=np.random.default_rng(3)))
    assert [r.radius for r in result.peaks] == list(near.radii)
    # a given radius reaching it is used as given, with a warning naming it
    given = Demodulator((256, 256), lattice, radius=0.05, neighbours=[(0.15, 0.13)])
    assert given.radii == (0.05,) * 3
    assert any("RF reaches the unselected peak at (0.15, 0.13)" in n for n in given.notes)
    # without a spectrum the automatic windows are at the bound, and say why
    assert {w.rule for w in demod.windows} == {"bound"}
    assert all("not measured" in w.reason for w in demod.windows)


def test_wrap_and_has_wraps() -> None:
    assert wrap(np.array([np.pi + 0.1]))[0] == pytest.approx(-np.pi + 0.1)
    ramp = np.tile(np.linspace(0, 3 * np.pi, 50), (20, 1))
    assert not has_wraps(ramp)
    assert has_wraps(wrap(ramp))
    mask = np.ones_like(ramp, bool)
    mask[:, 30:] = False
    assert not has_wraps(wrap(np.tile(np.linspace(0, 1.5 * np.pi, 50), (20, 1))), mask)


@pytest.mark.parametrize("decimate", [1, 2])
def test_spatial_unwrap_recovers_a_smooth_map(decimate: int) -> None:
    y, x = np.mgrid[:96, :128]
    truth = 12 * np.exp(-((x - 64) ** 2 + (y - 48) ** 2) / (2 * 25**2)) + 0.02 * x
    wrapped = wrap(truth).astype(np.float32)
    kept = wrapped.copy()
    result, changed = unwrap_spatial(wrapped, decimate=decimate)
    np.testing.assert_array_equal(wrapped, kept)
    offset = np.round(np.median(result - truth) / (2 * np.pi)) * 2 * np.pi
    assert changed
    np.testing.assert_allclose(result - offset, truth, atol=1e-4)
    # nothing wrapped: returned untouched, not even copied
    calm = (truth / 10).astype(np.float32)
    same, changed = unwrap_spatial(calm)
    assert same is calm and not changed


def test_spatial_unwrap_with_a_mask() -> None:
    y, x = np.mgrid[:64, :64]
    truth = 0.25 * x
    mask = np.hypot(x - 32, y - 32) < 28
    noisy = wrap(truth + np.where(mask, 0.0, np.random.default_rng(40).uniform(-3, 3, truth.shape)))
    result, changed = unwrap_spatial(noisy, mask)
    assert changed
    offset = np.round(np.median((result - truth)[mask]) / (2 * np.pi)) * 2 * np.pi
    np.testing.assert_allclose((result - offset)[mask], truth[mask], atol=1e-4)
    np.testing.assert_allclose(result[~mask], noisy[~mask], atol=1e-6)


def test_guided_unwrap_across_peaks() -> None:
    y, x = np.mgrid[:64, :80]
    shape_of_surface = np.exp(-((x - 40) ** 2 + (y - 32) ** 2) / (2 * 15**2))
    guide = 3.0 * shape_of_surface  # another peak, unwrapped, alpha ratio applied
    truth = 3.0 * shape_of_surface + 2.9  # this peak: the same shape plus its own offset
    result = unwrap_guided(wrap(truth + 4 * np.pi), guide)
    offset = np.round(np.median(result - truth) / (2 * np.pi)) * 2 * np.pi
    np.testing.assert_allclose(result - offset, truth, atol=1e-5)
    with pytest.raises(InputError, match="one shape"):
        unwrap_guided(np.zeros((3, 3)), np.zeros((4, 4)))


def test_phase_ratio_from_gradients() -> None:
    y, x = np.mgrid[:64, :80]
    surface = np.exp(-((x - 40) ** 2 + (y - 32) ** 2) / (2 * 12**2))
    guide = 6.0 * surface
    wrapped = wrap(2.5 * guide + 1.0 + np.random.default_rng(42).normal(0, 0.05, guide.shape))
    assert phase_ratio(wrapped, guide) == pytest.approx(2.5, rel=0.03)
    assert phase_ratio(wrapped, np.zeros_like(guide)) == 0.0
    mask = np.zeros(guide.shape, bool)
    mask[:, :40] = True
    assert phase_ratio(wrapped, guide, mask) == pytest.approx(2.5, rel=0.03)
    with pytest.raises(InputError, match="one shape"):
        phase_ratio(np.zeros((4, 4)), np.zeros((4, 5)))


def test_aperture_mask() -> None:
    mask = aperture_mask((50, 60), radius=10)
    assert mask.sum() == pytest.approx(np.pi * 100, rel=0.05)
    assert mask[24, 29] and not mask[0, 0]
    with pytest.raises(InputError, match="radius"):
        aperture_mask((5, 5), radius=0)


def test_phase_to_height_and_back() -> None:
    phase = np.array([0.0, 1.0, -2.0], dtype=np.float32)
    h = phase_to_height(phase, 0.333, WAVELENGTH)
    assert h.dtype == np.float32
    np.testing.assert_allclose(h, phase * WAVELENGTH / (4 * np.pi * 0.333), rtol=1e-6)
    np.testing.assert_allclose(height_to_phase(h, 0.333, WAVELENGTH), phase, rtol=1e-6)
    with pytest.raises(InputError, match="alpha"):
        phase_to_height(phase, 0.0, WAVELENGTH)
    with pytest.raises(InputError, match="wavelength"):
        phase_to_height(phase, 1.0, -1.0)


def test_fused_map_beats_the_best_single_peak_on_simulated_frames() -> None:
    shape = (256, 256)
    rng = np.random.default_rng(41)
    peaks = [Peak(c, a, 100.0, label=n, alpha=al) for n, c, a, al in BENCH]
    demod = Demodulator(shape, peaks, reference="relative", wavelength=WAVELENGTH)
    y, x = np.meshgrid(*box_positions(demod.box_shape, shape), indexing="ij")
    truth = 4e-9 * np.exp(-((y - 128) ** 2 + (x - 128) ** 2) / (2 * 40**2))
    demod.process(bench_frame(shape, 0.0, rng=rng))
    single: dict[str, list[float]] = {p.label: [] for p in peaks}
    fused_errors, average_errors, predicted = [], [], []
    for k in range(6):
        sign = 1 if k % 2 == 0 else -1
        result = demod.process(
            bench_frame(shape, bump(shape, 4e-9, 40) if k % 2 == 0 else 0.0, rng=rng)
        )
        maps = [r.delta_h for r in result.peaks]
        noises = [r.noise_height for r in result.peaks]
        fused, uncertainty = fuse(maps, noises, masks=[r.mask for r in result.peaks])
        inner = (slice(2, -2), slice(2, -2))
        for r in result.peaks:
            single[r.peak.label].append(
                float(np.sqrt(np.mean((r.delta_h - sign * truth)[inner] ** 2)))
            )
        fused_errors.append(float(np.sqrt(np.mean((fused - sign * truth)[inner] ** 2))))
        average_errors.append(
            float(np.sqrt(np.mean((plain_average(maps) - sign * truth)[inner] ** 2)))
        )
        predicted.append(float(np.nanmedian(uncertainty)))  # NaN: the untrusted border
    best = min(np.mean(v) for v in single.values())
    assert np.mean(fused_errors) < best
    assert np.mean(fused_errors) < np.mean(average_errors)
    assert np.mean(predicted) == pytest.approx(np.mean(fused_errors), rel=0.3)


def test_fuse_weights_and_masks() -> None:
    a = np.zeros((4, 4))
    b = np.ones((4, 4))
    fused, sigma = fuse([a, b], [1.0, 2.0])
    np.testing.assert_allclose(fused, 0.2)
    np.testing.assert_allclose(sigma, 1 / np.sqrt(1 + 0.25))
    mask_b = np.ones((4, 4), bool)
    fused, sigma = fuse([a, b], [1.0, 2.0], masks=[np.zeros((4, 4), bool), mask_b])
    np.testing.assert_allclose(fused, 1.0)
    fused, sigma = fuse([a, b], [1.0, 2.0], masks=[np.zeros((4, 4), bool)] * 2)
    assert np.isnan(fused).all() and np.isnan(sigma).all()
    with pytest.raises(InputError, match="noise"):
        fuse([a, b], [1.0])
    with pytest.raises(InputError, match="> 0"):
        fuse([a, b], [1.0, 0.0])
    with pytest.raises(InputError, match="one shape"):
        fuse([a, np.ones((3, 3))], [1.0, 1.0])


def test_plain_average_and_rms_spread() -> None:
    maps = [np.full((3, 3), v) for v in (1.0, 2.0, 6.0)]
    np.testing.assert_allclose(plain_average(maps), 3.0)
    np.testing.assert_allclose(rms_spread(maps), [2.0, 1.0, 3.0])


def test_upsample_is_band_limited_interpolation() -> None:
    rows, cols = 96, 120
    by, bx = 24, 30
    y, x = box_positions((by, bx), (rows, cols))
    wave = lambda yy, xx: np.cos(2 * np.pi * (3 * xx / cols + 2 * yy / rows))  # noqa: E731
    coarse = wave(y[:, None], x[None, :])
    fine = upsample(coarse, (rows, cols))
    yy, xx = np.mgrid[:rows, :cols]
    np.testing.assert_allclose(fine, wave(yy, xx), atol=1e-5)
    assert upsample(coarse.astype(np.complex64), (rows, cols)).dtype == np.complex64
    with pytest.raises(InputError, match="smaller"):
        upsample(coarse, (10, 10))
    with pytest.raises(InputError, match="NaN"):
        upsample(np.full((4, 4), np.nan), (8, 8))
    mask = np.zeros((rows, cols), bool)
    mask[:, : cols // 2] = True
    small = resample_mask(mask, (by, bx))
    assert small[:, : bx // 2].all() and not small[:, bx // 2 + 1 :].any()
