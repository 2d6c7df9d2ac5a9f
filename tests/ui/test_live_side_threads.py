"""The live maps worker's side threads: maps keep coming while windows are matched again and
maps co-registered; a restart shows no zeros.

Qt-free: the maps worker on a real ring fed by a producer thread, and the maps pipeline.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable

import numpy as np

from holoview.acquire.ring import FrameRing
from holoview.acquire.source import FrameMeta
from holoview.engine.experiment import Experiment, LabelledPeak
from holoview.engine.map_step import Coregistration
from holoview.live import maps_pipeline
from holoview.live.child_work import ChildWork
from holoview.live.maps_pipeline import MapsPipeline
from holoview.live.worker import DemodWorker

from .holograms import FB1, N1, N2, RB1, WAVELENGTH_M, hologram_stack
from .test_live_pipeline import _experiment as _given_radius

SHAPE = (128, 128)


def _experiment() -> Experiment:
    """Windows matched to the surface (the default radius rule), absolute maps."""
    return Experiment(
        wavelength_m=WAVELENGTH_M,
        n1=N1,
        n2=N2,
        reference="absolute",
        peaks=(LabelledPeak("RB1", RB1), LabelledPeak("FB1", FB1)),
    )


def _eventually(check: Callable[[], bool], seconds: float = 120.0) -> bool:
    deadline = time.monotonic() + seconds
    while not check():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


class Producer:
    """Put ``frames`` into ``ring`` over and over on a thread (about 50 frames/s)."""

    def __init__(self, ring: FrameRing, frames: np.ndarray) -> None:
        self._stop = threading.Event()

        def produce() -> None:
            i = 0
            while not self._stop.is_set():
                ring.put(frames[i % len(frames)], FrameMeta(i, i / 50, time.time()))
                i += 1
                self._stop.wait(0.02)

        self._thread = threading.Thread(target=produce, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def test_maps_keep_coming_while_the_windows_are_measured(monkeypatch) -> None:
    """A measurement of the windows (seconds on a large frame) is held until the test lets
    it go: the maps worker goes on publishing maps meanwhile, then takes the new windows
    between two frames and says the restart. Before, it measured on the maps worker's
    thread, and no map came while it measured (a 6 s gap in bench_gui)."""
    entered, release = threading.Event(), threading.Event()
    measure = ChildWork.__call__

    def held(self, job):  # the real measurement (in the match process), made to wait
        entered.set()
        release.wait(300)
        return measure(self, job)

    monkeypatch.setattr(ChildWork, "__call__", held)
    frames = hologram_stack(12, SHAPE)
    ring = FrameRing(4, SHAPE, np.uint16)
    worker = DemodWorker(ring, _experiment(), in_process=True)  # the test's patch reaches it
    worker.start()
    producer = Producer(ring, frames)
    try:
        # the second detection (about a second after the first) starts a measurement
        assert entered.wait(120), "no measurement of the windows started"
        held_at = worker.latest()
        assert held_at is not None
        assert _eventually(lambda: worker.latest().seq >= held_at.seq + 10), (
            "no maps came while the windows were measured"
        )
        assert not any("maps restart" in n for n in worker.latest().notes)
        release.set()
        # asked again, as the operator may: the held measurement's cost (the time the test
        # held it) would space the next one by ten times that, beyond the wait under load
        worker.post("match")
        assert _eventually(lambda: any("maps restart" in n for n in worker.latest().notes))
        assert worker.server is not None
        windows = worker.server.pipeline._core.windows()
        assert {w.rule for w in windows.values()} <= {"matched", "bound"}
    finally:
        release.set()
        producer.stop()
        ring.close()
        worker.stop()
    assert worker.server is not None and not worker.server.matches._thread.is_alive()


def _meta(i: int) -> FrameMeta:
    return FrameMeta(frame_id=i, t_device=i * 0.1, t_host=100.0 + i * 0.1)


def test_the_restart_s_reference_frame_is_marked_and_the_next_maps_are_not_zero() -> None:
    """At a restart (windows matched again, a reset) the first frame is the maps' new
    reference: its maps are zeros, marked so the window does not show them; the next
    frame's are the change again."""
    pipeline = MapsPipeline(_experiment(), SHAPE)
    pipeline.side_work_inline = False
    frames = hologram_stack(10, SHAPE)
    results = [pipeline.process(frames[i], _meta(i)) for i in range(3)]
    assert [r.reference for r in results] == [True, False, False]
    assert np.nanmax(np.abs(results[0].fused_m)) < 1e-12
    assert np.nanmax(np.abs(results[2].fused_m)) > 5e-9
    # the match thread's work, done here: two detections' frames measured, on request
    for i in (3, 4):
        pipeline.apply("match", None)
        job = pipeline.match_job(frames[i])
        assert job is not None and pipeline.match_job(frames[i]) is None  # handed out once
        rematch = job.run(pipeline.matcher)
    assert rematch is not None and "maps restart" in rematch.note
    pipeline.use_match(rematch)
    restart = pipeline.process(frames[5], _meta(5))
    after = [pipeline.process(frames[i], _meta(i)) for i in (6, 7)]
    assert restart.reference and any("maps restart" in n for n in restart.notes)
    assert np.nanmax(np.abs(restart.fused_m)) < 1e-12  # zeros by construction: marked
    assert [r.reference for r in after] == [False, False]
    assert np.nanmax(np.abs(after[-1].fused_m)) > 5e-9
    windows = pipeline._core.windows()
    assert all(windows[k].radius <= rematch.windows[k].radius + 1e-12 for k in windows)
    pipeline.apply("reset", None)
    assert pipeline.process(frames[8], _meta(8)).reference


