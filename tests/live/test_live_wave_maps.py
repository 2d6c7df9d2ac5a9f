"""The Waves panel's maps made in a child process: the engine's map of every frame, the
sequence broken where the worker breaks it, a child that ends said once and started again."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from holoview.acquire.simulated import SimulatedSource
from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FrameCore
from holoview.engine.map_step import MapStep
from holoview.errors import InputError
from holoview.live.wave_maps import MapProcess, MapProcessError
from holoview.optics.families import predict_families
from holoview.processing.peaks.detection import Peak

SHAPE = (256, 256)


@pytest.fixture(scope="module")
def scene() -> tuple[list[np.ndarray], list[Peak], Experiment]:
    """Six simulated frames of a wavy surface (uint16), their RB1 and FB1, an experiment."""
    source = SimulatedSource(shape=SHAPE, frame_rate_hz=60.0, seed=5, render="live")
    source.open()
    try:
        frames = [np.array(source._render(k / 60.0)) for k in range(6)]
        setup = source.sim_setup
    finally:
        source.close()
    families = {f.label: f for f in predict_families(setup, max_order=2, second_order=False)}
    peaks = [
        Peak(f.observed_carrier, f.amplitude, 100.0, label=f.label, alpha=f.alpha)
        for f in (families["RB1"], families["FB1"])
    ]
    experiment = Experiment(
        wavelength_m=setup.wavelength, pixel_pitch_m=setup.pixel_pitch, radius=0.06
    )
    return frames, peaks, experiment


def engine_maps(
    frames: list[np.ndarray], chosen: list[Peak], experiment: Experiment, fused: bool
) -> list[np.ndarray]:
    """The engine's maps of the frames in order, made here (the reference the child must match)."""
    core = FrameCore(SHAPE, experiment, chosen)
    step = MapStep(core)
    out = []
    for frame in frames:
        maps = step.process(frame, estimate=fused, fuse=fused)
        height = maps.fused if fused else maps.maps[0]
        assert height is not None
        out.append(height)
    return out


@pytest.mark.parametrize("fused", [False, True])
def test_the_child_makes_the_engines_map_of_every_frame(scene, fused: bool) -> None:
    frames, peaks, experiment = scene
    chosen = peaks if fused else peaks[:1]
    label = "fused" if fused else "RB1"
    expected = engine_maps(frames, chosen, experiment, fused)
    mapper = MapProcess(SHAPE)
    try:
        made = [
            mapper.map(f, chosen, experiment, label=label, fused=fused, estimate=fused)
            for f in frames
        ]
        pid = mapper.pid
        assert pid is not None and pid != os.getpid()  # made in another process
    finally:
        mapper.close()
    assert [m.rebuilt for m in made] == [True] + [False] * (len(frames) - 1)
    assert all(m.relative for m in made)  # the experiment's reference
    assert made[0].pixel_size == pytest.approx(
        (experiment.pixel_pitch_m * SHAPE[0] / made[0].height.shape[0],) * 2
    )
    for m, e in zip(made, expected, strict=True):
        assert m.height.dtype == e.dtype and m.height.shape == e.shape
        assert np.array_equal(np.isnan(m.height), np.isnan(e))
        assert np.isfinite(e).sum() > 0.5 * e.size
        scale = float(np.nanmax(np.abs(e))) or 1.0
        np.testing.assert_allclose(m.height, e, rtol=0, atol=1e-5 * scale, equal_nan=True)
    with pytest.raises(ProcessLookupError):  # the child ended with close()
        wait_until_gone(pid)


def wait_until_gone(pid: int, timeout: float = 30.0) -> None:
    """Signal 0 to ``pid`` until it fails (ProcessLookupError), or fail after ``timeout``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        os.kill(pid, 0)
        time.sleep(0.02)
    raise AssertionError(f"process {pid} still runs")


def test_a_broken_sequence_pairs_no_frames_in_the_child_either(scene) -> None:
    frames, peaks, experiment = scene
    core = FrameCore(SHAPE, experiment, peaks[:1])
    step = MapStep(core)
    mapper = MapProcess(SHAPE)
    try:
        for k, frame in enumerate(frames):
            if k == 3:
                core.break_sequence()
                mapper.break_sequence()
            mine = step.process(frame, fuse=False).maps[0]
            theirs = mapper.map(
                frame, peaks[:1], experiment, label="RB1", fused=False, estimate=False
            ).height
            np.testing.assert_allclose(theirs, mine, rtol=0, atol=1e-12, equal_nan=True)
            if k == 3:  # no map pairs frames 2 and 3: the reference starts again
                assert not np.any(np.nan_to_num(mine))
    finally:
        mapper.close()


def test_a_launched_child_makes_the_first_map_and_ends_with_close(scene) -> None:
    frames, peaks, experiment = scene
    mapper = MapProcess(SHAPE)
    try:
        mapper.launch(frames[0].dtype)  # returns at once: the child imports meanwhile
        pid = mapper.pid
        assert pid is not None
        made = mapper.map(
            frames[0], peaks[:1], experiment, label="RB1", fused=False, estimate=False
        )
        assert mapper.pid == pid and made.rebuilt
    finally:
        mapper.close()
    assert mapper.pid is None
    with pytest.raises(ProcessLookupError):
        wait_until_gone(pid)


def test_no_map_from_the_child_is_one_line(scene) -> None:
    frames, _, experiment = scene
    mapper = MapProcess(SHAPE)
    try:
        with pytest.raises(InputError, match="no map of RB1 from this frame"):
            mapper.map(frames[0], [], experiment, label="RB1", fused=False, estimate=False)
    finally:
        mapper.close()


def test_a_child_that_ends_is_said_once_and_started_again(scene) -> None:
    frames, peaks, experiment = scene
    mapper = MapProcess(SHAPE)
    try:
        first = mapper.map(
            frames[0], peaks[:1], experiment, label="RB1", fused=False, estimate=False
        )
        assert first.rebuilt
        pid = mapper.pid
        assert pid is not None
        os.kill(pid, signal.SIGKILL)
        with pytest.raises(MapProcessError, match="waves map process ended"):
            mapper.map(frames[1], peaks[:1], experiment, label="RB1", fused=False, estimate=False)
        again = mapper.map(
            frames[2], peaks[:1], experiment, label="RB1", fused=False, estimate=False
        )
        assert mapper.pid not in (None, pid)
        assert again.rebuilt  # a new demodulator: the panel's window starts again
    finally:
        mapper.close()


def test_on_the_calling_thread_the_maps_are_the_same(scene) -> None:
    frames, peaks, experiment = scene
    expected = engine_maps(frames[:3], peaks[:1], experiment, False)
    mapper = MapProcess(SHAPE, child=False)
    made = [
        mapper.map(f, peaks[:1], experiment, label="RB1", fused=False, estimate=False).height
        for f in frames[:3]
    ]
    assert mapper.pid is None
    for m, e in zip(made, expected, strict=True):
        np.testing.assert_array_equal(m, e)
