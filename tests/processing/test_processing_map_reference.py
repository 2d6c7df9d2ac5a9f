"""The demodulator's maps against a plain numpy reference, step by step (issue 23).

The demodulator transforms the frame's columns only where its boxes and the noise floor
read them, cuts each box by slices, takes the phase with a polynomial and sign bits, its
masks from ``|f|^2``, and unwraps only around the wraps. The reference here is written
plainly: numpy's full 2-D FFT in float64, the same window around the carrier, the field
evaluated exactly on the box grid (an inverse DFT at the box pixels' frame positions),
``np.angle``, the amplitude threshold, the floor's median, the noise formula. They are
compared on the optics simulator's frames and on the real holograms.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
import tifffile

from holoview.optics.families import predict_families
from holoview.optics.setup import Setup
from holoview.optics.synthesis import HologramSynthesizer
from holoview.processing.fourier.boxes import UNTRUSTED_BORDER, box_geometry, cut_box
from holoview.processing.fourier.half_spectrum import HalfSpectrum, column_runs
from holoview.processing.fourier.resample import box_positions
from holoview.processing.fourier.windows import radial_window
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.maps.phase_maps import floor_grid, floor_power, median_magnitude
from holoview.processing.peaks.detection import Peak, find_peaks

#: float32 FFTs against float64: the phase of a trusted pixel agrees this well (rad).
PHASE_TOLERANCE = 2e-4


def centred(k: np.ndarray, n: int) -> np.ndarray:
    """Integer offsets taken into [-n/2, n/2)."""
    return (k + n // 2) % n - n // 2


def reference_field(frame: np.ndarray, demod: Demodulator, i: int) -> np.ndarray:
    """Peak ``i``'s field (counts) on the box grid: full FFT, window, exact inverse DFT."""
    rows, cols = frame.shape
    fx0, fy0 = demod.peaks[i].carrier
    spectrum = np.fft.fft2(frame.astype(np.float64))
    ky = np.fft.fftfreq(rows, 1.0 / rows).round()
    kx = np.fft.fftfreq(cols, 1.0 / cols).round()
    # offsets from the carrier's bin, the way a box holds them (smallest representative)
    dy = centred(ky - round(fy0 * rows), rows)
    dx = centred(kx - round(fx0 * cols), cols)
    freq_y = dy / rows + round(fy0 * rows) / rows - fy0
    freq_x = dx / cols + round(fx0 * cols) / cols - fx0
    window = radial_window(
        demod.window, np.hypot(freq_y[:, None], freq_x[None, :]), demod.radii[i], taper=demod.taper
    )
    rows_in, cols_in = np.flatnonzero(window.any(axis=1)), np.flatnonzero(window.any(axis=0))
    windowed = (window * spectrum)[np.ix_(rows_in, cols_in)]
    y, x = box_positions(demod.box_shape, frame.shape)
    inverse_y = np.exp(2j * np.pi * np.outer(y, dy[rows_in]) / rows)
    inverse_x = np.exp(2j * np.pi * np.outer(x, dx[cols_in]) / cols)
    return inverse_y @ windowed @ inverse_x.T / (rows * cols)


def reference_mask(field: np.ndarray, demod: Demodulator, i: int, mean: float) -> np.ndarray:
    """Trusted pixels: amplitude over the threshold, away from the frame's periodic seam."""
    rows, cols = demod.shape
    y, x = box_positions(demod.box_shape, demod.shape)
    width = UNTRUSTED_BORDER / demod.radii[i]
    keep_y = np.minimum(y + 0.5, rows - 0.5 - y) >= width
    keep_x = np.minimum(x + 0.5, cols - 0.5 - x) >= width
    threshold = demod.min_amplitude * demod.peaks[i].amplitude * mean
    return (np.abs(field) >= threshold) & keep_y[:, None] & keep_x[None, :]


def reference_floor(frame: np.ndarray, before: np.ndarray | None) -> float:
    """Noise power per bin (counts^2): median of |S - S_before|^2 at the floor grid, / ln 2."""
    rows, cols = floor_grid(frame.shape)

    def samples(f: np.ndarray) -> np.ndarray:
        return np.fft.fft2(f.astype(np.float64))[rows, cols].ravel()

    d = samples(frame) - (0.0 if before is None else samples(before))
    return float(np.median(np.abs(d) ** 2) / np.log(2))


