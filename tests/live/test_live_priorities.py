"""The threads whose rate is what is left (maps, peak detection) yield the cores first."""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from holoview.acquire.ring import FrameRing
from holoview.engine.experiment import Experiment
from holoview.live.side_workers import SIDE_NICENESS, YIELDING_NICENESS, yield_to_others
from holoview.live.worker import DemodWorker

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
    """The maps made on the worker's thread (no process to be had): the thread and the
    peak detection at +5, the side work at +10."""
    ring = FrameRing(4, (64, 64), np.uint16)
    worker = DemodWorker(ring, Experiment(), in_process=True)
    expected = min(_nice_of(threading.get_native_id()) + YIELDING_NICENESS, 19)
    worker.start()
    try:
        assert worker.server is not None
        for thread in (worker._thread, worker.server.peaks._thread):  # each sets it at start
            assert _eventually(lambda t=thread: _nice_of(t.native_id) == expected), thread.name
        # the side work (spectrum, window matching, displacements) below the maps
        side = min(_nice_of(threading.get_native_id()) + SIDE_NICENESS, 19)
        server = worker.server
        for side_worker in (server.spectra, server.matches, server.coregistration):
            thread = side_worker._thread
            assert _eventually(lambda t=thread: _nice_of(t.native_id) == side), thread.name
    finally:
        ring.close()
        worker.stop()


def _nices_of_process(pid: int) -> set[int]:
    """The nice values of a process's threads named as it is (``/proc/PID/task``; the
    numerical libraries' threads, started as it imports them, have another name)."""
    out = set()
    name = Path(f"/proc/{pid}/comm").read_text().strip()
    for task in os.listdir(f"/proc/{pid}/task"):
        with contextlib.suppress(OSError):  # a thread that ended meanwhile
            if Path(f"/proc/{pid}/task/{task}/comm").read_text().strip() == name:
                out.add(_nice_of(int(task)))
    return out


def test_the_maps_process_yields_and_its_side_threads_below_it() -> None:
    """In their own process the maps run at +5, peak detection at +10 and the side work
    at +15; the window's thread that waits for them is not lowered."""
    ring = FrameRing(4, (64, 64), np.uint16)
    worker = DemodWorker(ring, Experiment())
    base = _nice_of(threading.get_native_id())
    worker.start()
    try:
        assert worker.child is not None and worker.child.pid is not None
        pid = worker.child.pid
        wanted = {min(base + n, 19) for n in (5, 5 + YIELDING_NICENESS, 5 + SIDE_NICENESS)}
        assert _eventually(lambda: wanted <= _nices_of_process(pid), 60), _nices_of_process(pid)
        assert min(_nices_of_process(pid)) == min(base + YIELDING_NICENESS, 19)
        assert _eventually(lambda: worker._thread.native_id is not None)
        assert _nice_of(worker._thread.native_id) == base
    finally:
        ring.close()
        worker.stop()
