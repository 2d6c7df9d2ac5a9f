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
    """A_n per pixel: weighted least squares of 1, cos and sin of each harmonic (lstsq)."""
    phase = (times - span[0]) / (span[1] - span[0])
    inside = (phase >= 0) & (phase <= 1)
    w = inside * 1.0 if flat else np.where(inside, np.sin(np.pi * phase) ** 2, 0.0)
    finite = np.isfinite(maps)
    out = np.full((len(harmonics), *maps.shape[1:]), np.nan, complex)
    for y, x in np.ndindex(maps.shape[1:]):
        use = finite[:, y, x] & (w > 0)
        t, h, root = times[use], maps[use, y, x], np.sqrt(w[use])
        columns = [np.ones_like(t)]
        for n in harmonics:
            columns.append(np.cos(2 * np.pi * n * frequency * t))
        for n in harmonics:
            columns.append(np.sin(2 * np.pi * n * frequency * t))
        basis = np.column_stack(columns)
        if use.sum() > basis.shape[1]:
            beta = np.linalg.lstsq(basis * root[:, None], h * root, rcond=None)[0]
            out[:, y, x] = beta[1 : 1 + len(harmonics)] + 1j * beta[1 + len(harmonics) :]
    return out, finite.sum(axis=0)


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
        np.testing.assert_allclose(result.amplitude[kept], expected[kept], rtol=0, atol=1e-15)
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


@pytest.mark.parametrize(
    ("frequency", "lost", "frames"),
    [
        (1.37, np.s_[100:350], 500),  # half the record lost: 2.3 cycles either side
        (7.37, np.s_[100:250], 500),
        (0.204, np.s_[0:0], 500),  # 1.02 cycles in the record
    ],
)
def test_lost_frames_and_few_cycles_leave_the_amplitudes_exact(frequency, lost, frames):
    """The fit on the frames there are: a noiseless drive and harmonic come back exactly
    (the weighted sums alone were off by up to 16 % with half the record lost)."""
    times = np.delete(np.arange(frames) / 100.0, lost)
    for shift in (0.0, 0.7, 1.5):
        omega = 2 * math.pi * frequency
        t = times[:, None, None]
        maps = 3e-7 + 4e-9 * np.cos(omega * t - shift) + 1e-9 * np.cos(2 * omega * t - 0.3)
        maps = np.broadcast_to(maps, (times.size, 2, 3))
        lockin = LockIn((2, 3), frequency, (1, 2), span=(times[0], times[-1]))
        lockin.push_block(maps, times)
        result = lockin.result()
        np.testing.assert_allclose(result.amplitude[0], 4e-9 * np.exp(1j * shift), rtol=1e-6)
        np.testing.assert_allclose(result.amplitude[1], 1e-9 * np.exp(0.3j), rtol=1e-6)


@pytest.mark.parametrize("drive", [7.37, 7.5])
def test_the_errors_hold_however_strong_the_drive(drive):
    """A drive 300 times its noise (the residual estimated from plain sums lost its digits
    and the error came out 5 times too large at 7.37 Hz, or 0)."""
    times = np.arange(2000) / 100.0
    rng = np.random.default_rng(4)
    noise = 1e-11
    maps = 3e-7 + 3e-9 * np.cos(2 * math.pi * drive * times - 0.4)[:, None, None]
    maps = maps + rng.normal(0.0, noise, (times.size, 16, 16))
    lockin = LockIn((16, 16), drive, (1,), span=(times[0], times[-1]))
    for start in range(0, times.size, 256):
        lockin.push_block(maps[start : start + 256], times[start : start + 256])
    result = lockin.result()
    w = np.sin(np.pi * (times - times[0]) / (times[-1] - times[0])) ** 2
    expected = math.sqrt(2 * noise**2 * np.sum(w**2) / np.sum(w) ** 2)
    assert np.median(result.stderr[0]) == pytest.approx(expected, rel=0.03)
    scatter = np.std(result.amplitude[0].real)  # over the 256 pixels
    assert scatter == pytest.approx(expected, rel=0.2)
