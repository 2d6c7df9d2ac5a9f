"""Windows matched to the surface: the wavy surface of issue 23, a flat one, the radius rules."""

from __future__ import annotations

import numpy as np
import pytest
from wavy_scene import (
    LABELS,
    render,
    shifts_px,
    travelling_waves,
    true_peaks,
    wavy_setup,
)

from holoview.engine.frame_core import matching_positions
from holoview.optics.synthesis import HologramSynthesizer, pixel_coordinates
from holoview.processing.fourier.resample import box_positions
from holoview.processing.fourier.windows import radial_window
from holoview.processing.maps.coregister import fuse_coregistered
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.peaks.detection import find_peaks
from holoview.processing.peaks.matched import MIN_RADIUS_BINS
from holoview.processing.peaks.radii import surface_band, window_neighbours
from holoview.processing.peaks.surface_spectrum import chi2_median, measure_spectrum

EDGE_PX = 24
FRAMES = 5


@pytest.fixture(scope="module")
def wavy():
    setup = wavy_setup()
    waves = travelling_waves(1)
    frames, heights = render(setup, waves, FRAMES + 1, seed=7)
    return setup, waves, frames, heights


def _numpy_map(frames, peak, radius, wavelength, t):
    """A plain Fourier filter: full FFT, a disk of ``radius`` at the carrier, phase vs frame 0."""
    carrier, alpha = peak.carrier, peak.alpha
    rows, cols = frames[0].shape
    fy = np.fft.fftfreq(rows)[:, None]
    fx = np.fft.fftfreq(cols)[None, :]
    dfx = (fx - carrier[0] + 0.5) % 1.0 - 0.5
    dfy = (fy - carrier[1] + 0.5) % 1.0 - 0.5
    disk = np.hypot(dfx, dfy) <= radius
    fields = [np.fft.ifft2(np.fft.fft2(frames[k].astype(np.float64)) * disk) for k in (0, t)]
    return np.angle(fields[1] * np.conj(fields[0])) * wavelength / (4 * np.pi * alpha)


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    return float(np.sum(a * b) / np.sqrt(np.sum(a * a) * np.sum(b * b)))


def test_wavy_surface_maps_keep_the_waves(wavy) -> None:
    setup, waves, frames, _ = wavy
    shape = setup.shape
    peaks = true_peaks(setup)
    detected = find_peaks(frames[0])
    demod = Demodulator(
        shape,
        peaks,
        reference="absolute",
        wavelength=setup.wavelength,
        neighbours=window_neighbours(detected),
        spectrum=measure_spectrum([frames[2], frames[4]], frames[0]),
    )
    # every window passes at least 90 % of the waves' power (power transfer W^2)
    power = waves.amplitude**2
    q = np.hypot(waves.q[:, 0], waves.q[:, 1])
    for peak, w in zip(peaks, demod.windows, strict=True):
        kept = float(np.sum(power * radial_window(w.kind, q, w.radius, taper=w.taper) ** 2))
        assert kept >= 0.9 * float(power.sum()), (peak.label, w)
        assert w.radius <= w.bound and w.radius >= MIN_RADIUS_BINS / min(shape)
    assert {w.rule for w in demod.windows[:5]} == {"matched"}
    # each map against the true change of the surface at its family's position
    shifts = shifts_px(setup)
    by, bx = box_positions(demod.box_shape, shape)
    rows, cols = shape
    inner = (np.minimum(by, rows - 1 - by) >= EDGE_PX)[:, None] & (
        np.minimum(bx, cols - 1 - bx) >= EDGE_PX
    )[None, :]
    x0, y0 = pixel_coordinates(setup)

    def truth(label: str, t: int) -> np.ndarray:
        dy, dx = shifts[label]
        x = np.interp(bx + dx, np.arange(cols), x0[0])[None, :]
        y = np.interp(by + dy, np.arange(rows), y0[:, 0])[:, None]
        return waves(t / 400.0, x, y) - waves(0.0, x, y)

    demod.process(frames[0])
    worst = {}
    for t in range(1, FRAMES + 1):
        result = demod.process(frames[t])
        errors, maps = {}, []
        for r in result.peaks:
            label = r.peak.label
            use = inner & r.mask
            assert use.sum() > 0.5 * inner.sum(), label
            true = truth(label, t)
            worst[label] = min(worst.get(label, 1.0), _correlation(r.delta_h[use], true[use]))
            err = r.delta_h[use] - true[use]
            errors[label] = float(np.sqrt(np.mean((err - err.mean()) ** 2)))
            maps.append(np.where(r.mask, r.delta_h, np.nan))
        fused = fuse_coregistered(maps, [r.error_height for r in result.peaks])
        true = truth("RB1", t)
        use = inner & np.isfinite(fused)
        err = fused[use] - true[use]
        assert float(np.sqrt(np.mean((err - err.mean()) ** 2))) <= min(errors.values()), t
    for label in LABELS:
        assert worst[label] >= 0.97, (label, worst)
    # a plain numpy Fourier filter of radius 0.05 at RB1 keeps the waves as well
    rb1 = peaks[0]
    reference = _numpy_map(frames, rb1, 0.05, setup.wavelength, 1)
    rr, cc = np.meshgrid(np.rint(by).astype(int), np.rint(bx).astype(int), indexing="ij")
    sampled = reference[rr, cc]
    assert _correlation(sampled[inner], truth("RB1", 1)[inner]) >= 0.97


