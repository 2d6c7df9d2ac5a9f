"""The Waves panel's map made in a process of its own (:mod:`holoview.live.wave_map`): the
same maps as on the calling thread, frames through shared memory, two maps under way at
once, and a map's process killed under a running replay (real processes, real signals)."""

from __future__ import annotations

import logging
import os
import signal
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from holoview.acquire.recording_reader import RecordingReader
from holoview.engine.experiment import Experiment
from holoview.errors import HoloviewError
from holoview.live.child_work import ChildWork
from holoview.live.session import LiveSession
from holoview.live.wave_map import FrameSlot, WaveJob, WaveMap, WaveMapper
from holoview.live.wave_window import FUSED, WaveSettings
from holoview.processing.peaks.detection import Peak

from .test_live_child_work import _alive, _gone
from .test_live_waves import stored_experiment, wait_for


def _frames_and_peaks(
    path: Path, count: int
) -> tuple[list[np.ndarray], tuple[Peak, ...], Experiment]:
    """The first ``count`` frames of a recording, its labelled peaks and experiment."""
    experiment = stored_experiment(path)
    with RecordingReader(path) as reader:
        frames = [np.array(reader.frame(k)) for k in range(count)]
    peaks = tuple(
        Peak(p.carrier, 1.0, 100.0, label=p.label, alpha=experiment.alpha(p))
        for p in experiment.peaks
    )
    return frames, peaks, experiment


def test_the_fused_map_keeps_its_peaks_while_detections_come_and_go(
    travelling_waves: Path,
) -> None:
    """On a wavy surface a weak family is found on some frames and missed on others (RB2
    here: before the waves start, not after), and the maps' peaks change with each
    detection; the fused map kept for the waves keeps its first peaks in one order (a
    missed family at its last carrier, a new one left out), so its window never starts
    again for that. Before, the first detection without RB2 rebuilt it."""
    frames, peaks, experiment = _frames_and_peaks(travelling_waves, 6)
    rb2 = Peak((-0.4012, -0.0679), 0.2, 50.0, label="RB2", alpha=1.2)
    fb2 = Peak((0.125, 0.25), 0.1, 40.0, label="FB2", alpha=0.9)
    sets = [
        (*peaks, rb2),
        peaks,  # RB2 missed
        (rb2, *reversed(peaks)),  # found again, in another order (by amplitude)
        (*peaks, fb2),  # a family the model adds
        peaks,
        (*peaks, rb2),
    ]
    mapper = WaveMapper((frames[0].shape[0], frames[0].shape[1]))
    made = [mapper.map(f, WaveJob(s, experiment, FUSED)) for f, s in zip(frames, sets, strict=True)]
    assert [m.rebuilt for m in made] == [True] + [False] * 5
    relabelled = replace(experiment, peaks=experiment.peaks[:2])  # the operator's labels change
    assert mapper.map(frames[0], WaveJob(peaks, relabelled, FUSED)).rebuilt


def test_maps_made_in_the_child_are_those_made_here_and_come_in_order(
    travelling_waves: Path,
) -> None:
    frames, peaks, experiment = _frames_and_peaks(travelling_waves, 6)
    shape = (frames[0].shape[0], frames[0].shape[1])
    here = WaveMapper(shape)
    expected = [here.map(f, WaveJob(peaks, experiment, "RB1")) for f in frames]
    slot = FrameSlot(shape, frames[0].dtype, 2)
    child: ChildWork[WaveJob, WaveMap] = ChildWork(slot.child_work(None), "holoview-test", 0)
    try:
        got = []
        for k, frame in enumerate(frames):  # two under way at once, as the waves worker has
            slot.put(k % 2, frame)
            child.submit(WaveJob(peaks, experiment, "RB1", slot=k % 2))
            if k:
                got.append(child.result())
        got.append(child.result())
        pid = child.pid
    finally:
        child.close()
        slot.close()
    assert pid is not None and pid != os.getpid()
    assert [g.rebuilt for g in got] == [True] + [False] * 5  # the first plans its FFTs
    for made, want in zip(got, expected, strict=True):
        np.testing.assert_array_equal(made.height, want.height)  # same frames, same bits
        assert made.k_cut == want.k_cut and made.pixel_size == want.pixel_size
        assert made.reference == "relative" and made.cpu_seconds > 0
    assert not Path("/dev/shm", slot.name).exists()  # the shared frames removed


def test_a_result_with_no_job_sent_is_refused() -> None:
    child: ChildWork[int, int] = ChildWork(_echo, "holoview-test", 0)
    with pytest.raises(HoloviewError, match="holoview-test has no job"):
        child.result()
    child.close()
    with pytest.raises(HoloviewError, match="holoview-test was stopped"):
        child.result()


def _echo() -> Callable[[int], int]:
    return lambda job: job


def test_a_killed_map_process_is_said_once_and_the_maps_go_on(
    travelling_waves: Path, caplog: pytest.LogCaptureFixture
) -> None:
    session = LiveSession(
        f"replay:{travelling_waves}",
        stored_experiment(travelling_waves),
        source_options={"loop": True},
    )
    caplog.set_level(logging.WARNING, logger="holoview.live.wave_worker")
    try:
        session.open_waves(WaveSettings(label="RB1", length=64, segment=32))
        session.start()
        worker = session.waves_worker
        assert worker is not None and worker._child is not None
        wait_for(lambda: worker.history.pushed >= 20)
        pid = worker._child.pid
        assert pid is not None and _alive(pid)
        os.kill(pid, signal.SIGKILL)
        assert _gone(pid)
        wait_for(lambda: worker._child is not None and worker._child.pid not in (None, pid))
        pushed = worker.history.pushed
        wait_for(lambda: worker.history.pushed >= pushed + 20)  # a new process, new maps
        assert worker.running and session.running
        slot_name = worker._slot.name if worker._slot is not None else ""
        new_pid = worker._child.pid
    finally:
        session.close()
    ended = [r.getMessage() for r in caplog.records if "process ended" in r.getMessage()]
    assert len(ended) == 1 and "exit code -9" in ended[0], ended
    assert new_pid is not None and _gone(new_pid)  # the session's close ends it
    assert slot_name and not Path("/dev/shm", slot_name).exists()
