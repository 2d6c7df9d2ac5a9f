"""Frame times: the nominal interval, gaps, and the segments between them."""

from __future__ import annotations

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.processing.waves.clock import frame_clock


def test_an_even_clock_is_one_run():
    clock = frame_clock(np.arange(100) * 0.004)
    assert clock.runs == ((0, 100),)
    assert clock.gaps == 0 and clock.lost == 0
    assert clock.interval == pytest.approx(0.004)
    assert clock.rate == pytest.approx(250.0)
    assert clock.jitter < 1e-12


def test_lost_frames_split_the_runs_and_are_counted():
    times = np.delete(np.arange(50) * 0.01, [10, 11, 12, 30])  # 3 lost, then 1 lost
    clock = frame_clock(times)
    assert clock.runs == ((0, 10), (10, 27), (27, 46))
    assert clock.lost == 4
    assert clock.gaps == 2


def test_jitter_within_the_tolerance_is_no_gap():
    rng = np.random.default_rng(0)
    times = np.arange(200) * 0.01 + rng.uniform(-0.002, 0.002, 200)
    clock = frame_clock(times)
    assert clock.runs == ((0, 200),)
    assert 0.001 < clock.jitter < 0.0041


@pytest.mark.parametrize(
    ("times", "message"),
    [
        ([0.0], "at least two"),
        ([0.0, np.nan, 0.2], "frame 1 is not finite"),
        ([0.0, 0.1, 0.1, 0.3], "frame 2 at 0.1 s follows"),
        ([0.0, 0.2, 0.1], "must increase"),
    ],
)
def test_bad_times_name_the_frame(times, message):
    with pytest.raises(InputError, match=message):
        frame_clock(times)
