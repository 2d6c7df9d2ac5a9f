"""The live workers: threads that take frames from the ring, the series and the maps.

- The series worker (``holoview-series``) takes *every* frame from the ring and has a
  :class:`~holoview.live.series_pipeline.SeriesPipeline` run on it, in a process of its
  own (``holoview-series``, :mod:`holoview.live.series_server`): the carrier values, so
  the trends, rates and the temporal unwrapping see the camera's full rate; frames the
  ring overwrote before it read them are counted (:meth:`RingWorker.status`), never
  hidden.
- The maps worker (``holoview-demod``) takes the *newest* frame (the series has the
  others, so a map is never older than it must be), or every frame in order when
  asked (scripted runs, the parity test), and has a
  :class:`~holoview.live.maps_server.MapsServer` make its maps, in a process of its own
  (``holoview-maps``): the maps, with their side work (peak detection, the display
  spectrum, the windows' match, the displacement estimate:
  :mod:`holoview.live.side_workers`), at whatever rate is left. It hands the
  demodulator's peaks to the series worker.

Each publishes its newest result under a lock; all stop with a flag (or the ring
closing) and are joined by their ``stop``.
"""

from __future__ import annotations

import collections
import functools
import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any, Generic, TypeVar

import numpy as np

from holoview.acquire.ring import CLOSED, FrameRing, RingConsumer, RingStatus
from holoview.acquire.source import FrameMeta
from holoview.engine.depth import DepthSummary
from holoview.engine.experiment import Experiment
from holoview.engine.series import PhaseSeries
from holoview.errors import HoloviewError
from holoview.live import series_pipeline
from holoview.live.child_work import ChildWork
from holoview.live.maps_pipeline import LiveResult
from holoview.live.maps_server import MapsJob, MapsReply, MapsServer, SlotServer
from holoview.live.series_pipeline import SeriesPipeline, TrendSummary
from holoview.live.series_server import SeriesJob, SeriesReply, SlotSeries
from holoview.live.side_workers import YIELDING_NICENESS, wait_at_exit, yield_to_others
from holoview.live.wave_map import FrameSlot
from holoview.processing.peaks.detection import Peak

logger = logging.getLogger(__name__)

#: Most messages kept for the window between two redraws.
MAX_MESSAGES = 20
#: Frames waiting in the ring for a worker beyond which a replay played as fast as it
#: reads waits for it (:meth:`RingWorker.wait_for_room`).
BACKLOG = 24
#: Longest a replay played as fast as it reads waits for a worker that takes no frames yet
#: (the series and the waves wait for the maps worker's first peaks), seconds: a file
#: whose peaks are never found still plays.
READY_WAIT_S = 10.0

#: The type of a worker's results.
R = TypeVar("R")
#: The types of a child process's jobs and replies.
J = TypeVar("J")
T = TypeVar("T")


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
        #: Where frames are read to (None: a copy each); the frame is only valid until the next.
        self._out: np.ndarray | None = None
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
                item = self._consumer.get(timeout=0.1, out=self._out)
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


