"""Side work beside the live workers: threads at a lower priority, a process for the match.

Peak detection (``holoview-peaks``), the display spectrum (``holoview-spectrum``), the
windows' match to the surface (``holoview-match``) and the maps' displacement estimate
(``holoview-coregister``) are each slower than a frame's maps: each runs on a thread of
its own (:class:`SideWorker`) at a lower priority, and the maps take their results
between frames, so that no frame's maps wait for them. The match, long and in Python,
runs in a process of its own (:class:`MatchWorker`): on a thread it held the
interpreter's lock away from the maps. :func:`yield_to_others` lowers a thread's
priority; :func:`wait_at_exit` has the interpreter's exit wait for a worker still
running.
"""

from __future__ import annotations

import atexit
import logging
import os
import sys
import threading
import time
import weakref
from collections.abc import Callable
from typing import Generic, Protocol, TypeVar

import numpy as np

from holoview.engine.frame_core import FFT_THREADS
from holoview.engine.map_step import Coregistration
from holoview.engine.window_matching import MatchJob, Rematch, WindowMatcher
from holoview.errors import HoloviewError
from holoview.live.child_work import ChildWork
from holoview.live.maps_pipeline import CoregistrationJob
from holoview.processing.peaks.detection import Peak, find_peaks

logger = logging.getLogger(__name__)

#: Niceness added to the threads whose rate is whatever is left (maps, peak detection):
#: on a machine with fewer cores than busy threads the series and the window, which
#: must keep up, get the cores first.
YIELDING_NICENESS = 5
#: Niceness added to the maps worker's side threads (display spectrum, window matching,
#: displacement estimate): below the maps, whose latency they must not lengthen (their
#: results may come late; the maps use the last ones meanwhile).
SIDE_NICENESS = 10


def yield_to_others(increment: int = YIELDING_NICENESS) -> None:
    """Lower the calling thread's scheduling priority by ``increment`` (Linux; else nothing).

    Linux gives every thread its own nice value (``setpriority`` on the thread id);
    raising it needs no privilege. Elsewhere the call does nothing.
    """
    if not sys.platform.startswith("linux"):
        return
    tid = threading.get_native_id()
    try:
        os.setpriority(os.PRIO_PROCESS, tid, os.getpriority(os.PRIO_PROCESS, tid) + increment)
    except OSError as exc:  # a sandbox that forbids it: run at the same priority
        logger.debug("cannot lower the priority of %s: %s", threading.current_thread().name, exc)


#: The type of a side thread's jobs and of its results.
J = TypeVar("J")
T = TypeVar("T")


#: Seconds the interpreter's exit waits for each worker still running (its job under way).
EXIT_JOIN_S = 60.0


class _Stoppable(Protocol):
    def stop(self, timeout: float = ...) -> None: ...


#: Workers started and not yet stopped for good (weakly held).
_STARTED: weakref.WeakSet[_Stoppable] = weakref.WeakSet()


def wait_at_exit(worker: _Stoppable, alive: bool) -> None:
    """Have the interpreter's exit stop ``worker`` and wait for it while it is ``alive``."""
    if alive:
        _STARTED.add(worker)
    else:
        _STARTED.discard(worker)


@atexit.register
def _stop_at_exit() -> None:
    """Stop every worker still running and wait for the job under way.

    A window's ``stop`` waits a few seconds for each thread; a measurement that takes
    longer (matching windows at 1024^2 under load) ran on, on a daemon thread, while the
    interpreter tore its modules down under it: a crash at exit. The interpreter calls
    this before that teardown.
    """
    for worker in list(_STARTED):
        worker.stop(EXIT_JOIN_S)


