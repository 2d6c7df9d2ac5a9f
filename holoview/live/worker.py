"""The live worker threads: the series, the maps, peak detection.

- The series worker (``holoview-series``) takes *every* frame from the ring and runs a
  :class:`~holoview.live.series_pipeline.SeriesPipeline` on it: the carrier values, so the
  trends, rates and the temporal unwrapping see the camera's full rate; frames the ring
  overwrote before it read them are counted (:meth:`RingWorker.status`), never hidden.
- The maps worker (``holoview-demod``) takes the *newest* frame (the series has the
  others, so a map is never older than it must be), or every frame in order when
  asked (scripted runs, the parity test), and runs a
  :class:`~holoview.live.maps_pipeline.MapsPipeline` on it: the maps, at whatever rate is
  left. It hands the demodulator's peaks to the series worker.
- Peak detection (``holoview-peaks``), the display spectrum (``holoview-spectrum``),
  the windows' match to the surface (``holoview-match``) and the maps' displacement
  estimate (``holoview-coregister``), each slower than a frame's maps, run beside them
  at a lower priority (:class:`SideWorker`); the maps worker takes their results between
  frames, so that no frame's maps wait for them. The match, long and in Python, runs in
  a process of its own (:class:`MatchWorker`): on a thread it held the interpreter's
  lock away from the maps and the window.

Each publishes its newest result under a lock; all stop with a flag (or the ring
closing) and are joined by their ``stop``.
"""

from __future__ import annotations

import atexit
import collections
import logging
import os
import queue
import sys
import threading
import time
import weakref
from collections.abc import Callable
from typing import Any, Generic, Protocol, TypeVar

import numpy as np

from holoview.acquire.ring import CLOSED, FrameRing, RingConsumer, RingStatus
from holoview.acquire.source import FrameMeta
from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FFT_THREADS
from holoview.engine.map_step import Coregistration
from holoview.engine.window_matching import MatchJob, Rematch, WindowMatcher
from holoview.errors import HoloviewError
from holoview.live.child_work import ChildWork
from holoview.live.maps_pipeline import (
    CoregistrationJob,
    LiveResult,
    MapsPipeline,
    spectrum_image,
)
from holoview.live.series_pipeline import SeriesPipeline, TrendSummary
from holoview.processing.peaks.detection import Peak, find_peaks

logger = logging.getLogger(__name__)

#: Most messages kept for the window between two redraws.
MAX_MESSAGES = 20
#: Niceness added to the threads whose rate is whatever is left (maps, peak detection):
#: on a machine with fewer cores than busy threads the series and the window, which
#: must keep up, get the cores first.
YIELDING_NICENESS = 5
#: Frames waiting in the ring for a worker beyond which a replay played as fast as it
#: reads waits for it (:meth:`RingWorker.wait_for_room`).
BACKLOG = 24
#: Longest a replay played as fast as it reads waits for a worker that takes no frames yet
#: (the series and the waves wait for the maps worker's first peaks), seconds: a file
#: whose peaks are never found still plays.
READY_WAIT_S = 10.0
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


#: The type of a worker's results.
R = TypeVar("R")


