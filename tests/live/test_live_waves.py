"""The live waves worker and its window (no Qt): every frame of a full-speed replay, the fit
against the simulator's truth, lost frames left as gaps, and one line for each bad input."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import cast

import h5py
import numpy as np
import pytest

from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.ring import FrameRing
from holoview.engine.experiment import Experiment
from holoview.errors import InputError
from holoview.live import wave_worker
from holoview.live.session import LiveSession
from holoview.live.wave_window import FUSED, LiveWaves, WaveHistory, WaveSettings, analyse_window
from holoview.live.wave_worker import FIT_SHARE, FIT_SHARE_BEHIND, WAVES_HZ, WavesWorker
from holoview.live.worker import DemodWorker
from holoview.optics.surfaces import WATER_SURFACE_TENSION
from holoview.optics.wave_fields import random_travelling_waves

#: Frames of the ``travelling_waves`` recording (tests/conftest.py).
FRAMES = 160


@pytest.fixture
def travelling(travelling_waves: Path) -> Path:
    """:data:`FRAMES` frames of travelling waves on 1 mm of water, with their truth."""
    with RecordingReader(travelling_waves) as reader:
        assert len(reader) == FRAMES
    return travelling_waves


def truth_of(path: Path) -> dict:
    with h5py.File(path, "r") as f:
        return dict(f["truth/waves"].attrs)


def stored_experiment(path: Path) -> Experiment:
    with RecordingReader(path) as reader:
        return Experiment.from_json(reader.experiments()[-1][1], where=path.name)


def wait_for(condition, timeout: float = 120.0) -> None:
    """Wait until ``condition()`` is true (polling; no fixed sleep before asserting)."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def assert_close_to_truth(fit, truth: dict, errors: float = 3.0) -> None:
    """sigma within 5 % and d within 10 % of the truth, or within ``errors`` of their standard
    errors where those are larger (small maps); U within the same errors or 2 mm/s; each with
    a standard error (no number without its error)."""
    assert fit.surface_tension_stderr > 0 and fit.depth_stderr > 0
    sigma, depth = truth["sigma_n_per_m"], truth["depth_m"]
    assert abs(fit.surface_tension - sigma) < max(0.05 * sigma, errors * fit.surface_tension_stderr)
    assert abs(fit.depth - depth) < max(0.10 * depth, errors * fit.depth_stderr)
    for axis in (0, 1):
        assert fit.flow_stderr[axis] > 0
        error = abs(fit.flow[axis] - truth["flow_m_per_s"][axis])
        assert error < max(errors * fit.flow_stderr[axis], 2e-3)


def every_frame_analysed(session: LiveSession, frames: int) -> LiveWaves:
    """Wait until the waves worker has made a map of each of ``frames`` frames and an
    analysis begun after the last has come (the one under way then may hold an older
    window: analyses are numbered as they begin); return that analysis."""
    worker = session.waves_worker
    assert worker is not None
    wait_for(lambda: worker.history.pushed >= frames)
    done = worker.latest()
    seq = 0 if done is None else done.seq
    wait_for(lambda: (w := session.waves()) is not None and w.seq >= seq + 2)
    waves = session.waves()
    assert waves is not None
    return waves


def test_a_full_speed_replay_gives_every_frame_and_the_truth(travelling: Path) -> None:
    experiment = stored_experiment(travelling)
    assert experiment.reference == "relative"  # steps between frames, summed by the history
    session = LiveSession(
        f"replay:{travelling}", experiment, source_options={"loop": False, "speed": "fast"}
    )
    try:
        session.open_waves(WaveSettings(label="RB1", length=128, segment=32))
        session.start()
        waves = every_frame_analysed(session, FRAMES)
        assert session.waves_worker is not None
        status = session.waves_worker.status()
        pushed = session.waves_worker.history.pushed
    finally:
        session.close()
    assert waves.label == "RB1" and waves.stride == 1 and waves.gaps == 0
    assert status.read == FRAMES and status.dropped == 0  # the replay waited for the worker
    assert pushed == FRAMES and waves.frames == 128  # a map of every frame; the newest kept
    assert waves.rate == pytest.approx(250.0) and waves.nyquist == pytest.approx(125.0)
    assert waves.spectrum is not None and waves.spectrum.segments == 7  # hop 16 in 128
    assert waves.problems == () and waves.fit is not None
    assert_close_to_truth(waves.fit, truth_of(travelling))
    # both known; no order between them: a replay paced by another worker leaves the map's
    # process idle between frames, and the thread's time per map is then the hand-over's
    assert waves.map_cpu_seconds > 0 and waves.map_seconds > 0


