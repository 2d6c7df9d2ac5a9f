"""The threads whose rate is what is left (maps, peak detection) yield the cores first."""

from __future__ import annotations

import os
import sys
import threading
import time

import numpy as np
import pytest

from holoview.acquire.ring import FrameRing
from holoview.engine.experiment import Experiment
from holoview.live.maps_pipeline import MapsPipeline
from holoview.live.worker import SIDE_NICENESS, YIELDING_NICENESS, DemodWorker, yield_to_others

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="per-thread nice values are Linux's"
)


def _nice_of(tid: int) -> int:
    return os.getpriority(os.PRIO_PROCESS, tid)


def test_yield_to_others_lowers_only_the_calling_thread() -> None:
    seen: dict[str, int] = {}

    def run() -> None:
        yield_to_others(3)
        seen["thread"] = _nice_of(threading.get_native_id())

    before = _nice_of(threading.get_native_id())
    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    assert seen["thread"] == min(before + 3, 19)
    assert _nice_of(threading.get_native_id()) == before  # this thread is untouched


def _eventually(check, seconds: float = 2.0) -> bool:
    deadline = time.monotonic() + seconds
    while not check():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


def test_the_maps_worker_and_its_peak_thread_run_niced() -> None:
    ring = FrameRing(4, (64, 64), np.uint16)
    worker = DemodWorker(ring, MapsPipeline(Experiment(), (64, 64)))
    expected = min(_nice_of(threading.get_native_id()) + YIELDING_NICENESS, 19)
    worker.start()
    try:
        for thread in (worker._thread, worker.peaks._thread):  # each sets it as it starts
            assert _eventually(lambda t=thread: _nice_of(t.native_id) == expected), thread.name
        # the side work (spectrum, window matching, displacements) below the maps
        side = min(_nice_of(threading.get_native_id()) + SIDE_NICENESS, 19)
        for side_worker in (worker.spectra, worker.matches, worker.coregistration):
            thread = side_worker._thread
            assert _eventually(lambda t=thread: _nice_of(t.native_id) == side), thread.name
    finally:
        ring.close()
        worker.stop()