class ChildRingWorker(RingWorker[R], Generic[R, J, T]):
    """A ring worker whose work runs in a child process, on frames in shared memory.

    The thread puts each frame in a one-frame :class:`~holoview.live.wave_map.FrameSlot`
    and waits, without the interpreter's lock, for the child's reply. A child that ended
    (killed, out of memory) is said once and started again at the next frame. Subclasses
    make the child (:meth:`_start_child`) and keep their work on the thread where no
    process or shared memory can be had.
    """

    def __init__(self, ring: FrameRing, name: str, consumer: RingConsumer) -> None:
        super().__init__(ring, name, consumer)
        #: The child process (None where the work runs on the thread).
        self.child: ChildWork[J, T] | None = None
        self._slot: FrameSlot | None = None

    def _start_child(self, slot: FrameSlot) -> ChildWork[J, T]:
        raise NotImplementedError

    def _open_child(self, what: str) -> None:
        """Make the slot and start the child; log ``what`` runs on the thread where neither
        can be had."""
        try:
            self._slot = FrameSlot(self.ring.frame_shape, self.ring.dtype, 1)
            self.child = self._start_child(self._slot)
        except OSError as exc:  # no shared memory or no process here: on the thread
            logger.warning("%s in the window's process: %s", what, exc)
            self._close_child()

    def _close_child(self) -> None:
        child, self.child = self.child, None
        if child is not None:
            child.close()
        slot, self._slot = self._slot, None
        self._out = None
        if slot is not None:
            slot.close()

    def _exchange(self, job: Callable[[FrameSlot], J], what: str) -> T:
        """``job(slot)``'s reply from the child (one started again if it had ended): the job
        is made after that, its frame put in the slot by it where need be."""
        assert self.child is not None and self._slot is not None
        if self.child.pid is None and not self._stop.is_set():  # it ended: a new one
            self.child.close()
            self.child = self._start_child(self._slot)
        try:
            self.child.submit(job(self._slot))
            return self.child.result()
        except HoloviewError as exc:
            if self.child.pid is None and not self._stop.is_set():
                logger.warning("%s: %s", what, exc)  # said once: the next frame starts a new one
            raise


class DemodWorker(ChildRingWorker[LiveResult, MapsJob, MapsReply]):
    """The maps: a :class:`~holoview.live.maps_server.MapsServer` on the newest frame.

    The server runs in a process of its own (``holoview-maps``): the thread
    (``holoview-demod``) takes the newest frame, puts it in shared memory and waits,
    without the interpreter's lock, for the maps. Where no process or shared memory can
    be had (a sandbox), or when asked, the server runs on the thread, as it did before.
    A maps process that ends (killed, out of memory) is said once and started again at
    the next frame (its peaks found again: the maps and the series restart).

    Parameters
    ----------
    ring : FrameRing
        Frames to process (a ``"newest"`` consumer).
    experiment : Experiment
        The settings to start with; commands (``experiment``, ``reset``, ``match``)
        are applied before the next frame.
    saturation : float, optional
        Raw value at which the camera saturates.
    every_frame : bool
        Take every frame in order (an ``"every"`` consumer) instead of the newest.
    in_process : bool
        Run the server on the thread rather than in a process of its own.
    """

    def __init__(
        self,
        ring: FrameRing,
        experiment: Experiment,
        saturation: float | None = None,
        every_frame: bool = False,
        in_process: bool = False,
    ) -> None:
        if every_frame:
            consumer = ring.consumer("maps", mode="every")
        else:
            consumer = ring.consumer("maps", mode="newest")
        super().__init__(ring, "holoview-demod", consumer)
        self._experiment = experiment
        self._saturation = saturation
        self._in_process = in_process
        #: The server, where it runs on the thread (None while it runs in its process).
        self.server: MapsServer | None = None
        self._pending: list[tuple[str, Any]] = []
        self._peak_set: tuple[tuple[Peak, ...], Experiment] | None = None
        self._reference_mode: str | None = None
        #: The display spectrum the maps process sent last (results that keep it share it).
        self._spectrum: np.ndarray | None = None

    def start(self) -> None:
        """Start the maps process (or the server on the thread) and the thread."""
        if not self._in_process:
            self._open_child("the maps run")
        if self.child is None:
            self.server = MapsServer(self._experiment, self.ring.frame_shape, self._saturation)
            self.niceness = YIELDING_NICENESS  # the thread makes the maps: it yields
        super().start()

    def wait_ready(self, timeout: float = READY_WAIT_S) -> None:
        """Wait up to ``timeout`` s for the maps process to be ready for frames (it takes a
        second or two to start): the camera starts after it, so that the series, which
        waits for the first peaks, misses no frame meanwhile. A process that failed to
        start is started again with the first frame."""
        if self.child is None:
            return
        try:
            self.child.wait_ready(timeout)
        except HoloviewError as exc:
            logger.warning("maps: %s", exc)

    def _start_child(self, slot: FrameSlot) -> ChildWork[MapsJob, MapsReply]:
        """A maps process on ``slot``'s frames with the experiment in force, started."""
        make = functools.partial(SlotServer, slot.shared, self._experiment, self._saturation)
        # not daemonic: it starts the match's process; ended by stop
        child: ChildWork[MapsJob, MapsReply] = ChildWork(
            make, "holoview-maps", YIELDING_NICENESS, daemon=False
        )
        child.start()
        return child

    def stop(self, timeout: float = 5.0) -> None:
        """End the maps process (a frame under way is dropped), then stop and join the
        thread (or the server's side threads)."""
        self._stop.set()  # no maps process is started again from now on
        if self.child is not None:
            self.child.close()  # the thread's wait for it ends now
        super().stop(timeout)
        if self.server is not None:
            self.server.stop(timeout)
        if not self._thread.is_alive():
            self._close_child()

    def latest(self) -> LiveResult | None:
        """The newest result, or None before the first."""
        with self._lock:
            return self._latest

    def peak_set(self) -> tuple[tuple[Peak, ...], Experiment] | None:
        """The demodulator's peaks and the experiment after the last frame; None before."""
        with self._lock:
            return self._peak_set

    def reference_mode(self) -> str | None:
        """The demodulator's reference mode after the last frame (None before one)."""
        with self._lock:
            return self._reference_mode

    def _apply(self, name: str, value: Any) -> None:
        if name == "experiment" and isinstance(value, Experiment):
            self._experiment = value  # a maps process started again starts with it
        self._pending.append((name, value))  # applied with the next frame

    def _step(self, pixels: np.ndarray, meta: FrameMeta) -> None:
        commands, self._pending = tuple(self._pending), []
        if self.server is not None:
            reply = self.server.step(pixels, meta, commands)
        else:
            reply = self._in_child(pixels, meta, commands)
        for message in reply.messages:
            self._report(message)
        with self._lock:
            self._peak_set = reply.peak_set
            self._reference_mode = reply.reference_mode
        if reply.result is not None:
            if reply.spectrum_kept:
                self._publish(replace(reply.result, frame=pixels, spectrum=self._spectrum))
            else:
                self._spectrum = reply.result.spectrum
                self._publish(replace(reply.result, frame=pixels))

    def _in_child(
        self, pixels: np.ndarray, meta: FrameMeta, commands: tuple[tuple[str, Any], ...]
    ) -> MapsReply:
        """The frame's maps from the maps process."""

        def job(slot: FrameSlot) -> MapsJob:
            slot.put(0, pixels)
            return MapsJob(0, meta, commands)

        return self._exchange(job, "maps")


