"""Lock-in maps at a drive frequency and its harmonics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from waves_synth import grid

from holoview.errors import InputError
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