def reference_noise(
    field: np.ndarray, mask: np.ndarray, floor: float, eta: float, size: int
) -> float:
    """Phase noise per trusted pixel (rad): sqrt(eta floor / (2 size) mean(1 / |f|^2)),
    the mean over every 4th row and column's trusted pixels."""
    sample = (slice(None, None, 4), slice(None, None, 4))
    power = np.abs(field[sample][mask[sample]]) ** 2
    return float(np.sqrt(eta * floor / (2.0 * size) * np.mean(1.0 / power)))


def wrapped(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a))


def simulated_scene(shape: tuple[int, int]) -> tuple[Setup, list[Peak]]:
    """The optics simulator's bench and its four main families as peaks: the carriers and
    amplitudes found in a frame, the families' labels and alphas."""
    setup = Setup(shape=shape, depth=0.02)
    rows, cols = shape
    found = find_peaks(HologramSynthesizer(setup).render(0.0, rng=np.random.default_rng(0)))
    peaks = []
    for family in predict_families(setup, max_order=2, second_order=False):
        if family.label not in ("RB1", "RF", "FB1", "RB2"):
            continue
        fx, fy = family.observed_carrier
        for candidate in [p for q in found for p in (q, q.flipped())]:
            cx, cy = candidate.carrier
            if np.hypot((cx - fx) * cols, (cy - fy) * rows) < 1.0:
                peaks.append(candidate.relabelled(family.label, family.alpha))
                break
    assert [p.label for p in peaks] == ["RB1", "RF", "FB1", "RB2"]
    return setup, peaks


def waves(t: int, shape: tuple[int, int]) -> np.ndarray:
    """Three travelling waves of 8 nm (m) at frame ``t``."""
    y, x = np.mgrid[: shape[0], : shape[1]].astype(np.float64)
    total = np.zeros(shape)
    for k in range(3):
        ky, kx = np.random.default_rng(k).uniform(-0.02, 0.02, 2)
        total += 8e-9 * np.cos(2 * np.pi * (ky * y + kx * x) - 0.9 * t + k)
    return total


def compare_frame(
    demod: Demodulator, result: object, frame: np.ndarray, previous: np.ndarray
) -> None:
    """Every peak's map, mask, noise and mean value against the reference (relative mode)."""
    mean = float(frame.astype(np.float64).mean())
    assert result.mean_counts == pytest.approx(mean, rel=1e-6)  # type: ignore[attr-defined]
    floor = reference_floor(frame, previous)
    for i, r in enumerate(result.peaks):  # type: ignore[attr-defined]
        now = reference_field(frame, demod, i)
        before = reference_field(previous, demod, i)
        scale = np.abs(now).max()
        np.testing.assert_allclose(r.field, now, rtol=0, atol=2e-5 * scale)
        mask = reference_mask(now, demod, i, mean)
        # the threshold in |f|^2 and float32: only pixels at the threshold may differ
        at_threshold = np.isclose(
            np.abs(now), demod.min_amplitude * demod.peaks[i].amplitude * mean, rtol=1e-4
        )
        assert np.array_equal(r.mask | at_threshold, mask | at_threshold), r.peak.label
        phase = np.angle(now * np.conj(before))
        error = np.abs(wrapped(r.phase - phase))[r.mask]
        assert error.max() < PHASE_TOLERANCE, (r.peak.label, error.max())
        expected = reference_noise(now, mask, floor, demod.area_fraction(i), frame.size)
        assert r.noise == pytest.approx(expected, rel=1e-3), r.peak.label
        ramp = np.exp(2j * np.pi * np.add.outer(*_sub_bin_phases(demod, i)))
        value = np.mean(now * np.conj(ramp))
        assert r.carrier_value == pytest.approx(value, rel=1e-4, abs=1e-5 * scale)


def _sub_bin_phases(demod: Demodulator, i: int) -> tuple[np.ndarray, np.ndarray]:
    """The sub-bin plane wave's phase (cycles) along the box grid's rows and columns."""
    rows, cols = demod.shape
    fx, fy = demod.peaks[i].carrier
    y, x = box_positions(demod.box_shape, demod.shape)
    return (fy - round(fy * rows) / rows) * y, (fx - round(fx * cols) / cols) * x