class SeriesWorker(ChildRingWorker[TrendSummary, SeriesJob, SeriesReply]):
    """The series: a :class:`SeriesPipeline` on every frame, in a process of its own.

    The thread (``holoview-series``) reads each frame from the ring straight into shared
    memory and waits, without the interpreter's lock, for the series process
    (``holoview-series``, :mod:`holoview.live.series_server`) to add it. Where no process
    or shared memory can be had (a sandbox), or when asked, the pipeline runs on the
    thread. A series process that ends (killed, out of memory) is said once and started
    again at the next frame: a new series. When the thread ends (stopped, or the stream
    ended), the series comes back for :meth:`summary` and :attr:`series`.

    It takes no frame until the maps worker has resolved its first set of peaks (the
    frames wait in the ring), so a series starts at the stream's first frame; it then
    follows the maps worker's peaks, a new series for each new set.

    Parameters
    ----------
    ring : FrameRing
        Frames to measure (an ``"every"`` consumer: overwritten frames are counted).
    maps : DemodWorker
        Where the peaks come from.
    saturation : float, optional
        Raw value at which the camera saturates.
    in_process : bool
        Run the pipeline on the thread rather than in a process of its own.
    """

    def __init__(
        self,
        ring: FrameRing,
        maps: DemodWorker,
        saturation: float | None = None,
        in_process: bool = False,
    ) -> None:
        super().__init__(ring, "holoview-series", ring.consumer("series", mode="every"))
        self.maps = maps
        self._saturation = saturation
        self._in_process = in_process
        #: The pipeline, where it runs on the thread (None while it runs in its process).
        self.pipeline: SeriesPipeline | None = None
        self._peak_set: tuple[tuple[Peak, ...], Experiment] | None = None
        self._sent: tuple[tuple[Peak, ...], Experiment] | None = None  # the child's peaks
        self._pending: list[tuple[str, Any]] = []
        self._pca = False
        self._end: SeriesReply | None = None
        #: The id of the last frame the series took (None before one).
        self.last_frame: int | None = None

    def start(self) -> None:
        """Start the series process (or the pipeline on the thread) and the thread."""
        if not self._in_process:
            self._open_child("the series runs")
        if self._slot is not None:
            self._out = self._slot.frame(0)  # frames are read into the slot itself
        if self.child is None:
            self.pipeline = SeriesPipeline(self.ring.frame_shape, saturation=self._saturation)
        super().start()

    def _start_child(self, slot: FrameSlot) -> ChildWork[SeriesJob, SeriesReply]:
        # the summaries' rate in force here (a test may change it)
        make = functools.partial(
            SlotSeries, slot.shared, self._saturation, series_pipeline.TREND_HZ
        )
        child: ChildWork[SeriesJob, SeriesReply] = ChildWork(make, "holoview-series", 0)
        child.start()
        self._sent = None  # a new process has no peaks yet, nor the PCA setting
        self._pending = [("pca", True)] if self._pca else []
        return child

    def stop(self, timeout: float = 5.0) -> None:
        """Stop and join the thread (it brings the series back), then end the process."""
        super().stop(timeout)
        self._close_child()

    def latest(self) -> TrendSummary | None:
        """The newest trends summary, or None before the first."""
        with self._lock:
            return self._latest

    @property
    def series(self) -> PhaseSeries | None:
        """The series: while running on the thread, else once the thread has ended."""
        if self.pipeline is not None:
            return self.pipeline.series
        return None if self._end is None else self._end.series

    def summary(self) -> DepthSummary | None:
        """Depths and rates of the series (as :attr:`series`); None before three frames.

        Raises
        ------
        HoloviewError
            The series cannot be summarised (the message says why).
        """
        if self.pipeline is not None:
            return self.pipeline.summary()
        if self._end is not None and self._end.problem is not None:
            raise HoloviewError(self._end.problem)
        return None if self._end is None else self._end.summary

    def _apply(self, name: str, value: Any) -> None:
        if self.pipeline is not None:
            self.pipeline.apply(name, value)
            return
        if name not in series_pipeline.COMMANDS:  # as the pipeline would say
            raise ValueError(f"unknown series command {name!r}")
        if name == "pca":
            self._pca = bool(value)  # for a process started again
        self._pending.append((name, value))  # sent with the next frame

    def _ready(self) -> bool:
        peak_set = self.maps.peak_set()
        if peak_set is None:  # no peaks yet: wait, unless the maps worker has ended
            return not self.maps.running
        self._peak_set = peak_set
        if self.pipeline is not None:
            self.pipeline.set_peaks(*peak_set)
        return True

    def _step(self, pixels: np.ndarray, meta: FrameMeta) -> None:
        self.last_frame = meta.frame_id
        if self.pipeline is not None:
            self._publish(self.pipeline.process(pixels, meta))
            return
        self._publish(self._in_child(meta).trend)

    def _in_child(self, meta: FrameMeta | None) -> SeriesReply:
        """A job for the series process (the frame is in the slot already)."""

        def job(_: FrameSlot) -> SeriesJob:  # after a restart: the new process's peaks
            peak_set = None if self._peak_set is self._sent else self._peak_set
            commands, self._pending = tuple(self._pending), []
            return SeriesJob(meta, peak_set, commands)

        reply = self._exchange(job, "series")
        self._sent = self._peak_set
        return reply

    def _run(self) -> None:
        super()._run()
        if self.child is None:
            return
        try:  # the series comes back for the session's summary
            self._end = self._in_child(None)
        except HoloviewError as exc:
            logger.warning("the series could not be brought back: %s", exc)