class SideWorker(Generic[J, T]):
    """Run ``work`` on one job at a time on a thread of its own, at a lower priority.

    For work slower than a frame's maps (peak detection, the display spectrum, matching
    the windows, the displacement estimate): on its own thread it never holds up the
    frames behind it. :meth:`submit` hands over a job
    when the thread is idle; :meth:`take` returns each result once.

    Parameters
    ----------
    name : str
        The thread's name (``holoview-...``).
    work : callable
        What to do with a job (on the thread); a :class:`~holoview.errors.HoloviewError`
        it raises becomes a message.
    what : str
        What the work is, for the messages (``"peak detection"``).
    niceness : int
        Added to the thread's niceness at start (:func:`yield_to_others`).
    """

    def __init__(
        self, name: str, work: Callable[[J], T], what: str, niceness: int = SIDE_NICENESS
    ) -> None:
        self._work = work
        self._what = what
        self._niceness = niceness
        self._cond = threading.Condition()
        self._job: J | None = None
        self._result: tuple[T, float] | None = None
        self._error: str | None = None
        self._busy = False
        self._stop = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        """Start the thread."""
        wait_at_exit(self, alive=True)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Ask the thread to stop (after the job under way) and join it.

        A job that outlasts ``timeout`` runs on; the interpreter's exit waits for it.
        """
        with self._cond:
            self._stop = True
            self._cond.notify()
        if self._thread.ident is not None:
            self._thread.join(timeout)
        wait_at_exit(self, self._thread.is_alive())

    @property
    def busy(self) -> bool:
        """Whether a job is under way."""
        with self._cond:
            return self._busy

    def submit(self, job: J) -> bool:
        """Hand ``job`` to the thread; False, doing nothing, while a job is under way."""
        with self._cond:
            if self._busy:
                return False
            self._busy = True
            self._job = job
            self._cond.notify()
            return True

    def take(self) -> tuple[T, float] | str | None:
        """The newest (result, seconds it took), an error message, or None; each once."""
        with self._cond:
            out: tuple[T, float] | str | None = self._error or self._result
            self._result, self._error = None, None
            return out

    def _run(self) -> None:
        yield_to_others(self._niceness)
        while True:
            with self._cond:
                while self._job is None and not self._stop:
                    self._cond.wait()
                if self._stop or self._job is None:
                    return
                job = self._job
                self._job = None
            tick = time.perf_counter()
            try:
                result = self._work(job)
            except HoloviewError as exc:
                with self._cond:
                    self._error, self._busy = f"{self._what}: {exc}", False
                continue
            except Exception:  # a bug: log it, keep the window running
                logger.exception("%s failed", self._what)
                with self._cond:
                    self._error, self._busy = f"{self._what} failed (see the log)", False
                continue
            with self._cond:
                self._result, self._busy = (result, time.perf_counter() - tick), False


def _detect(job: tuple[np.ndarray, float | None]) -> list[Peak]:
    frame, radius = job
    return find_peaks(frame, radius=radius, threads=FFT_THREADS)


class PeakWorker(SideWorker[tuple[np.ndarray, float | None], list[Peak]]):
    """Find the peaks of one frame at a time on a thread named ``holoview-peaks``."""

    def __init__(self) -> None:
        super().__init__("holoview-peaks", _detect, "peak detection", YIELDING_NICENESS)


def coregistration_work(
    coregistration: Coregistration,
) -> Callable[[CoregistrationJob], Coregistration | None]:
    """The co-registration thread's work: add each job's maps to ``coregistration``."""

    def work(job: CoregistrationJob) -> Coregistration | None:
        return job.run(coregistration)

    return work


def _matcher_in_child() -> Callable[[MatchJob], Rematch | None]:
    """The match process's work (made there): a matcher of its own, its frames kept there."""
    matcher = WindowMatcher()

    def work(job: MatchJob) -> Rematch | None:
        return job.run(matcher)

    return work


class MatchWorker(SideWorker[MatchJob, Rematch | None]):
    """Match the windows to the surface in a process of its own, from ``holoview-match``.

    A measurement takes seconds on a large frame; the maps worker hands a
    :class:`~holoview.engine.window_matching.MatchJob` over (its own copy of the frame)
    and goes on with the maps; the new windows come back through :meth:`take`. The
    thread sends each job to a child process (:class:`~holoview.live.child_work.ChildWork`)
    and waits: the measurement, long and in Python, would otherwise hold the interpreter's
    lock away from the maps, the series and the window for as long as it runs. The child
    yields to every other (:data:`SIDE_NICENESS`): its result may come late.
    """

    def __init__(self) -> None:
        self.child: ChildWork[MatchJob, Rematch | None] = ChildWork(
            _matcher_in_child, "holoview-match", SIDE_NICENESS
        )
        super().__init__("holoview-match", self.child, "window matching")

    def stop(self, timeout: float = 5.0) -> None:
        """End the match process (a measurement under way is dropped), then the thread."""
        self.child.close()
        super().stop(timeout)
