"""The omega-k spectrum: where a wave lands, Parseval, gaps, masks, E(k) and E(omega)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from waves_synth import grid

from holoview.errors import InputError
from holoview.processing.waves.omega_k import SIGN_CONVENTION, OmegaKAccumulator

SIZE, PIXEL, FPS = 32, 1e-3, 100.0


def plane_wave(frames: int, kx: float, ky: float, omega: float, amplitude: float = 1e-8):
    x, y = grid(SIZE, PIXEL)
    t = np.arange(frames)[:, None, None] / FPS
    return amplitude * np.cos(kx * x + ky * y - omega * t)


def push_all(acc, maps, times=None):
    times = np.arange(len(maps)) / FPS if times is None else times
    for frame, t in zip(maps, times, strict=True):
        acc.push(frame, t)


def test_a_wave_travelling_along_plus_k_lands_at_plus_k_and_its_frequency():
    dk = 2 * np.pi / (SIZE * PIXEL)
    kx, ky, omega = 5 * dk, -3 * dk, 2 * np.pi * 12.5  # 12.5 Hz: bin 16 of 128 at 100 fps
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=128)
    push_all(acc, plane_wave(256, kx, ky, omega))
    spectrum = acc.spectrum()
    assert spectrum.segments == 3
    f, iy, ix = np.unravel_index(np.argmax(spectrum.power), spectrum.power.shape)
    assert spectrum.frequency[f] == pytest.approx(12.5)
    assert spectrum.kx[ix] == pytest.approx(kx)
    assert spectrum.ky[iy] == pytest.approx(ky)
    # the opposite direction holds almost nothing (the taper's leakage only)
    mirror = spectrum.power[f, SIZE - iy, SIZE - ix]
    assert mirror < 1e-6 * spectrum.power[f, iy, ix]
    assert "travels along +k" in SIGN_CONVENTION


def test_the_spectrum_sums_to_the_mean_square_height():
    rng = np.random.default_rng(2)
    maps = rng.normal(0, 3e-9, (256, SIZE, SIZE))
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=64)
    push_all(acc, maps)
    s = acc.spectrum()
    dky, dkx = s.dk
    total = float(s.power.sum(dtype=np.float64)) * s.df * dky * dkx
    assert total == pytest.approx(9e-18, rel=0.05)
    # E(k) over 0..Nyquist (inside the circle) and E(omega) agree with each other
    k, e_k = s.energy_k()
    omega, e_omega = s.energy_omega()
    assert np.sum(e_k) * (k[1] - k[0]) == pytest.approx(
        np.sum(e_omega) * (omega[1] - omega[0]), rel=1e-6
    )
    inside = np.pi / 4  # the disc's share of the square of white noise
    assert np.sum(e_omega) * (omega[1] - omega[0]) == pytest.approx(9e-18 * inside, rel=0.06)


def test_e_of_k_and_omega_put_a_wave_at_its_k_and_omega():
    dk = 2 * np.pi / (SIZE * PIXEL)
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=64)
    push_all(acc, plane_wave(192, 6 * dk, 0.0, 2 * np.pi * 25.0, amplitude=2e-8))
    s = acc.spectrum()
    k, e_k = s.energy_k()
    omega, e_omega = s.energy_omega()
    assert k[np.argmax(e_k)] == pytest.approx(6 * dk)
    assert omega[np.argmax(e_omega)] == pytest.approx(2 * np.pi * 25.0)
    # a plane wave of amplitude a holds a^2 / 2 (the Hann tapers leak a few per cent outside)
    assert np.sum(e_k) * (k[1] - k[0]) == pytest.approx(2e-16, rel=0.02)


def test_segments_do_not_span_gaps_and_too_short_runs_are_refused():
    maps = plane_wave(300, 0.0, 0.0, 1.0)
    times = np.arange(300) / FPS
    times[100:] += 0.5  # 50 frames lost after frame 99
    times[200:] += 0.5
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=128)
    push_all(acc, maps, times)
    with pytest.raises(InputError, match="no run of 128 without a gap"):
        acc.spectrum()
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=64)
    push_all(acc, maps, times)
    assert acc.segments == 3 * 2  # two half-overlapping segments in each run of 100
    assert acc.spectrum().frames == 3 * 96  # frames 0-95 of each run


def test_a_gap_is_not_closed():
    """A wave whose phase jumps across a gap: segments on either side see a clean tone."""
    omega = 2 * np.pi * 12.5
    times = np.concatenate([np.arange(128), np.arange(128) + 128 + 37.3]) / FPS
    x, _ = grid(SIZE, PIXEL)
    maps = 1e-8 * np.cos(3 * 2 * np.pi / (SIZE * PIXEL) * x - omega * times[:, None, None])
    maps = np.broadcast_to(maps, (256, SIZE, SIZE))
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=128)
    push_all(acc, maps, times)
    assert acc.segments == 2
    closed = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=128)
    push_all(closed, maps)  # the same frames as if evenly spaced: the gap closed
    f = np.argmin(np.abs(acc.spectrum().frequency - 12.5))
    peak_kept = acc.spectrum().power[f].max()
    peak_closed = closed.spectrum().power[f].max()
    assert peak_closed < 0.9 * peak_kept  # closing the gap smears the tone


def test_masked_pixels_leave_the_wave_where_it_was():
    dk = 2 * np.pi / (SIZE * PIXEL)
    maps = plane_wave(128, 4 * dk, 2 * dk, 2 * np.pi * 18.75).copy()
    maps[:, 10:14, 5:20] = np.nan
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=64)
    push_all(acc, maps)
    s = acc.spectrum()
    assert s.valid_fraction == pytest.approx(1 - 60 / SIZE**2)
    f, iy, ix = np.unravel_index(np.argmax(s.power), s.power.shape)
    assert (s.frequency[f], s.kx[ix], s.ky[iy]) == pytest.approx((18.75, 4 * dk, 2 * dk))


def test_mostly_masked_segments_are_skipped_with_the_reason():
    maps = np.full((64, SIZE, SIZE), np.nan)
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=32)
    push_all(acc, maps)
    with pytest.raises(InputError, match="finite pixels"):
        acc.spectrum()


def test_latest_is_the_last_segment_alone():
    dk = 2 * np.pi / (SIZE * PIXEL)
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=32)
    with pytest.raises(InputError, match="fewer than a segment"):
        acc.latest()
    push_all(acc, plane_wave(40, 3 * dk, 0.0, 2 * np.pi * 25.0))
    later = plane_wave(32, 0.0, 5 * dk, 2 * np.pi * 12.5)
    for i, frame in enumerate(later):
        acc.push(frame, (40 + i) / FPS)
    latest = acc.latest()
    f, iy, ix = np.unravel_index(np.argmax(latest.power), latest.power.shape)
    assert latest.segments == 1
    assert (latest.frequency[f], latest.ky[iy], latest.kx[ix]) == pytest.approx((12.5, 5 * dk, 0))


def test_input_is_not_mutated_and_bad_input_is_refused():
    maps = plane_wave(40, 100.0, 0.0, 30.0)
    before = maps.copy()
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=32)
    push_all(acc, maps)
    np.testing.assert_array_equal(maps, before)
    with pytest.raises(InputError, match="times must increase"):
        acc.push(maps[0], 0.0)
    with pytest.raises(InputError, match="shape"):
        acc.push(np.zeros((4, 4)), 1.0)
    for kwargs, message in (
        ({"segment": 4}, "at least 8 frames"),
        ({"overlap": 0.9}, "overlap"),
        ({"k_cut": -1.0}, "cut-off"),
    ):
        with pytest.raises(InputError, match=message):
            OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, **kwargs)
    with pytest.raises(InputError, match="pixel size"):
        OmegaKAccumulator((SIZE, SIZE), 0.0, 1 / FPS)
    with pytest.raises(InputError, match="too small"):
        OmegaKAccumulator((4, SIZE), PIXEL, 1 / FPS)


def test_the_cut_off_is_kept_and_bounds_the_energy():
    acc = OmegaKAccumulator((SIZE, SIZE), PIXEL, 1 / FPS, segment=32, k_cut=1000.0)
    rng = np.random.default_rng(1)
    push_all(acc, rng.normal(0, 1e-9, (64, SIZE, SIZE)))
    s = acc.spectrum()
    assert s.k_cut == 1000.0
    k, _ = s.energy_k()
    assert k[-1] <= 1000.0 + math.pi / (SIZE * PIXEL)
