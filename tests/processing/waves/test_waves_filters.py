"""Band filters in k, f and direction."""

from __future__ import annotations

import math

import numpy as np
import pytest
from waves_synth import grid

from holoview.errors import InputError
from holoview.processing.waves.filters import Band, band_filter

SIZE, PIXEL, FPS = 24, 1e-3, 200.0


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