def test_windows_today_shrink_on_the_sidebands_without_recognition(wavy) -> None:
    # the failure of issue 23: every detected peak a neighbour, sidebands included
    setup, _, frames, _ = wavy
    detected = find_peaks(frames[0])
    everything = [p.carrier for p in detected]
    peaks = true_peaks(setup)
    narrow = Demodulator(setup.shape, peaks, radius="bound", neighbours=everything)
    wide = Demodulator(setup.shape, peaks, radius="bound", neighbours=window_neighbours(detected))
    assert narrow.radii[0] < 0.5 * wide.radii[0]
    # a radius given by the user is not refused for a sideband (nor for anything but DC)
    given = Demodulator(setup.shape, peaks, radius=0.045, neighbours=window_neighbours(detected))
    assert given.radii == (0.045,) * len(peaks) and not given.notes


def test_a_flat_surface_falls_back_to_the_bound_with_a_note(wavy) -> None:
    setup, _, _, _ = wavy
    frames, _ = render(setup, travelling_waves(1, rms=0.0), 2, seed=5)
    peaks = true_peaks(setup)
    demod = Demodulator(
        setup.shape,
        peaks,
        neighbours=window_neighbours(find_peaks(frames[0])),
        spectrum=measure_spectrum(frames[1], frames[0]),
    )
    bound = Demodulator(setup.shape, peaks, radius="bound")
    assert demod.radii == bound.radii
    assert all(w.rule == "bound" and "no measurable change" in w.reason for w in demod.windows)
    names = [p.label for p in peaks]  # one line for the peaks with the same reason
    assert len(demod.notes) == 1, demod.notes
    assert demod.notes[0].startswith(
        ", ".join(names[:-1]) + " and " + names[-1] + ": no measurable"
    )
    assert min(demod.radii) >= 1.0 / min(setup.shape)  # never narrower than one FFT bin


def test_the_noise_floor_is_the_change_s_noise_not_the_surface_s_spread() -> None:
    # the change a wavy surface makes spreads over much of the spectrum (harmonics of
    # the phase modulation, terms between families): the median of every bin stood
    # 30 % above the noise here, which made the matched windows too narrow for FB2
    setup = wavy_setup()
    waves = travelling_waves(4)
    x, y = pixel_coordinates(setup)
    noisy = HologramSynthesizer(setup, noise="poisson")
    clean = HologramSynthesizer(setup, noise="none")
    rng = np.random.default_rng(104)
    h0, h1 = waves(0.0, x, y), waves(3 / 400.0, x, y)
    frames = [noisy.render(h, rng=rng).astype(np.float64) for h in (h0, h1)]
    spectrum = measure_spectrum(frames[1], frames[0])
    change = np.fft.rfft2(frames[1]) - np.fft.rfft2(frames[0])
    change_clean = np.fft.rfft2(clean.render(h1).astype(np.float64)) - np.fft.rfft2(
        clean.render(h0).astype(np.float64)
    )
    noise = float(np.mean(np.abs(change - change_clean) ** 2))
    assert abs(spectrum.floor / noise - 1.0) < 0.08, spectrum.floor / noise
    everywhere = float(np.median(np.abs(change[::2, 1::2]) ** 2)) / np.log(2)
    assert everywhere > 1.15 * noise  # the rule it replaces


@pytest.mark.parametrize("seed", [4, 6])
def test_the_weakest_family_s_map_holds_up_where_its_waves_near_its_noise(seed: int) -> None:
    # FB2 (amplitude 0.003, alpha 2.67: about 1 rad rms of phase at 20 nm) correlated
    # 0.967 and 0.958 with the truth on these seeds: its window was too narrow
    setup = wavy_setup()
    waves = travelling_waves(seed)
    frames, _ = render(setup, waves, 6, seed=100 + seed)
    peaks = true_peaks(setup)
    detected = find_peaks(frames[0])
    later = [frames[p] for p in matching_positions("absolute", len(frames))]
    demod = Demodulator(
        setup.shape,
        peaks,
        reference="absolute",
        wavelength=setup.wavelength,
        neighbours=window_neighbours(detected),
        spectrum=measure_spectrum(later, frames[0], band=surface_band(detected)),
    )
    fb2 = LABELS.index("FB2")
    window = demod.windows[fb2]
    # its own shape passes the waves detected (W >= 0.95 out to the band)
    assert (
        radial_window(
            window.kind, np.array([surface_band(detected)]), window.radius, taper=window.taper
        )[0]
        >= 0.95
    )
    shifts = shifts_px(setup)
    by, bx = box_positions(demod.box_shape, setup.shape)
    rows, cols = setup.shape
    inner = (np.minimum(by, rows - 1 - by) >= EDGE_PX)[:, None] & (
        np.minimum(bx, cols - 1 - bx) >= EDGE_PX
    )[None, :]
    x0, y0 = pixel_coordinates(setup)
    dy, dx = shifts["FB2"]
    x = np.interp(bx + dx, np.arange(cols), x0[0])[None, :]
    y = np.interp(by + dy, np.arange(rows), y0[:, 0])[:, None]
    demod.process(frames[0])
    for t in range(1, len(frames)):
        r = demod.process(frames[t]).peaks[fb2]
        use = inner & r.mask
        true = waves(t / 400.0, x, y) - waves(0.0, x, y)
        assert _correlation(r.delta_h[use], true[use]) >= 0.97, (t, window)


@pytest.mark.parametrize("dof", [1.0, 2.0, 3.5, 62.0, 2000.0])
def test_the_chi_square_median_is_scipys(dof: float) -> None:
    """The noise floors' median of a chi-square, against scipy.stats (imported here only)."""
    from scipy import stats

    assert chi2_median(dof) == pytest.approx(float(stats.chi2.median(dof)), rel=1e-12)