class RingWorker(Generic[R]):
    """A thread that takes frames from a ring, runs a step on each and publishes the result.

    Subclasses fill in :meth:`_step` (and :meth:`_apply`, for commands). Commands are
    applied between frames; problems the operator can fix are kept as messages, each
    once while it repeats.

    Parameters
    ----------
    ring : FrameRing
        Where frames come from.
    name : str
        The thread's name (``holoview-...``).
    consumer : RingConsumer
        This worker's cursor on the ring.
    """

    #: Niceness the thread adds to its own at start (:func:`yield_to_others`).
    niceness = 0

    def __init__(self, ring: FrameRing, name: str, consumer: RingConsumer) -> None:
        self.ring = ring
        self._consumer = consumer
        self._commands: queue.SimpleQueue[tuple[str, Any]] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._latest: R | None = None
        self._times: collections.deque[float] = collections.deque(maxlen=32)
        self._messages: collections.deque[str] = collections.deque(maxlen=MAX_MESSAGES)
        self._last_error = ""
        self._stop = threading.Event()
        self._room = threading.Condition()  # notified as each frame is taken
        self._taking = False  # taking frames (not waiting for something first, _ready)
        self._taking_since = time.monotonic()  # when it started or stopped taking frames
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        #: Called on this worker's thread after each new result (a window's wake-up).
        self.listener: Callable[[], None] | None = None

    def start(self) -> None:
        """Start the thread."""
        self._taking_since = time.monotonic()
        wait_at_exit(self, alive=True)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Ask the thread to stop and join it (the interpreter's exit waits for a late one)."""
        self._stop.set()
        with self._room:
            self._room.notify_all()
        if self._thread.ident is not None:
            self._thread.join(timeout)
        wait_at_exit(self, self._thread.is_alive())

    @property
    def running(self) -> bool:
        """True while the thread runs."""
        return self._thread.is_alive()

    def backlog(self) -> int:
        """Frames waiting in the ring for this worker."""
        return self._consumer.status().unread

    def wait_for_room(self, stop: threading.Event, limit: int = BACKLOG) -> None:
        """Wait until fewer than ``limit`` frames wait for this worker (at most half the ring).

        A replay played as fast as it reads calls it before each frame for the workers
        that must take every frame: none of them then misses one. A worker that takes no
        frames yet (it waits for something else first) is waited for at most
        :data:`READY_WAIT_S`; it returns at once when the worker or ``stop`` ends.
        """
        limit = max(1, min(limit, self.ring.capacity // 2))
        with self._room:
            while not (stop.is_set() or self._stop.is_set()) and self.backlog() >= limit:
                if self._thread.ident is not None and not self._thread.is_alive():
                    return  # it ended (an internal error); one not started yet starts soon
                if not self._taking and time.monotonic() - self._taking_since > READY_WAIT_S:
                    return
                self._room.wait(0.1)

    def post(self, name: str, value: Any = None) -> None:
        """Queue a command, applied before the next frame."""
        self._commands.put((name, value))

    def status(self) -> RingStatus:
        """The worker's ring accounting (acquired, dropped or skipped, transport losses)."""
        return self._consumer.status()

    def rate_hz(self) -> float:
        """Frames processed per second over the last 32 frames (0 after 2 s without one)."""
        with self._lock:
            times = list(self._times)
        if len(times) < 2 or times[-1] <= times[0]:
            return 0.0
        if time.monotonic() - times[-1] > 2.0:
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0])

    def drain_messages(self) -> list[str]:
        """Return and forget the problems met since the last call."""
        out = []
        while self._messages:
            out.append(self._messages.popleft())
        return out

    def _report(self, text: str) -> None:
        if text != self._last_error:
            self._last_error = text
            self._messages.append(text)

    def _publish(self, result: R | None) -> None:
        """Count a processed frame; keep ``result`` as the newest when it is not None."""
        with self._lock:
            if result is not None:
                self._latest = result
            self._times.append(time.monotonic())
        if result is not None and self.listener is not None:
            self.listener()

    def _apply(self, name: str, value: Any) -> None:
        raise ValueError(f"unknown command {name!r}")

    def _apply_commands(self) -> None:
        while True:
            try:
                name, value = self._commands.get_nowait()
            except queue.Empty:
                return
            try:
                self._apply(name, value)
            except HoloviewError as exc:
                self._report(str(exc))

    def _ready(self) -> bool:
        """Whether to take frames now (a worker that waits for something says False)."""
        return True

    def _step(self, pixels: np.ndarray, meta: FrameMeta) -> None:
        raise NotImplementedError

    def _idle(self) -> None:
        """No frame came for a while, or the ring closed: finish work still under way."""

    def _run(self) -> None:
        if self.niceness:
            yield_to_others(self.niceness)
        try:
            while not self._stop.is_set():
                self._apply_commands()
                taking = self._ready()
                if taking != self._taking:
                    self._taking, self._taking_since = taking, time.monotonic()
                if not taking:
                    self._stop.wait(0.005)
                    continue
                item = self._consumer.get(timeout=0.1)
                with self._room:
                    self._room.notify_all()
                if item is None or item is CLOSED:
                    self._idle()
                if item is CLOSED:
                    break
                if item is None:
                    continue
                try:
                    self._step(*item)
                except HoloviewError as exc:
                    self._report(str(exc))
                    continue
                self._last_error = ""
        except Exception:  # a bug: keep the traceback in the log, end the thread cleanly
            logger.exception("%s failed", self._thread.name)
            self._messages.append(
                f"{self._thread.name} stopped after an internal error (see the log)"
            )


class DemodWorker(RingWorker[LiveResult]):
    """The maps: a :class:`MapsPipeline` on the newest frame, on ``holoview-demod``.

    Parameters
    ----------
    ring : FrameRing
        Frames to process (a ``"newest"`` consumer).
    pipeline : MapsPipeline
        What to do with each frame; commands (``experiment``, ``reset``) between frames.
    every_frame : bool
        Take every frame in order (an ``"every"`` consumer) instead of the newest.
    """

    niceness = YIELDING_NICENESS

    def __init__(self, ring: FrameRing, pipeline: MapsPipeline, every_frame: bool = False) -> None:
        if every_frame:
            consumer = ring.consumer("maps", mode="every")
        else:
            consumer = ring.consumer("maps", mode="newest")
        super().__init__(ring, "holoview-demod", consumer)
        self.pipeline = pipeline
        pipeline.detect_inline = False
        self.peaks = PeakWorker()
        pipeline.side_work_inline = False
        self.spectra: SideWorker[np.ndarray, np.ndarray] = SideWorker(
            "holoview-spectrum", spectrum_image, "the spectrum"
        )
        self.matches = MatchWorker()
        self.coregistration: SideWorker[CoregistrationJob, Coregistration | None] = SideWorker(
            "holoview-coregister",
            coregistration_work(Coregistration(None)),
            "co-registration",
        )
        self._peak_set: tuple[tuple[Peak, ...], Experiment] | None = None

    def start(self) -> None:
        """Start the thread and its side threads."""
        self.peaks.start()
        self.matches.start()
        self.spectra.start()
        self.coregistration.start()
        super().start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop and join the thread and its side threads."""
        super().stop(timeout)
        self.peaks.stop(timeout)
        self.matches.stop(timeout)
        self.spectra.stop(timeout)
        self.coregistration.stop(timeout)

    def latest(self) -> LiveResult | None:
        """The newest result, or None before the first."""
        with self._lock:
            return self._latest

    def peak_set(self) -> tuple[tuple[Peak, ...], Experiment] | None:
        """The demodulator's peaks and the experiment after the last frame; None before."""
        with self._lock:
            return self._peak_set

    def _apply(self, name: str, value: Any) -> None:
        self.pipeline.apply(name, value)

    def _exchange_peaks(self, pixels: np.ndarray) -> None:
        """Hand the newest detected peaks to the pipeline; start a detection when due."""
        found = self.peaks.take()
        if isinstance(found, str):
            self._report(found)
        elif found is not None:
            self.pipeline.set_peaks(found[0])
            self.pipeline.peaks_done(found[1])
        due = self.pipeline.peaks_due()
        if due and self.peaks.submit((pixels, self.pipeline.experiment.fixed_radius)):
            self.pipeline.peaks_started()

    def _hand_over(self, side: SideWorker[Any, T], use: Callable[[T, float], object]) -> None:
        """Give ``side``'s newest result and its seconds to ``use`` (a frame boundary), or
        report its error."""
        found = side.take()
        if isinstance(found, str):
            self._report(found)
        elif found is not None:
            use(*found)

    def _step(self, pixels: np.ndarray, meta: FrameMeta) -> None:
        self._exchange_peaks(pixels)
        self._hand_over(self.matches, self.pipeline.use_match)
        self._hand_over(self.coregistration, self.pipeline.use_coregistration)
        self._hand_over(self.spectra, self.pipeline.use_spectrum)
        try:
            result = self.pipeline.process(pixels, meta)
        finally:
            with self._lock:
                self._peak_set = (self.pipeline.peaks, self.pipeline.experiment)
        self._publish(result)
        # the side work due, each dropped while its thread is busy (due again soon)
        coregistration = self.pipeline.coregistration_job()
        if coregistration is not None:
            self.coregistration.submit(coregistration)
        spectrum = self.pipeline.spectrum_job()
        if spectrum is not None:
            self.spectra.submit(spectrum)
        if not self.matches.busy:  # the measurement due, if any, after the maps are out
            job = self.pipeline.match_job(pixels)
            if job is not None:
                self.matches.submit(job)


class SeriesWorker(RingWorker[TrendSummary]):
    """The series: a :class:`SeriesPipeline` on every frame, on ``holoview-series``.

    It takes no frame until the maps worker has resolved its first set of peaks (the
    frames wait in the ring), so a series starts at the stream's first frame; it then
    follows the maps worker's peaks, a new series for each new set.

    Parameters
    ----------
    ring : FrameRing
        Frames to measure (an ``"every"`` consumer: overwritten frames are counted).
    pipeline : SeriesPipeline
        What to do with each frame; commands (``pca``, ``reset``) between frames.
    maps : DemodWorker
        Where the peaks come from.
    """

    def __init__(self, ring: FrameRing, pipeline: SeriesPipeline, maps: DemodWorker) -> None:
        super().__init__(ring, "holoview-series", ring.consumer("series", mode="every"))
        self.pipeline = pipeline
        self.maps = maps

    def latest(self) -> TrendSummary | None:
        """The newest trends summary, or None before the first."""
        with self._lock:
            return self._latest

    def _apply(self, name: str, value: Any) -> None:
        self.pipeline.apply(name, value)

    def _ready(self) -> bool:
        peak_set = self.maps.peak_set()
        if peak_set is None:  # no peaks yet: wait, unless the maps worker has ended
            return not self.maps.running
        self.pipeline.set_peaks(*peak_set)
        return True

    def _step(self, pixels: np.ndarray, meta: FrameMeta) -> None:
        self._publish(self.pipeline.process(pixels, meta))
