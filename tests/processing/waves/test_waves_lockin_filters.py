"""Lock-in maps at a drive frequency and its harmonics; band filters in k, f and direction."""

from __future__ import annotations

import math

import numpy as np
import pytest
from waves_synth import grid

from holoview.errors import InputError
from holoview.processing.waves.filters import Band, band_filter
from holoview.processing.waves.lockin import LockIn, push_lockins

SIZE, PIXEL, FPS = 24, 1e-3, 200.0


def driven(times, drive=17.3, noise=0.0, seed=0):
    """h = A1 cos(w t - p1) + A2 cos(2 w t - p2) with known maps A, p, plus an offset."""
    x, y = grid(SIZE, PIXEL)
    a1 = 5e-9 * (1 + x / x.max()) + 0 * y
    p1 = 30.0 * y + 0 * x
    a2 = 2e-9 + 0 * x * y
    p2 = 0.5 + 0 * x * y
    omega = 2 * math.pi * drive
    t = np.asarray(times)[:, None, None]
    rng = np.random.default_rng(seed)
    maps = 3e-7 + a1 * np.cos(omega * t - p1) + a2 * np.cos(2 * omega * t - p2)
    return maps + rng.normal(0, noise, maps.shape), (a1, p1, a2, p2)


def test_amplitude_and_phase_maps_of_the_drive_and_its_harmonic_with_gaps_and_masks():
    times = np.delete(np.arange(1200) / FPS, np.s_[300:340])  # frames lost
    maps, (a1, p1, a2, p2) = driven(times, noise=0.5e-9)
    maps[100:400, 3, 4] = np.nan  # a pixel untrusted for a while
    lockin = LockIn((SIZE, SIZE), 17.3, (1, 2, 3), span=(times[0], times[-1]))
    for start in range(0, times.size, 100):
        lockin.push_block(maps[start : start + 100], times[start : start + 100])
    result = lockin.result()
    np.testing.assert_allclose(result.magnitude[0], a1, atol=0.1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (result.phase[0] - p1))), 0, atol=0.05)
    np.testing.assert_allclose(result.magnitude[1], a2, atol=0.1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (result.phase[1] - p2))), 0, atol=0.1)
    assert np.all(result.magnitude[2] < 0.15e-9)  # no third harmonic
    # the errors match the scatter of the no-signal harmonic
    expected = np.sqrt(np.mean(result.magnitude[2] ** 2) / 2)
    assert np.median(result.stderr[2]) == pytest.approx(expected, rel=0.3)
    assert result.frames[3, 4] == times.size - 300
    assert result.frames[0, 0] == times.size


def plain_lockin(maps, times, frequency, harmonics, *, span, flat):
    """A_n = 2 sum w (h - mean) e^{+i n w t} / sum w per pixel, over its finite frames."""
    phase = (times - span[0]) / (span[1] - span[0])
    inside = (phase >= 0) & (phase <= 1)
    w = inside * 1.0 if flat else np.where(inside, np.sin(np.pi * phase) ** 2, 0.0)
    finite = np.isfinite(maps)
    h = np.where(finite, maps, 0.0).astype(np.float64)
    weights = w[:, None, None] * finite
    total = np.sum(weights, axis=0)
    has = total > 0
    total = np.where(has, total, 1.0)
    mean = np.sum(weights * h, axis=0) / total
    out = []
    for n in harmonics:
        turn = np.exp(2j * np.pi * n * frequency * times)[:, None, None]
        out.append(np.where(has, 2 * np.sum(weights * (h - mean) * turn, axis=0) / total, np.nan))
    return np.array(out), finite.sum(axis=0)


def test_lockins_fed_together_give_each_its_own_maps():
    """push_lockins: one pass over each block for every lock-in, the numbers of each alone."""
    times = np.delete(np.arange(700) / FPS, np.s_[200:230])
    maps, _ = driven(times, noise=0.5e-9)
    maps[:, 5:8, 9:12] = np.nan  # a hole in every frame (one mask per block)
    maps[120:260, 2, 3] = np.nan  # a pixel untrusted for a while (masks that change)
    half = 0.5 * (times[0] + times[-1])
    plans = [
        (17.3, (1, 2, 3), (times[0], times[-1]), False),
        (17.3, (1,), (times[0], times[-1]), True),
        (17.3, (1,), (times[0], half), True),
        (9.1, (2,), (half, times[-1]), False),
    ]
    lockins = [
        LockIn((SIZE, SIZE), f, n, span=span, window="flat" if flat else "hann")
        for f, n, span, flat in plans
    ]
    for start in range(0, times.size, 64):
        push_lockins(lockins, maps[start : start + 64], times[start : start + 64])
    for lockin, (f, n, span, flat) in zip(lockins, plans, strict=True):
        result = lockin.result()
        expected, frames = plain_lockin(maps, times, f, n, span=span, flat=flat)
        kept = np.isfinite(expected)
        assert np.array_equal(np.isfinite(result.amplitude), kept)
        np.testing.assert_allclose(result.amplitude[kept], expected[kept], rtol=0, atol=2e-14)
        np.testing.assert_array_equal(result.frames, frames)
    with pytest.raises(InputError, match="same map shape"):
        push_lockins([lockins[0], LockIn((4, 4), 1.0)], maps[:4], times[:4])


