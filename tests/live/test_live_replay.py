"""Replays steered through the live engine (no Qt): jumps never mix frames, trends start over.

A simulated evaporation (50 nm per frame) is recorded with its experiment; its frames go
through the maps pipeline with the segments a replay stamps, and through a live session
steered by :class:`~holoview.live.replay_control.ReplayControl`.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.source import FrameMeta
from holoview.engine.experiment import Experiment
from holoview.errors import InputError
from holoview.live import series_pipeline
from holoview.live import session as session_module
from holoview.live.continuity import Continuity
from holoview.live.maps_pipeline import LiveResult, MapsPipeline
from holoview.live.replay_control import FASTEST
from holoview.live.session import LiveSession


@pytest.fixture(scope="module")
def recording(simulate_evaporation) -> Path:
    """Evaporation at 60 um/min, 128 x 128, 40 frames at 20 frames/s, with its experiment."""
    return simulate_evaporation(40)


def _stored(path: Path, reference: str) -> Experiment:
    with RecordingReader(path) as reader:
        text = reader.experiments()[-1][1]
    return replace(Experiment.from_json(text, where=path.name), reference=reference)


def _frames(path: Path) -> np.ndarray:
    with RecordingReader(path) as reader:
        return reader[:]


def _play(pipeline: MapsPipeline, frames: np.ndarray, plan: list[tuple[int, int]]) -> list:
    """Process ``(index, segment)`` in order, as a replay would deliver them."""
    return [
        pipeline.process(frames[i], FrameMeta(i, i * 0.05, 100 + i * 0.05, file_index=i, segment=s))
        for i, s in plan
    ]


def _mean_nm(result: LiveResult, name: str) -> float:
    return float(np.nanmean(result.heights_m[name])) * 1e9


def test_continuity_breaks_only_where_the_segment_changes() -> None:
    c = Continuity()
    segments = [0, 0, 1, 1, 1, 2]
    assert [c.breaks(FrameMeta(0, 0.0, 0.0, segment=s)) for s in segments] == [
        False,
        False,
        True,
        False,
        False,
        True,
    ]


def test_relative_maps_never_pair_frames_across_a_jump(recording: Path) -> None:
    frames = _frames(recording)
    pipeline = MapsPipeline(_stored(recording, "relative"), frames.shape[1:])
    plan = [(0, 0), (1, 0), (2, 0), (20, 1), (21, 1), (20, 2)]
    results = _play(pipeline, frames, plan)
    assert [(r.frame_index, r.segment) for r in results] == plan
    name = "RB1"
    one_frame = _mean_nm(results[1], name)  # frame 1 against frame 0: 50 nm of evaporation
    assert abs(one_frame) > 20
    for jumped in (results[3], results[5]):  # right after the seek, right after the step back
        assert jumped.heights_m, "a frame after a jump still gives maps"
        for heights in jumped.heights_m.values():
            assert not np.any(heights), "a relative map paired frames across a jump"
    # frame 21 is taken against frame 20, the frame before it in the file
    assert _mean_nm(results[4], name) == pytest.approx(one_frame, rel=0.25)


def test_absolute_reference_is_kept_across_a_jump(recording: Path) -> None:
    frames = _frames(recording)
    pipeline = MapsPipeline(_stored(recording, "absolute"), frames.shape[1:])
    results = _play(pipeline, frames, [(0, 0), (1, 0), (10, 1), (11, 1)])
    name = "RB1"
    assert not np.any(results[0].heights_m[name])  # the reference frame
    # against frame 0 still: 10 frames, 500 nm (RB1's phase wraps every ~800 nm)
    assert abs(_mean_nm(results[2], name)) > 5 * abs(_mean_nm(results[1], name))
    step = _mean_nm(results[3], name) - _mean_nm(results[2], name)
    assert step == pytest.approx(_mean_nm(results[1], name), rel=0.25)


def _wait(predicate, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def _shown(session: LiveSession, index: int) -> LiveResult:
    """Wait until the maps of frame ``index`` are out; return them."""
    _wait(lambda: (r := session.latest()) is not None and r.frame_index == index)
    result = session.latest()
    assert result is not None
    return result


def test_a_steered_session_follows_seeks_and_restarts_its_trends(
    recording: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(series_pipeline, "TREND_HZ", math.inf)
    session = LiveSession(
        f"replay:{recording}",
        _stored(recording, "relative"),
        source_options={"speed": "step"},
        every_frame=True,
    )
    try:
        control = session.replay
        assert control is not None
        session.start()
        for i in range(4):
            assert control.step(1) == i
            assert _shown(session, i).segment == 0
        assert control.seek(30) == 30
        sought = _shown(session, 30)
        assert sought.segment == 1 and not any(np.any(h) for h in sought.heights_m.values())
        for i in (31, 32, 33):
            control.step(1)
            assert _shown(session, i).segment == 1
        # the series may still be on segment 0's four frames (0 to 3) when the steps end
        _wait(lambda: (t := session.trend()) is not None and t.segment == 1 and len(t.times_s) == 4)
        trend = session.trend()
        assert trend is not None and trend.segment == 1
        np.testing.assert_allclose(trend.times_s, [0.0, 0.05, 0.1, 0.15], atol=1e-9)
        assert trend.rate_m_per_s is not None  # fitted over frames 30 to 33 only
        state = control.state()
        assert (state.index, state.n_frames, state.paused) == (33, 40, True)
        assert state.time_s == pytest.approx(33 * 0.05)
        assert state.text == "frame 33 / 39 · 1.650 s"
        with pytest.raises(InputError, match=r"frame 40 is outside evaporation\.h5"):
            control.seek(40)
        assert session.running  # a bad seek changes nothing
    finally:
        session.close()
    assert session.series_worker.series is not None  # brought back when the thread ended
    np.testing.assert_array_equal(session.series_worker.series.frames, [30, 31, 32, 33])


def test_maps_start_at_a_frame_sought_and_follow_frames_the_maps_skipped(
    recording: Path,
) -> None:
    # the window's maps worker takes the newest frame: a seek to the frame after the one
    # shown is still where relative maps start; frames it skipped in one segment are not
    session = LiveSession(
        f"replay:{recording}", _stored(recording, "relative"), source_options={"speed": "step"}
    )
    try:
        control = session.replay
        assert control is not None
        session.start()
        for i in range(4):
            assert control.step(1) == i
            assert _shown(session, i).segment == 0
        assert control.seek(4) == 4
        sought = _shown(session, 4)
        assert sought.segment == 1 and sought.heights_m
        assert not any(np.any(h) for h in sought.heights_m.values())
        for i in (5, 6, 7):  # each delivered before the next step; the maps may skip 5 and 6
            control.step(1)
            _wait(lambda i=i: control.state().index == i)
        last = _shown(session, 7)
        assert last.segment == 1
        # against the last frame the maps took (4, 5 or 6): 50 to 150 nm of evaporation
        assert 20 < abs(_mean_nm(last, "RB1")) < 250
    finally:
        session.close()


def test_play_pause_speed_and_loop_through_the_control(recording: Path) -> None:
    session = LiveSession(f"replay:{recording}", _stored(recording, "relative"))
    try:
        control = session.replay
        assert control is not None
        control.pause()
        session.start()
        assert control.state().paused and control.state().index == -1
        assert control.state().text == "frame - / 39"
        assert control.set_speed(4.0) == 4.0
        assert control.faster() == 8.0 and control.faster() == FASTEST
        assert control.faster() == FASTEST  # the top
        assert control.slower() == 8.0
        assert control.toggle() is True  # plays
        _wait(lambda: control.state().index >= 5)
        assert control.toggle() is False
        control.set_loop(False)
        assert control.to_end() == 39
        _wait(lambda: control.state().index == 39)
        control.play()  # from the last frame without loop: held at the end
        _wait(lambda: control.state().held)
        assert control.state().index == 39 and session.running
        control.play()  # held: plays from the start
        _wait(lambda: 0 <= control.state().index < 39)
        assert control.to_start() == 0
    finally:
        session.close()


def test_a_replay_at_full_speed_waits_for_the_series(simulate_evaporation, monkeypatch) -> None:
    """Played as fast as it reads, a replay waits for the series worker, which takes every
    frame: through a ring of 8 frames the series misses none."""
    recording = simulate_evaporation(200)
    monkeypatch.setattr(session_module, "RING_BYTES", 1)  # the smallest ring: 8 frames
    session = LiveSession(
        f"replay:{recording}",
        _stored(recording, "relative"),
        source_options={"loop": False, "speed": "fast"},
    )
    try:
        assert session.ring.capacity == 8 and session._replay_paced()
        session.start()
        _wait(lambda: session.series_worker.last_frame == 199)
        missed = session.series_worker.status().dropped
    finally:
        session.close()
    assert session.series_worker.series is not None
    frames = np.asarray(session.series_worker.series.frames)
    # none lost, even while the series waited for the maps worker's first peaks (the
    # replay waited too); its newest series began where the peaks last changed
    assert missed == 0
    np.testing.assert_array_equal(frames, np.arange(frames[0], 200))


def test_a_camera_has_no_transport() -> None:
    session = LiveSession("sim", Experiment())
    try:
        assert session.replay is None
    finally:
        session.close()
