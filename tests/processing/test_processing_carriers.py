"""Carriers of broadened peaks, and phases against a background hologram, on real data.

The real holograms (``../shared/data/real``, PyHoloscope's, MIT licence) are a
paramecium out of focus and the same setup without it; their phase difference is
compared with a plain implementation written here (numpy's FFT, the same window).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import tifffile

from holoview.errors import InputError
from holoview.processing.fourier.windows import radial_window
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.maps.unwrap import unwrap_spatial
from holoview.processing.peaks.detection import Peak, find_peaks, refine_carriers


def cells_hologram(
    shape: tuple[int, int], carrier: np.ndarray, rng: np.random.Generator, *, cells: bool
) -> np.ndarray:
    """A fringe pattern at ``carrier`` on a slightly curved reference, cells optional."""
    rows, cols = shape
    y, x = np.mgrid[:rows, :cols].astype(np.float64)
    phase = np.zeros(shape)
    amplitude = np.ones(shape)
    if cells:  # phase objects of 1-4 rad, 15-60 pixels, absorbing up to 30 %
        for _ in range(rng.integers(5, 20)):
            cy, cx = rng.uniform(0, rows), rng.uniform(0, cols)
            sigma = rng.uniform(15, 60) * rows / 1024
            bump = np.exp(-((y - cy) ** 2 + (x - cx) ** 2) / (2 * sigma**2))
            phase += rng.uniform(1, 4) * bump
            amplitude *= 1 - 0.3 * bump
    curvature = 2e-5 * (1024 / rows) ** 2 * ((x - cols / 2) ** 2 + (y - rows / 2) ** 2)
    fringes = 2 * np.pi * (carrier[0] * x + carrier[1] * y) + curvature - phase
    return rng.poisson(500 * (1 + 0.25 * amplitude**2 + amplitude * np.cos(fringes)))


def test_a_broadened_peak_keeps_its_carrier_and_reports_its_uncertainty() -> None:
    shape = (512, 512)
    plain, refined, apart = [], [], []
    for seed in range(4):
        rng = np.random.default_rng(seed)
        carrier = np.array([rng.uniform(0.2, 0.35), rng.uniform(-0.3, -0.15)])
        holo = cells_hologram(shape, carrier, rng, cells=True)
        background = cells_hologram(shape, carrier, rng, cells=False)
        first = find_peaks(holo, refine=False)[0]
        best = find_peaks(holo)[0]
        empty = find_peaks(background)[0]
        assert best.carrier_error is not None and 0 < best.carrier_error < 0.5
        plain.append(np.hypot(*((np.array(first.carrier) - carrier) * shape[::-1])))
        refined.append(np.hypot(*((np.array(best.carrier) - carrier) * shape[::-1])))
        apart.append(np.hypot(*((np.subtract(best.carrier, empty.carrier)) * shape[::-1])))
    assert max(refined) < 0.3 and max(apart) < 0.3  # bins
    assert np.mean(refined) < np.mean(plain)


def plane_tilt_bins(phase: np.ndarray, frame_shape: tuple[int, int]) -> tuple[float, float]:
    """The least-squares plane's slope of a box-resolution map, FFT bins (x, y)."""
    by, bx = phase.shape
    rows, cols = frame_shape
    y, x = np.mgrid[:by, :bx].astype(np.float64)
    inner = (slice(3, -3), slice(3, -3))
    design = np.c_[np.ones(phase[inner].size), x[inner].ravel() * cols / bx]
    design = np.c_[design, y[inner].ravel() * rows / by]
    coef, *_ = np.linalg.lstsq(design, phase[inner].ravel(), rcond=None)
    return coef[1] * cols / (2 * np.pi), coef[2] * rows / (2 * np.pi)


