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


@pytest.mark.parametrize(("after", "refused"), [(0.01, True), (0.012, True), (0.0104, False)])
def test_a_change_of_frame_rate_is_refused_where_it_happens(after, refused):
    """450 maps at 50 frames/s then 250 faster: analysed at the nominal 20 ms, a 12.3 Hz
    wave of the fast part showed at 6.25 Hz. A change within 5 % stands (4 % here)."""
    before = 0.02 if after == 0.01 else 0.01
    times = np.concatenate([np.arange(450) * before, 450 * before + np.arange(250) * after])
    if not refused:
        assert frame_clock(times).runs == ((0, 700),)
        return
    with pytest.raises(InputError, match=r"frame rate changes: around frame 4[45]\d the maps"):
        frame_clock(times)


def test_a_jittery_clock_is_no_change_of_rate():
    """Time stamps scattered by 8 % of the interval (a host's clock at 400 frames/s)."""
    rng = np.random.default_rng(2)
    times = np.arange(20000) / 400 + rng.normal(0, 0.0002, 20000)
    clock = frame_clock(times)  # a step 4.4 sigma long is a gap now and then: no change
    assert clock.lost <= 2 and clock.interval == pytest.approx(0.0025, rel=1e-3)