@pytest.mark.parametrize("unwrap", ["auto", "never"])
def test_maps_equal_the_plain_reference_on_simulated_waves(unwrap: str) -> None:
    setup, peaks = simulated_scene((512, 512))
    synthesizer = HologramSynthesizer(setup, noise="poisson")
    rng = np.random.default_rng(230)
    frames = [synthesizer.render(waves(t, setup.shape), rng=rng) for t in range(3)]
    demod = Demodulator(setup.shape, peaks, wavelength=setup.wavelength, unwrap=unwrap)
    demod.process(frames[0])
    for previous, frame in itertools.pairwise(frames):
        result = demod.process(frame)
        compare_frame(demod, result, frame, previous)


def test_unwrapped_maps_equal_the_reference_put_on_the_truth() -> None:
    """A bump of 0.5 um wraps every map; unwrapped, each is the reference's phase plus the
    whole turns the true surface says, up to one turn for the whole map."""
    setup, peaks = simulated_scene((512, 512))
    synthesizer = HologramSynthesizer(setup, noise="poisson")
    rng = np.random.default_rng(231)
    rows, cols = setup.shape
    y, x = np.mgrid[:rows, :cols].astype(np.float64)
    bump = 0.5e-6 * np.exp(-((y - 280) ** 2 + (x - 230) ** 2) / (2 * 60.0**2))
    flat, raised = synthesizer.render(0.0, rng=rng), synthesizer.render(bump, rng=rng)
    demod = Demodulator(setup.shape, peaks, wavelength=setup.wavelength)
    demod.process(flat)
    result = demod.process(raised)
    by, bx = box_positions(demod.box_shape, setup.shape)
    truth = 0.5e-6 * np.exp(-((by[:, None] - 280) ** 2 + (bx[None, :] - 230) ** 2) / (2 * 60**2))
    for i, r in enumerate(result.peaks):
        assert r.unwrapped, r.peak.label
        phase = np.angle(
            reference_field(raised, demod, i) * np.conj(reference_field(flat, demod, i))
        )
        # the family images the surface shifted: its true phase, within a turn, is enough
        alpha = r.peak.alpha
        assert alpha is not None
        true_phase = 4 * np.pi * alpha * truth / setup.wavelength
        unwrapped = phase + 2 * np.pi * np.round((true_phase - phase) / (2 * np.pi))
        inner = r.mask.copy()
        inner[:4], inner[-4:], inner[:, :4], inner[:, -4:] = False, False, False, False
        offset = np.round(np.median((r.phase - unwrapped)[inner]) / (2 * np.pi))
        error = np.abs(r.phase - unwrapped - 2 * np.pi * offset)[inner]
        assert error.max() < PHASE_TOLERANCE, (r.peak.label, error.max())


def test_maps_equal_the_plain_reference_on_real_holograms(real_data: Path) -> None:
    """The paramecium against its background (absolute), the USAF target (synthetic)."""
    holo = tifffile.imread(real_data / "paramecium_oa_oof.tif")
    background = tifffile.imread(real_data / "paramecium_oa_oof_background.tif")
    peak = find_peaks(background)[0]
    demod = Demodulator(
        holo.shape, [peak], reference="absolute", background=background, unwrap="never"
    )
    r = demod.process(holo).peaks[0]
    now, before = reference_field(holo, demod, 0), reference_field(background, demod, 0)
    scale = np.abs(now).max()
    np.testing.assert_allclose(r.field, now, rtol=0, atol=2e-5 * scale)
    trusted = np.abs(now) > 0.05 * scale
    phase = np.angle(now * np.conj(before))
    error = np.abs(wrapped(r.phase - phase))[trusted & r.mask]
    assert error.size and error.max() < PHASE_TOLERANCE
    usaf = tifffile.imread(real_data / "usaf_oa.tif")
    peak = find_peaks(usaf)[0]
    demod = Demodulator(usaf.shape, [peak], reference="synthetic", unwrap="never")
    r = demod.process(usaf).peaks[0]
    field = reference_field(usaf, demod, 0)
    ramp = np.exp(2j * np.pi * np.add.outer(*_sub_bin_phases(demod, 0)))
    phase = np.angle(field * np.conj(ramp))
    trusted = np.abs(field) > 0.05 * np.abs(field).max()
    error = np.abs(wrapped(r.phase - phase))[trusted & r.mask]
    assert error.size and error.max() < PHASE_TOLERANCE