def test_the_fused_map_of_a_full_speed_replay_has_every_frame(travelling: Path) -> None:
    session = LiveSession(
        f"replay:{travelling}",
        stored_experiment(travelling),
        source_options={"loop": False, "speed": "fast"},
    )
    try:
        session.open_waves(WaveSettings(label=FUSED, length=128, segment=32))
        session.start()
        waves = every_frame_analysed(session, FRAMES)
        assert session.waves_worker is not None
        status = session.waves_worker.status()
    finally:
        session.close()
    assert waves.label == FUSED and waves.stride == 1 and waves.gaps == 0
    assert status.read == FRAMES and status.dropped == 0
    assert waves.frames == 128 and waves.spectrum is not None
    assert waves.latest is not None and np.isfinite(waves.latest).any()


def test_the_analyses_yield_the_cores_to_the_maps_while_frames_are_skipped() -> None:
    ring = FrameRing(4, (64, 64), np.uint16)
    maps = cast(DemodWorker, None)  # asked for peaks only when frames come
    worker = WavesWorker(ring, maps, (64, 64), WaveSettings(label="RB1"))
    assert worker.fit_period(0.05) == pytest.approx(1.0 / WAVES_HZ)  # cheap: at the top rate
    assert worker.fit_period(0.5) == pytest.approx(0.5 / FIT_SHARE)
    worker.stride = 2  # the maps keep one camera frame in two: the analyses take less
    assert worker.fit_period(0.5) == pytest.approx(0.5 / FIT_SHARE_BEHIND)
    assert FIT_SHARE_BEHIND < FIT_SHARE


def test_a_window_shorter_than_a_segment_is_refused() -> None:
    with pytest.raises(InputError, match="shorter than a segment"):
        WaveSettings(length=32, segment=64)


# ---- the window on maps made here -------------------------------------------------
PIXEL = 5e-4  # m
RATE = 500.0  # maps/s


def wave_maps(times: np.ndarray, *, size: int = 64, depth: float = 1e-3) -> list[np.ndarray]:
    """Maps (m, float32) of broadband waves on ``depth`` of water with a flow, at ``times``."""
    waves = random_travelling_waves(
        np.random.default_rng(3),
        k_range=(800.0, 2500.0),
        components=150,
        rms=20e-9,
        depth=depth,
        flow=(0.02, -0.01),
    )
    axis = np.arange(size) * PIXEL
    x, y = axis[np.newaxis, :], axis[:, np.newaxis]
    return [np.asarray(waves(float(t), x, y), dtype=np.float32) for t in times]


def history_of(maps, times, ids, *, pixel_size=(PIXEL, PIXEL)) -> WaveHistory:
    history = WaveHistory(len(maps))
    history.label = "RB1"
    history.pixel_size = pixel_size
    history.k_cut = math.pi / PIXEL
    for frame, t, i in zip(maps, times, ids, strict=True):
        history.push(frame, float(t), int(i))
    return history


