"""The live worker threads: demodulation (``holoview-demod``), peak detection (``holoview-peaks``).

The demodulation worker takes the *newest* frame from the ring (in order while at most
:data:`PROCESSING_MAX_LAG` frames wait, so one slow frame costs a little latency rather
than a gap in the series), or every frame in order when asked (scripted runs, the
parity test), runs a :class:`~holoview.live.pipeline.LivePipeline` on it and publishes
the result under a lock; peak detection, much slower than a frame, runs beside it.
Both stop with a flag (or the ring closing) and are joined by their ``stop``.
"""

from __future__ import annotations

import collections
import logging
import queue
import threading
import time
from typing import Any

import numpy as np

from holoview.acquire.ring import CLOSED, FrameRing, RingConsumer, RingStatus
from holoview.errors import HoloviewError
from holoview.live.pipeline import FFT_THREADS, LivePipeline, LiveResult
from holoview.processing.peaks import Peak, find_peaks

logger = logging.getLogger(__name__)

#: Most messages kept for the window between two redraws.
MAX_MESSAGES = 20


class PeakWorker:
    """Find the peaks of one frame at a time on a thread named ``holoview-peaks``.

    Peak detection takes much longer than demodulating a frame; on its own thread it
    never holds up the frames behind it. :meth:`submit` hands over a frame when the
    thread is idle; :meth:`take` returns each result once.
    """

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._job: tuple[np.ndarray, float] | None = None
        self._result: tuple[list[Peak], float] | None = None
        self._error: str | None = None
        self._busy = False
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="holoview-peaks", daemon=True)

    def start(self) -> None:
        """Start the thread."""
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Ask the thread to stop (after the detection under way) and join it."""
        with self._cond:
            self._stop = True
            self._cond.notify()
        if self._thread.ident is not None:
            self._thread.join(timeout)

    def submit(self, frame: np.ndarray, radius: float) -> bool:
        """Detect the peaks of ``frame`` (not modified) with window radius ``radius``.

        Returns False, doing nothing, while a detection is under way.
        """
        with self._cond:
            if self._busy:
                return False
            self._busy = True
            self._job = (frame, radius)
            self._cond.notify()
            return True

    def take(self) -> tuple[list[Peak], float] | str | None:
        """The newest (peaks, seconds it took), an error message, or None; each once."""
        with self._cond:
            out: tuple[list[Peak], float] | str | None = self._error or self._result
            self._result, self._error = None, None
            return out

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._job is None and not self._stop:
                    self._cond.wait()
                if self._stop:
                    return
                frame, radius = self._job  # type: ignore[misc]
                self._job = None
            tick = time.perf_counter()
            try:
                peaks = find_peaks(frame, radius=radius, threads=FFT_THREADS)
            except HoloviewError as exc:
                with self._cond:
                    self._error, self._busy = f"peak detection: {exc}", False
                continue
            except Exception:  # a bug: log it, keep the window running
                logger.exception("peak detection failed")
                with self._cond:
                    self._error, self._busy = "peak detection failed (see the log)", False
                continue
            with self._cond:
                self._result, self._busy = (peaks, time.perf_counter() - tick), False


#: Frames the worker may fall behind the newest before it skips (2: 33 ms at 60 frames/s).
PROCESSING_MAX_LAG = 2


class DemodWorker:
    """Run a pipeline on the newest frame of a ring, on a thread named ``holoview-demod``.

    Parameters
    ----------
    ring : FrameRing
        Frames to process (a ``"newest"`` consumer with :data:`PROCESSING_MAX_LAG`
        is made at construction).
    pipeline : LivePipeline
        What to do with each frame; commands are applied between frames.
    every_frame : bool
        Take every frame in order (an ``"every"`` consumer) instead of the newest.
    """

    def __init__(self, ring: FrameRing, pipeline: LivePipeline, every_frame: bool = False) -> None:
        self.pipeline = pipeline
        pipeline.detect_inline = False
        self.peaks = PeakWorker()
        if every_frame:
            self._consumer: RingConsumer = ring.consumer("processing", mode="every")
        else:
            self._consumer = ring.consumer("processing", mode="newest", max_lag=PROCESSING_MAX_LAG)
        self._commands: queue.SimpleQueue[tuple[str, Any]] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._latest: LiveResult | None = None
        self._times: collections.deque[float] = collections.deque(maxlen=32)
        self._messages: collections.deque[str] = collections.deque(maxlen=MAX_MESSAGES)
        self._last_error = ""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="holoview-demod", daemon=True)

    def start(self) -> None:
        """Start the thread (and its peak thread)."""
        self.peaks.start()
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Ask the thread to stop and join it (and its peak thread)."""
        self._stop.set()
        if self._thread.ident is not None:
            self._thread.join(timeout)
        self.peaks.stop(timeout)

    @property
    def running(self) -> bool:
        """True while the thread runs."""
        return self._thread.is_alive()

    def post(self, name: str, value: Any = None) -> None:
        """Queue a command for the pipeline (``experiment``, ``pca``, ``reset``)."""
        self._commands.put((name, value))

    def latest(self) -> LiveResult | None:
        """The newest result, or None before the first."""
        with self._lock:
            return self._latest

    def status(self) -> RingStatus:
        """The worker's ring accounting (acquired, skipped by design, transport losses)."""
        return self._consumer.status()

    def rate_hz(self) -> float:
        """Frames processed per second over the last 32 frames."""
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

    def _apply_commands(self) -> None:
        while True:
            try:
                name, value = self._commands.get_nowait()
            except queue.Empty:
                return
            try:
                self.pipeline.apply(name, value)
            except HoloviewError as exc:
                self._report(str(exc))

    def _exchange_peaks(self, pixels: np.ndarray) -> None:
        """Hand the newest detected peaks to the pipeline; start a detection when due."""
        found = self.peaks.take()
        if isinstance(found, str):
            self._report(found)
        elif found is not None:
            self.pipeline.set_peaks(found[0])
            self.pipeline.peaks_done(found[1])
        due = self.pipeline.peaks_due()
        if due and self.peaks.submit(pixels, self.pipeline.experiment.radius):
            self.pipeline.peaks_started()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                self._apply_commands()
                item = self._consumer.get(timeout=0.1)
                if item is CLOSED:
                    break
                if item is None:
                    continue
                pixels, meta = item
                self._exchange_peaks(pixels)
                try:
                    result = self.pipeline.process(pixels, meta)
                except HoloviewError as exc:
                    self._report(str(exc))
                    continue
                self._last_error = ""
                with self._lock:
                    self._latest = result
                    self._times.append(time.monotonic())
        except Exception:  # a bug: keep the traceback in the log, end the thread cleanly
            logger.exception("demodulation worker failed")
            self._messages.append("processing stopped after an internal error (see the log)")