def test_real_carriers_differ_by_the_tilt_the_sample_adds(real_data: Path) -> None:
    """The paramecium's hologram and its background do not share one carrier.

    Demodulated alike, their phase difference holds a plane of (-3.2, -2.2) bins: the
    sample tilts the object wave. So the carriers must differ by that plane, not agree
    within 0.3 bins; find_peaks' maxima were 1.1 bins off it.
    """
    holo = tifffile.imread(real_data / "paramecium_oa_oof.tif")
    background = tifffile.imread(real_data / "paramecium_oa_oof_background.tif")
    peak, empty = find_peaks(holo)[0], find_peaks(background)[0]
    for p in (peak, empty):
        assert p.carrier_error is not None and p.carrier_error < 0.3
    demod = Demodulator(holo.shape, [empty], reference="absolute", background=background)
    phase, _ = unwrap_spatial(demod.process(holo).peaks[0].phase)
    tilt = plane_tilt_bins(phase, holo.shape)
    moved = np.subtract(peak.carrier, empty.carrier) * holo.shape[::-1]
    assert moved == pytest.approx(tilt, abs=0.3)
    assert abs(tilt[0]) > 2  # a real tilt, not noise


def reference_phase(
    holo: np.ndarray, background: np.ndarray, carrier: tuple[float, float], radius: float
) -> np.ndarray:
    """A plain implementation: full numpy FFTs, the same Tukey window, the phase difference."""
    rows, cols = holo.shape
    fy = np.fft.fftfreq(rows)[:, None]
    fx = np.fft.fftfreq(cols)[None, :]
    delta_x = (fx - carrier[0] + 0.5) % 1.0 - 0.5
    delta_y = (fy - carrier[1] + 0.5) % 1.0 - 0.5
    window = radial_window("tukey", np.hypot(delta_x, delta_y), radius, taper=0.25)
    fields = [np.fft.ifft2(np.fft.fft2(f.astype(np.float64)) * window) for f in (holo, background)]
    return np.angle(fields[0] * np.conj(fields[1]))


def test_phase_against_a_background_hologram_equals_a_plain_implementation(
    real_data: Path,
) -> None:
    holo = tifffile.imread(real_data / "paramecium_oa_oof.tif")
    background = tifffile.imread(real_data / "paramecium_oa_oof_background.tif")
    peak = find_peaks(background)[0]
    demod = Demodulator(
        holo.shape, [peak], window="tukey", taper=0.25, reference="absolute", background=background
    )
    first = demod.process(holo)
    assert "reference" not in first.flags  # the background is the reference, not frame 0
    r = first.peaks[0]
    reference = demod.reference_field(0)
    assert reference is not None
    ours = np.angle(demod.upsample(r.field) * np.conj(demod.upsample(reference)))
    theirs = reference_phase(holo, background, peak.carrier, r.radius)
    inner = (slice(2, -2), slice(2, -2))
    difference = np.angle(np.exp(1j * (ours - theirs)))[inner]
    assert np.sqrt(np.mean(difference**2)) < 0.03  # rad
    # the map itself is that phase, on the box grid
    by, bx = demod.box_shape
    step_y, step_x = holo.shape[0] // by, holo.shape[1] // bx
    if holo.shape == (by * step_y, bx * step_x):
        sampled = theirs[::step_y, ::step_x]
        assert np.angle(np.exp(1j * (r.phase - sampled)))[2:-2, 2:-2].std() < 0.03
    # and the next frame is still against the background, not against the first frame
    again = demod.process(holo).peaks[0]
    np.testing.assert_allclose(again.phase, r.phase, atol=1e-5)
    assert again.mean_phase == pytest.approx(r.mean_phase, abs=1e-6)


def test_background_hologram_bad_input() -> None:
    p = Peak((0.2, 0.1), 0.1, 10.0)
    with pytest.raises(InputError, match="absolute"):
        Demodulator((64, 64), [p], reference="relative", background=np.ones((64, 64)))
    with pytest.raises(InputError, match="background hologram has shape"):
        Demodulator((64, 64), [p], reference="absolute", background=np.ones((32, 64)))
    with pytest.raises(InputError, match="NaN"):
        Demodulator((64, 64), [p], reference="absolute", background=np.full((64, 64), np.nan))
    demod = Demodulator((64, 64), [p], reference="absolute", background=np.ones((64, 64)))
    assert demod.reference_field(0) is not None
    demod.set_background(None)  # back to the first frame as the reference
    assert demod.background is None and demod.reference_field(0) is None
    assert refine_carriers(np.random.default_rng(2).random((64, 64)), []) == []