def test_lost_frames_are_gaps_no_segment_spans() -> None:
    ids = np.concatenate([np.arange(0, 100), np.arange(105, 180)])  # 5 frames lost
    times = ids / RATE
    history = history_of(wave_maps(times), times, ids)
    window = history.snapshot()
    assert window is not None
    assert window.gaps == 1 and history.lost == 5
    assert window.interval == pytest.approx(1 / RATE)
    waves = analyse_window(window, WaveSettings(label="RB1", length=256, segment=32, depth=1e-3))
    assert waves.spectrum is not None
    # Welch by hand: segments of 32 with a hop of 16 inside each run (100 and 75 maps)
    expected = sum((run - 32) // 16 + 1 for run in (100, 75))
    assert waves.spectrum.segments == expected
    assert waves.spectrum.frames == 100 + 75 - (75 - 32) % 16 - (100 - 32) % 16


def test_relative_steps_are_summed_and_a_new_grid_starts_over() -> None:
    history = WaveHistory(8)
    steps = [np.full((8, 8), v, np.float32) for v in (1.0, 2.0, 3.0)]
    for i, step in enumerate(steps):
        history.push(step, i * 0.01, i, relative=True)
    window = history.snapshot()
    assert window is not None
    assert [float(m[0, 0]) for m in window.maps] == [1.0, 3.0, 6.0]
    history.push(np.zeros((4, 4), np.float32), 0.03, 3)
    assert len(history) == 1  # maps of another shape: a new record


def test_a_full_window_keeps_the_newest_maps_only() -> None:
    history = WaveHistory(16)
    for i in range(40):
        history.push(np.full((8, 8), i, np.float32), i * 0.01, i)
    window = history.snapshot()
    assert window is not None and len(window.maps) == 16
    assert float(window.maps[0][0, 0]) == 24 and window.times[-1] == pytest.approx(0.39)


def test_the_fit_of_maps_made_here_against_their_truth() -> None:
    times = np.arange(256) / RATE
    history = history_of(wave_maps(times), times, np.arange(256))
    window = history.snapshot()
    assert window is not None
    waves = analyse_window(window, WaveSettings(label="RB1", length=256, segment=64, depth=2e-3))
    assert waves.problems == () and waves.fit is not None
    truth = {"sigma_n_per_m": WATER_SURFACE_TENSION, "depth_m": 1e-3, "flow_m_per_s": (0.02, -0.01)}
    assert_close_to_truth(waves.fit, truth)


# ---- bad input: one line each, never a number without its error ------------------
def _window(**changes):
    times = np.arange(96) / RATE
    history = history_of(wave_maps(times), times, np.arange(96))
    window = history.snapshot()
    assert window is not None
    return replace(window, **changes)


SETTINGS = WaveSettings(label="RB1", length=96, segment=32, depth=1e-3)


def test_no_pixel_size_is_one_line() -> None:
    waves = analyse_window(_window(pixel_size=None), SETTINGS)
    assert waves.spectrum is None and waves.fit is None
    assert len(waves.problems) == 1 and "pixel size is not known" in waves.problems[0]


def test_fewer_frames_than_a_segment_is_one_line() -> None:
    window = _window()
    short = replace(window, maps=window.maps[:20], times=window.times[:20])
    waves = analyse_window(short, SETTINGS)
    assert waves.spectrum is None and waves.fit is None
    assert waves.problems == ("no omega-k spectrum yet: 20 maps without a gap, a segment needs 32",)


def test_all_nan_maps_are_one_line() -> None:
    window = _window()
    nan = tuple(np.full_like(m, np.nan) for m in window.maps)
    waves = analyse_window(replace(window, maps=nan), SETTINGS)
    assert waves.spectrum is None and waves.fit is None
    assert waves.problems == ("no omega-k spectrum: the RB1 maps are all NaN (untrusted)",)


def test_a_fit_that_does_not_converge_is_one_line_and_no_number() -> None:
    times = np.arange(96) / RATE
    deep = history_of(wave_maps(times, depth=0.05), times, np.arange(96)).snapshot()
    assert deep is not None
    waves = analyse_window(deep, replace(SETTINGS, depth=5e-3))  # k d > 3: depth undetermined
    assert waves.spectrum is not None and waves.fit is None
    assert len(waves.problems) == 1 and "did not converge" in waves.problems[0]
    held = analyse_window(deep, replace(SETTINGS, depth=0.05, hold=("depth",)))
    assert held.fit is not None and held.problems == ()  # held at a known depth: it fits
    assert held.fit.depth == 0.05 and held.fit.depth_stderr == 0.0 and "depth" in held.fit.held


def test_a_centre_outside_the_field_is_one_line() -> None:
    window = _window()
    outside = analyse_window(window, replace(SETTINGS, centre=(0.5, 0.5)))
    assert outside.mf is None and outside.spectrum is not None
    assert len(outside.problems) == 1 and "is outside the maps" in outside.problems[0]
    inside = analyse_window(window, replace(SETTINGS, centre=(32 * PIXEL, 32 * PIXEL)))
    assert inside.mf is not None and inside.centre == (32 * PIXEL, 32 * PIXEL)
    assert inside.mf.power.shape == (17, 17)  # m from -8 to 8, f from 0 to Nyquist


def test_a_smaller_stride_that_does_not_hold_is_tried_later_and_later(monkeypatch) -> None:
    """A machine at the edge of keeping every frame settles on the stride it keeps: each
    change of stride starts the window again, so flapping would leave it never full."""
    clock = {"now": 0.0}
    monkeypatch.setattr(
        wave_worker,
        "time",
        SimpleNamespace(
            monotonic=lambda: clock["now"],
            perf_counter=time.perf_counter,
            thread_time=time.thread_time,
        ),
    )
    ring = FrameRing(4, (64, 64), np.uint16)
    worker = WavesWorker(ring, cast(DemodWorker, None), (64, 64), WaveSettings(label="RB1"))
    needs = {"stride": 2}
    monkeypatch.setattr(worker, "_needed_stride", lambda: needs["stride"])

    def at(t: float, needed: int) -> int:
        clock["now"], needs["stride"] = t, needed
        worker._adapt_stride()
        return worker.stride

    assert at(0.0, 2) == 2  # behind: at once
    needs_one = [at(t, 1) for t in np.arange(1.0, 6.5, 0.5)]
    assert needs_one.index(1) == len(needs_one) - 1  # RELAX_S after the first (t = 1 + 5)
    assert at(6.5, 2) == 2  # did not hold: the next try comes twice as late
    assert [at(t, 1) for t in (12.0, 17.0, 22.0)] == [2, 2, 1]  # 10 s after t = 12, not 5
    assert at(28.0, 2) == 2  # held 6 s, as a stride a machine cannot keep does: 20 s
    assert [at(t, 1) for t in (29.0, 39.0, 49.0)] == [2, 2, 1]
    assert at(70.0, 2) == 2  # held 21 s: no longer wait
    assert [at(t, 1) for t in (71.0, 81.0, 91.0)] == [2, 2, 1]  # still 20 s
    assert wave_worker.RELAX_S == 5.0 and wave_worker.HELD_S > wave_worker.RELAX_S
    assert wave_worker.MAX_RELAX_S >= 20.0


def test_the_stride_rises_when_a_map_outlasts_its_interval_and_falls_with_room(
    monkeypatch,
) -> None:
    """A band between rising and falling: a map timed at 0.92 of the camera's interval
    keeps every frame, one at 1.8 of it keeps every second (stride 4 before); a smaller
    stride is tried only where a map would take at most RELAX_BUSY of its interval. A
    map's cost raises the stride only once an eighth of the ring waits (a moment behind
    is caught up)."""
    ring = FrameRing(64, (64, 64), np.uint16)
    worker = WavesWorker(ring, cast(DemodWorker, None), (64, 64), WaveSettings(label="RB1"))
    worker._costs.extend([0.01] * wave_worker.MIN_COSTS)
    share = {"busy": 0.0, "backlog": 8}
    monkeypatch.setattr(worker, "paced", lambda: False)
    monkeypatch.setattr(worker, "camera_rate", lambda: 60.0)
    monkeypatch.setattr(worker, "map_seconds", lambda: share["busy"] / 60.0)
    monkeypatch.setattr(worker, "backlog", lambda: share["backlog"])

    def needed(stride: int, busy: float) -> int:
        worker.stride, share["busy"] = stride, busy
        return worker._needed_stride()

    share["backlog"] = 7  # under an eighth of the ring: not behind yet
    assert needed(1, 1.2) == 1 and needed(2, 2.5) == 2
    share["backlog"] = 8
    assert needed(1, 0.92) == 1  # keeps up: every frame (2 before)
    assert needed(1, 1.2) == 2 and needed(1, 2.5) == 4  # behind: to TARGET_BUSY at once
    assert needed(2, 1.8) == 2  # the edge at stride 2: stays (4 before)
    assert needed(2, 2.1) == 4
    assert needed(2, 0.9) == 2  # no room at stride 1: not tried (1 before)
    assert needed(2, wave_worker.RELAX_BUSY) == 1
    assert needed(8, 0.5) == 1  # far below: the smallest with room
    assert wave_worker.TARGET_BUSY > wave_worker.RELAX_BUSY