@pytest.mark.parametrize("shape", [(256, 256), (96, 130), (81, 63), (1024, 1280)])
def test_half_spectrum_is_the_real_fft_where_it_is_read(shape: tuple[int, int]) -> None:
    rng = np.random.default_rng(232)
    frame = rng.integers(0, 4096, shape).astype(np.uint16)
    kept = frame.copy()
    half_cols = shape[1] // 2 + 1
    columns = [np.arange(3, 40), np.arange(half_cols - 5, half_cols), np.array([0])]
    columns = [c[c < half_cols] for c in columns]
    rows_grid, cols_grid = floor_grid(shape)
    spectrum = HalfSpectrum(shape, columns, rows_grid, cols_grid)
    half, mean, floor = spectrum.transform(frame)
    expected = np.fft.rfft2(frame.astype(np.float64))
    assert half is not None
    scale = np.abs(expected).max()
    for start, stop in spectrum.runs:
        np.testing.assert_allclose(half[:, start:stop], expected[:, start:stop], atol=1e-6 * scale)
    for c in columns:
        assert all(any(a <= k < b for a, b in spectrum.runs) for k in c)
    assert mean == pytest.approx(frame.mean(), rel=1e-9)
    np.testing.assert_allclose(floor, expected[rows_grid, cols_grid].ravel(), atol=1e-6 * scale)
    floor[:] = 0  # the caller's own array: the next frame's must not be this one
    assert np.abs(spectrum.transform(frame)[2]).max() > 0
    np.testing.assert_array_equal(frame, kept)
    broken = frame.astype(np.float32)
    broken[5, 7] = np.nan
    half, mean, floor = spectrum.transform(broken)
    assert half is None and np.isnan(mean) and floor.size == 0


def test_column_runs_cover_what_is_read_in_aligned_blocks() -> None:
    assert column_runs(513, [np.array([0]), np.array([512])]) == ((0, 16), (512, 513))
    assert column_runs(513, [np.arange(30, 70), np.arange(60, 100)]) == ((16, 112),)
    assert column_runs(40, [np.arange(40)]) == ((0, 40),)
    assert column_runs(513, []) == ()


@pytest.mark.parametrize("shape", [(256, 256), (192, 256), (63, 65), (1024, 1280)])
def test_a_box_cut_by_slices_is_the_box_gathered_bin_by_bin(shape: tuple[int, int]) -> None:
    rng = np.random.default_rng(233)
    half_shape = (shape[0], shape[1] // 2 + 1)
    half = (rng.standard_normal(half_shape) + 1j * rng.standard_normal(half_shape)).astype(
        np.complex64
    )
    carriers = [(0.21, 0.13), (-0.17, 0.31), (0.015, 0.3), (0.46, -0.44), (-0.49, 0.01), (0.3, 0)]
    for carrier in carriers:
        for box in [(16, 16), (40, 24), shape]:
            geo = box_geometry(shape, box, carrier=carrier, kind="tukey", radius=0.05, taper=0.25)
            gathered = np.take(half.reshape(-1), geo.index).reshape(box)
            pairs = gathered.view(np.float32).reshape(-1)
            pairs *= geo.weights
            out = np.empty(box, np.complex64)
            np.testing.assert_array_equal(cut_box(half, geo, out), gathered)
            # the columns transformed: those where the window is not zero
            read = (geo.index % half_shape[1]).reshape(box)
            windowed = (geo.weights[0::2] != 0).reshape(box).any(axis=0)
            assert set(geo.columns) == set(read[:, windowed].ravel())


def test_floor_and_median_helpers_equal_numpy() -> None:
    rng = np.random.default_rng(234)
    for n in (1, 2, 7, 4096):
        a = (rng.standard_normal(n) + 1j * rng.standard_normal(n)).astype(np.complex64)
        b = (rng.standard_normal(n) + 1j * rng.standard_normal(n)).astype(np.complex64)
        assert floor_power(a, b) == pytest.approx(
            np.median(np.abs(a - b) ** 2) / np.log(2), rel=1e-5
        )
        assert floor_power(a) == pytest.approx(np.median(np.abs(a) ** 2) / np.log(2), rel=1e-5)
        power = rng.random((3, n)).astype(np.float32)
        kept = power.copy()
        assert median_magnitude(power) == pytest.approx(float(np.median(np.sqrt(power))), rel=1e-6)
        np.testing.assert_array_equal(power, kept)