def test_lockin_refuses_bad_input():
    with pytest.raises(InputError, match="drive frequency"):
        LockIn((4, 4), 0.0)
    with pytest.raises(InputError, match="harmonics"):
        LockIn((4, 4), 1.0, (0,))
    lockin = LockIn((4, 4), 1.0)
    with pytest.raises(InputError, match="do not match"):
        lockin.push_block(np.zeros((3, 4, 4)), [0.0, 1.0])
    with pytest.raises(InputError, match="no pixel"):
        lockin.result()


def two_waves(frames):
    x, _ = grid(SIZE * 2, PIXEL)
    t = np.arange(frames)[:, None, None] / FPS
    k1, k2 = 2 * np.pi * 8 / (2 * SIZE * PIXEL), 2 * np.pi * 4 / (2 * SIZE * PIXEL)
    along = np.cos(k1 * x - 2 * np.pi * 25.0 * t) * np.ones((1, 2 * SIZE, 1))  # +x, 25 Hz
    against = np.cos(-k2 * x - 2 * np.pi * 50.0 * t) * np.ones((1, 2 * SIZE, 1))  # -x, 50 Hz
    return along, against, (k1, k2)


@pytest.mark.parametrize(
    ("band", "kept"),
    [
        (Band(direction=0.0, half_width=0.5), "along"),
        (Band(direction=math.pi, half_width=0.5), "against"),
        (Band(f_min=40.0, f_max=60.0), "against"),
        (Band(f_max=35.0), "along"),
    ],
)
def test_temporal_band_filters_keep_one_wave(band, kept):
    along, against, _ = two_waves(512)
    out = np.zeros_like(along)
    times = np.arange(512) / FPS
    band_filter(along + against, times, PIXEL, band, out, block=128)
    expected = along if kept == "along" else against
    middle = slice(64, -64)  # the ends of a run see less of their neighbours
    assert np.max(np.abs(out[middle] - expected[middle])) < 0.02


def test_a_wavenumber_band_works_frame_by_frame_and_keeps_masks():
    along, against, (k1, k2) = two_waves(16)
    maps = along + against
    maps[3, 5, 6] = np.nan
    out = np.zeros_like(maps)
    band_filter(maps, np.arange(16) / FPS, PIXEL, Band(k_max=0.5 * (k1 + k2)), out)
    assert np.isnan(out[3, 5, 6])
    keep = np.isfinite(maps)
    keep[3] = False  # the masked frame's neighbours of the NaN see its zero
    assert np.max(np.abs(out - against)[keep]) < 1e-9


def test_runs_are_filtered_apart():
    along, against, _ = two_waves(300)
    times = np.arange(300) / FPS
    times[150:] += 1.0  # a gap of 200 frames
    out = np.zeros_like(along)
    band_filter(along + against, times, PIXEL, Band(f_max=35.0), out, block=64)
    assert np.max(np.abs(out[32:118] - along[32:118])) < 0.05
    assert np.max(np.abs(out[182:268] - along[182:268])) < 0.05


class CountingStack:
    """Maps read by frame slices, as from a file, each frame's reads counted."""

    def __init__(self, maps: np.ndarray) -> None:
        self.maps, self.shape = maps, maps.shape
        self.reads = np.zeros(maps.shape[0], int)

    def __getitem__(self, key: slice) -> np.ndarray:
        self.reads[key] += 1
        return self.maps[key]


def test_each_frame_is_read_once_and_its_masks_kept():
    """A frame is in two blocks and in the output: read once (a relative recording's maps
    are summed as they are read), its untrusted pixels NaN in the output."""
    along, against, _ = two_waves(300)
    maps = along + against
    maps[[5, 140, 151, 299], 3, 4] = np.nan
    times = np.arange(300) / FPS
    times[150:] += 1.0  # two runs
    stack, out = CountingStack(maps), np.zeros_like(maps)
    band_filter(stack, times, PIXEL, Band(f_max=35.0), out, block=64)
    assert np.all(stack.reads == 1)
    assert np.array_equal(np.isnan(out), np.isnan(maps))


def test_band_limits_are_checked():
    with pytest.raises(InputError, match="must increase"):
        Band(k_min=10.0, k_max=5.0)
    with pytest.raises(InputError, match=">= 0"):
        Band(f_min=-1.0)
    with pytest.raises(InputError, match="half-width"):
        Band(direction=0.0, half_width=0.0)
    out = np.zeros((20, 4, 4))
    with pytest.raises(InputError, match="block"):
        band_filter(np.zeros((20, 4, 4)), np.arange(20.0), 1.0, Band(f_max=0.1), out, block=7)