def test_displacements_measured_off_the_maps_worker_move_the_fused_map(monkeypatch) -> None:
    """The maps' displacements are measured on a thread of their own (adding a frame's maps
    took 140-290 ms on the maps worker at 1024 x 1024); their estimate, held until the test
    lets it go, lets the maps come meanwhile, then reaches the maps and their fusion."""
    monkeypatch.setattr(maps_pipeline, "COREGISTER_HZ", math.inf)  # every frame it can
    entered, release = threading.Event(), threading.Event()
    add_maps = Coregistration.add_maps

    def held(self, *args, **kwargs):  # the real estimate, made to wait for the test
        entered.set()
        release.wait(300)
        return add_maps(self, *args, **kwargs)

    monkeypatch.setattr(Coregistration, "add_maps", held)
    images = {"RB1": (0.5, -0.5), "RF": (3.0, -2.0), "RB2": (-2.0, 1.5)}
    frames = hologram_stack(40, SHAPE, shifts=images)
    ring = FrameRing(4, SHAPE, np.uint16)
    worker = DemodWorker(ring, _given_radius(), in_process=True)  # the test's patch reaches it
    worker.start()
    producer = Producer(ring, frames)
    try:
        assert entered.wait(120), "no maps were added to the estimate"
        held_at = worker.latest()
        assert held_at is not None
        assert _eventually(lambda: worker.latest().seq >= held_at.seq + 10), (
            "no maps came while the displacements were estimated"
        )
        release.set()

        def measured() -> bool:
            shifts = worker.latest().shifts_px
            return all(
                name in shifts
                and abs(shifts[name][0] - (images["RB1"][0] - image[0])) < 0.6
                and abs(shifts[name][1] - (images["RB1"][1] - image[1])) < 0.6
                for name, image in images.items()
                if name != "RB1"
            )

        assert _eventually(measured), worker.latest().shifts_px
        assert worker.latest().grid_of == "RB1" and worker.latest().fused_m is not None
    finally:
        release.set()
        producer.stop()
        ring.close()
        worker.stop()


def test_a_long_measurement_spaces_the_next_unless_the_operator_asks() -> None:
    """Measurements take seconds (their thread would hold the interpreter's lock most of
    the time at one a detection): the next waits for SIDE_SHARE of the time, a request
    does not."""
    pipeline = MapsPipeline(_experiment(), SHAPE)
    pipeline.side_work_inline = False
    frames = hologram_stack(4, SHAPE)
    pipeline.process(frames[0], _meta(0))
    pipeline.set_peaks(pipeline._peaks or [])  # a detection: a measurement is due
    job = pipeline.match_job(frames[0])
    assert job is not None
    pipeline.use_match(job.run(pipeline.matcher), cost_s=1e6)  # a very long measurement
    pipeline.process(frames[1], _meta(1))
    pipeline.set_peaks(pipeline._peaks or [])
    assert pipeline.match_job(frames[1]) is None  # spaced: not yet
    pipeline.apply("match", None)
    asked = pipeline.match_job(frames[1])
    assert asked is not None and asked.requested
