"""The demodulator's maps on the frame's pixels (``grid="frame"``, issue 23).

A frame-grid field is the inverse FFT of the windowed sideband in a frame-sized array.
Checked against a plain numpy Fourier filter written here and against the box field
brought to the frame by Fourier zero-padding (band-limited: the two must agree
everywhere, to float32 rounding).
"""

from __future__ import annotations

import numpy as np
import pytest
from processing_synth import BENCH, WAVELENGTH, bench_frame, bump

from holoview.errors import InputError
from holoview.processing.fourier.boxes import UNTRUSTED_BORDER
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.peaks.detection import Peak

SHAPE = (128, 160)
RADIUS = 0.05


def _peaks() -> list[Peak]:
    return [Peak(c, a, 100.0, label=n, alpha=al) for n, c, a, al in BENCH]


def _fourier_filter(frame: np.ndarray, carrier: tuple[float, float], radius: float) -> np.ndarray:
    """A top-hat disc at ``carrier`` (fx, fy), moved to zero frequency, inverted at full size."""
    rows, cols = frame.shape
    spectrum = np.fft.fft2(frame.astype(np.float64))
    fy = np.fft.fftfreq(rows)[:, None]
    fx = np.fft.fftfreq(cols)[None, :]
    disc = np.hypot(fx - carrier[0], fy - carrier[1]) <= radius
    k0y, k0x = round(carrier[1] * rows), round(carrier[0] * cols)
    return np.fft.ifft2(np.roll(spectrum * disc, (-k0y, -k0x), axis=(0, 1)))


def _frames() -> list[np.ndarray]:
    rng = np.random.default_rng(4)
    return [
        bench_frame(SHAPE, h, rng=rng) for h in (0.0, bump(SHAPE, 30e-9, 12), bump(SHAPE, 60e-9, 9))
    ]


def test_frame_grid_maps_are_a_plain_fourier_filters() -> None:
    peaks = _peaks()
    frames = _frames()
    demod = Demodulator(
        SHAPE,
        peaks,
        window="top-hat",
        radius=RADIUS,
        reference="absolute",
        wavelength=WAVELENGTH,
        grid="frame",
    )
    assert demod.box_shape == SHAPE
    results = [demod.process(f) for f in frames]
    for i, peak in enumerate(peaks):
        reference = _fourier_filter(frames[0], peak.carrier, RADIUS)
        for frame, result in zip(frames[1:], results[1:], strict=True):
            r = result.peaks[i]
            assert r.phase.shape == SHAPE and r.delta_h is not None
            field = _fourier_filter(frame, peak.carrier, RADIUS)
            # the field itself, in counts (the demodulator's is at the carrier's nearest bin)
            scale = np.abs(field).max()
            assert np.abs(r.field - field).max() < 1e-4 * scale, peak.label
            phase = np.angle(field * np.conj(reference))
            to_height = WAVELENGTH / (4 * np.pi * peak.alpha)
            wrapped = np.angle(np.exp(1j * (r.phase - phase)))
            assert np.abs(wrapped[r.mask]).max() < 1e-3, peak.label
            np.testing.assert_allclose(r.delta_h, r.phase * to_height, rtol=1e-6)
            # untrusted: the seam of the periodic FFT, UNTRUSTED_BORDER / radius wide
            width = int(np.ceil(UNTRUSTED_BORDER / RADIUS - 0.5))
            assert not r.mask[:width].any() and not r.mask[:, -width:].any()
            assert r.mask[width + 2 : -width - 2, width + 2 : -width - 2].mean() > 0.9


def test_box_fields_brought_to_the_frame_are_the_frame_grids() -> None:
    peaks = _peaks()
    frames = _frames()
    box = Demodulator(SHAPE, peaks, reference="relative", wavelength=WAVELENGTH)
    grid = box.with_peaks(peaks, grid="frame")
    assert grid.grid == "frame" and grid.box_shape == SHAPE and box.box_shape < SHAPE
    assert grid.with_peaks(peaks).grid == "frame"
    for frame in frames:
        coarse, fine = box.process(frame), grid.process(frame)
        for i in range(len(peaks)):
            upsampled = box.upsample(coarse.peaks[i].field)
            scale = np.abs(upsampled).max()
            assert np.abs(upsampled - fine.peaks[i].field).max() < 1e-5 * scale
            # the noise per pixel: the same (averaged over other pixels); the same flags
            assert fine.peaks[i].noise == pytest.approx(coarse.peaks[i].noise, rel=0.25)
            assert fine.peaks[i].flags == coarse.peaks[i].flags


def test_an_unknown_grid_is_refused() -> None:
    with pytest.raises(InputError, match="unknown map grid 'pixels'; choose one of box, frame"):
        Demodulator(SHAPE, _peaks(), grid="pixels")
