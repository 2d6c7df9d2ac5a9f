"""Cyclic garbage is collected on the GUI thread, between events (holoview.ui.garbage)."""

from __future__ import annotations

import gc
import threading
import time
import weakref

from holoview.ui.garbage import collect_between_events


class _Cycle:
    """An object in a reference cycle: only the cyclic collector frees it."""

    def __init__(self) -> None:
        self.me = self


def test_garbage_made_on_another_thread_is_collected_by_the_gui_thread(qapp) -> None:
    collected_on: list[int] = []

    def note(phase: str, info: dict) -> None:
        if phase == "start":
            collected_on.append(threading.get_ident())

    thresholds = gc.get_threshold()
    gc.set_threshold(50, 10, 10)
    gc.callbacks.append(note)
    try:
        with collect_between_events(qapp) as timer:
            assert not gc.isenabled() and timer.isActive()
            first = _Cycle()
            freed = weakref.ref(first)
            del first
            # a thread allocating far past the threshold collects nothing itself ...
            worker = threading.Thread(target=lambda: [_Cycle() for _ in range(5000)])
            worker.start()
            worker.join()
            assert freed() is not None
            # ... the GUI thread's timer does, once the event loop runs
            deadline = time.monotonic() + 5.0
            while freed() is not None and time.monotonic() < deadline:
                qapp.processEvents()
                time.sleep(0.01)
            assert freed() is None
        assert gc.isenabled()
    finally:
        gc.callbacks.remove(note)
        gc.set_threshold(*thresholds)
    assert collected_on and set(collected_on) == {threading.main_thread().ident}
