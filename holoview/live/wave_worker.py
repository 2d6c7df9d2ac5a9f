"""The Waves panel's worker: one chosen map from every camera frame, and its analyses, Qt-free.

The maps worker takes the newest frame at whatever rate is left, so its maps come
irregularly spaced and, on a slow machine, at a fraction of the camera's rate; a
spectrum needs them evenly spaced. The waves worker (``holoview-waves``) therefore takes
*every* frame from the ring itself and has the one map the panel shows (a labelled
peak's, or the fused map of every peak with a height) made in a process of its own
(:mod:`holoview.live.wave_map`: the engine's per-frame core, its window's radius held;
the frame passed in shared memory, the thread waiting without the interpreter's lock),
into a :class:`~holoview.live.wave_window.WaveHistory`:

- every frame while a map takes less than the camera's frame interval (``stride`` 1);
  else every second frame (``frame_id`` even), every fourth, ...: the maps stay evenly
  spaced at ``camera rate / stride`` and the panel says that the frequency axis ends at
  half that rate. The stride rises when a map takes longer than the time between two
  kept frames and :data:`RISE_BACKLOG` of the ring waits (a map that waits for a core
  now and then is caught up), to the smallest at which it takes :data:`TARGET_BUSY` of
  it; it falls only to a stride at which a map would take at most :data:`RELAX_BUSY` (a
  band between the two, since each change of stride starts the window again and a map
  costs more where more are made). Once a smaller stride has sufficed for
  :data:`RELAX_S` seconds the stride becomes the largest that was needed meanwhile (one
  step); a smaller stride that had to be left again within :data:`HELD_S` is next tried
  twice as late (up to :data:`MAX_RELAX_S`), so that a machine at the edge settles on
  the stride it keeps.
- a replay played as fast as it reads waits for it
  (:meth:`~holoview.live.worker.RingWorker.wait_for_room`), so a replay at full speed
  fills the panel from every frame;
- frames lost before it read them are gaps in the history (by the frame times),
  never closed; a replay's jump, or a demodulator rebuilt (new peaks: its reference
  starts again), starts the history again.

A second thread (``holoview-waves-fit``) analyses the history at most :data:`WAVES_HZ`
times a second, and less often when an analysis takes more than :data:`FIT_SHARE` of the
time, or :data:`FIT_SHARE_BEHIND` while the maps keep fewer frames than the camera gives
(the cores go to the maps first); the analyses are
:func:`~holoview.live.wave_window.analyse_window`, the functions of ``holoview waves``.
The map's process, like the maps worker and the analyses, yields to the series and the
window, which must keep up and hold the numbers the operator trusts
(:data:`MAP_NICENESS`); its stride follows what it is left. A map costs one carrier window of one
frame: the frame's row FFTs, the column FFTs under that window alone
(:class:`~holoview.processing.fourier.half_spectrum.HalfSpectrum`) and one box's inverse
FFT. A map's process that ends (killed) is said in the panel and started again at the
next frame, its window anew.
"""

from __future__ import annotations

import collections
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from holoview.acquire.ring import FrameRing
from holoview.acquire.source import FrameMeta
from holoview.engine.experiment import Experiment
from holoview.engine.series import frame_time
from holoview.errors import HoloviewError
from holoview.live.child_work import ChildWork
from holoview.live.continuity import Continuity
from holoview.live.side_workers import YIELDING_NICENESS, wait_at_exit, yield_to_others
from holoview.live.wave_map import FrameSlot, WaveJob, WaveMap
from holoview.live.wave_window import (
    LiveWaves,
    WaveHistory,
    WaveSettings,
    analyse_window,
)
from holoview.live.worker import DemodWorker, RingWorker
from holoview.processing.peaks.detection import Peak

logger = logging.getLogger(__name__)

__all__ = [
    "FIT_SHARE",
    "FIT_SHARE_BEHIND",
    "MAX_STRIDE",
    "RELAX_BUSY",
    "RISE_BACKLOG",
    "TARGET_BUSY",
    "WAVES_HZ",
    "WavesWorker",
]

#: Highest rate of the analyses, Hz.
WAVES_HZ = 1.0
#: Most of the time the analyses may take (they run less often when slower).
FIT_SHARE = 0.25
#: Most of the time the analyses may take while the stride is above 1. An analysis of 256
#: maps of 180 x 180 takes 0.32 s of CPU (2-core AVX2, ``benchmarks/bench_wave_map.py``):
#: at FIT_SHARE a quarter of a core, most of what a 60 frames/s camera's maps need beside
#: the series and the window on two cores.
FIT_SHARE_BEHIND = 0.1
#: Largest stride (camera frames per map).
MAX_STRIDE = 16
#: Share of the time between two kept frames a map takes at the stride chosen when it had
#: to rise (median of the last 16); it rises once a map takes more than all of it. A map is
#: timed as this thread's time per kept frame, the map's process making the previous one
#: meanwhile; the ring holds seconds of frames against a map that comes late now and then.
TARGET_BUSY = 0.9
#: Share a map must take at most, timed at the stride in use, for a smaller stride to be
#: tried. On two cores (``benchmarks/bench_gui.py --waves RB1``) a map timed 15 ms of a
#: 16.7 ms interval at stride 1 and 31 ms at stride 2; with one bound (0.9) for both ways
#: the stride went 1, 2, 1, 2, 4, 2, 4 in 30 s, each change the window anew.
RELAX_BUSY = 0.7
#: Share of the ring's frames that must wait before a map's cost raises the stride. Maps
#: that wait for a core now and then time over the interval for a while, the backlog
#: staying a few frames (``benchmarks/bench_gui.py --waves RB1``, 2 cores: 16 maps timed
#: 2-26 ms, median 17.5, against 16.7); a machine too slow falls behind steadily.
RISE_BACKLOG = 1 / 8
#: Maps timed (since the demodulator was built) before the stride follows their cost.
MIN_COSTS = 8
#: Niceness of the map's process: after the series and the window, which must keep up and
#: hold the numbers the operator trusts; with the maps worker. At 3 the series missed up
#: to 393 frames in 20 s (``benchmarks/bench_gui.py --waves RB1``, 2 cores); at 5, 0-115,
#: the panel keeping 32-34 maps/s (1 camera frame in 2 at 60 frames/s).
MAP_NICENESS = YIELDING_NICENESS
#: Frames whose maps are under way at once: the map's process makes one while this thread
#: hands over the next.
IN_FLIGHT = 2
#: Seconds a smaller stride must have sufficed before the stride is lowered to it.
RELAX_S = 5.0
#: Seconds a smaller stride must hold for the next one to be tried as soon again. The maps
#: are timed over the last 16: a stride that a machine cannot keep is left 5-7 s after it
#: was tried (``benchmarks/bench_gui.py --waves RB1``, two cores), which a bound of
#: :data:`RELAX_S` did not count as failing, so the stride went 1, 2, 1, 2 every 5-6 s.
HELD_S = 15.0
#: Longest wait before a smaller stride is tried again after it failed.
MAX_RELAX_S = 80.0


@dataclass(frozen=True)
class _Sent:
    """A frame whose map is being made: what its history entry needs besides the map."""

    t: float
    frame_id: int
    jumped: bool


class WavesWorker(RingWorker[LiveWaves]):
    """Demodulate one map from every frame (or every ``stride``-th) and analyse the last N.

    Parameters
    ----------
    ring : FrameRing
        Frames (an ``"every"`` consumer named ``waves``).
    maps : DemodWorker
        Where the peaks, the experiment and the detected carriers come from.
    frame_shape : (int, int)
        Frames' ``(rows, cols)``, pixels.
    settings : WaveSettings
        The map and the analyses.
    saturation : float, optional
        Raw value at which the camera saturates.
    """

    niceness = 0  # must keep up (module docstring); its analyses yield

    def __init__(
        self,
        ring: FrameRing,
        maps: DemodWorker,
        frame_shape: tuple[int, int],
        settings: WaveSettings,
        saturation: float | None = None,
    ) -> None:
        super().__init__(ring, "holoview-waves", ring.consumer("waves", mode="every"))
        self.maps = maps
        self.frame_shape = frame_shape
        self.saturation = saturation
        self.settings = settings
        self.history = WaveHistory(settings.length)
        self.history.label = settings.label
        self.stride = 1
        self._slot: FrameSlot | None = None
        self._child: ChildWork[WaveJob, WaveMap] | None = None
        self._restart = False  # the next map starts a new sequence (a jump, a new stride)
        self._in_flight: collections.deque[_Sent] = collections.deque()
        self._sent = 0
        self._backlog_at_change = 0  # frames waiting at the last change of stride
        self._cannot = "the waves worker has not started"
        self._continuity = Continuity()
        self._costs: collections.deque[float] = collections.deque(maxlen=16)  # s per map
        self._cpu: collections.deque[float] = collections.deque(maxlen=16)  # CPU s per map
        self._relaxed_since: float | None = None
        self._relax_to = 1
        self._relax_s = RELAX_S  # the wait before a smaller stride is tried
        self._lowered_at = -math.inf  # when the stride was last lowered
        #: True while the source waits for this worker (a replay played as fast as it
        #: reads, :meth:`wait_for_room`): every frame is then kept, whatever a map costs,
        #: also for the frames still in the ring once the replay has reached its end.
        self.paced: Callable[[], bool] = lambda: False
        self._camera_times: collections.deque[float] = collections.deque(maxlen=65)
        self._problem: str | None = None
        self._waves: LiveWaves | None = None
        self._seq = 0
        self._fit_wake = threading.Event()
        self._fit_thread = threading.Thread(
            target=self._fit_loop, name="holoview-waves-fit", daemon=True
        )

    # ---- life cycle ----------------------------------------------------------
    def start(self) -> None:
        """Start the thread, its analysis thread and the map's process (it starts meanwhile)."""
        try:
            self._slot = FrameSlot(self.frame_shape, self.ring.dtype, IN_FLIGHT)
            self._child = ChildWork(
                self._slot.child_work(self.saturation), "holoview-waves-map", MAP_NICENESS
            )
            self._child.start()
        except OSError as exc:  # no shared memory, no process: said in the panel
            self._cannot = f"the waves map's process cannot start: {exc}"
            logger.warning("waves: %s", self._cannot)
        super().start()
        self._fit_thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """End the map's process (a map under way is dropped), stop and join both threads."""
        self._stop.set()  # before the map's process ends: its maps' failure is no news
        if self._child is not None:
            self._child.close()
        super().stop(timeout)
        self._fit_wake.set()
        if self._fit_thread.ident is not None:
            self._fit_thread.join(timeout)
        wait_at_exit(self, self._thread.is_alive() or self._fit_thread.is_alive())
        if self._slot is not None and not self._thread.is_alive():
            self._slot.close()

    # ---- what the window reads -----------------------------------------------
    def latest(self) -> LiveWaves | None:
        """The newest analysis, or None before the first."""
        with self._lock:
            return self._waves

    def camera_rate(self) -> float:
        """The camera's frames per second from the frame times, Hz (0 before two frames)."""
        with self._lock:
            times = np.asarray(self._camera_times)
        if times.size < 2:
            return 0.0
        steps = np.diff(times)
        steps = steps[steps > 0]
        return 1.0 / float(np.median(steps)) if steps.size else 0.0

    def map_seconds(self) -> float:
        """Time one map takes, s (median of the last 16; 0 before any): this thread's time per
        frame kept, from taking it to handing it over with the previous frame's map in."""
        costs = list(self._costs)
        return float(np.median(costs)) if costs else 0.0

    def map_cpu_seconds(self) -> float:
        """CPU time one map takes in the map's process, s (median of the last 16; 0 before any).

        :meth:`map_seconds` less this is the time the map waited: for a core (the
        machine's other work), or for this thread, which waits for the GIL (this
        process's other threads) to hand frames over and take maps in.
        """
        costs = list(self._cpu)
        return float(np.median(costs)) if costs else 0.0

    # ---- commands ------------------------------------------------------------
    def _apply(self, name: str, value: Any) -> None:
        if name != "settings":
            raise ValueError(f"unknown command {name!r}")
        if not isinstance(value, WaveSettings):
            raise TypeError(f"settings command needs WaveSettings, not {value!r}")
        old, self.settings = self.settings, value
        with self._lock:
            if value.label != old.label:
                self.history.clear()
                self.history.label = value.label
            self.history.resize(value.length)
        self._fit_wake.set()

    # ---- one frame -----------------------------------------------------------
    def _ready(self) -> bool:
        """Wait (the frames kept in the ring) until the maps worker has its first peaks."""
        return self.maps.peak_set() is not None or not self.maps.running

    def _step(self, pixels: np.ndarray, meta: FrameMeta) -> None:
        t = frame_time(meta.t_device, meta.t_host)
        with self._lock:
            self._camera_times.append(t)
        jumped = self._continuity.breaks(meta)
        self._restart |= jumped
        self._adapt_stride()
        if meta.frame_id % self.stride:
            return
        peak_set = self.maps.peak_set()
        if peak_set is None:
            return
        tick = time.perf_counter()
        try:
            self._send(pixels, *peak_set)
        except HoloviewError as exc:  # said in the panel, not the banner
            self._failed(exc)
            return
        self._in_flight.append(_Sent(t, meta.frame_id, jumped))
        child_cpu, rebuilt = 0.0, False
        while len(self._in_flight) > 1:  # the previous frame's map, made meanwhile
            made = self._take()
            if made is not None:
                child_cpu += made.cpu_seconds
                rebuilt |= made.rebuilt
        if rebuilt:  # a new demodulator's first frame plans its FFTs: not a map's cost
            self._costs.clear()
            self._cpu.clear()
            # the frames that came while the first peaks were found: behind only if more come
            self._backlog_at_change = self.backlog()
        elif child_cpu:
            self._costs.append(time.perf_counter() - tick)
            self._cpu.append(child_cpu)

    def _idle(self) -> None:
        """No frame came: take the map still being made (the last of a replay's, say)."""
        self._drain()

    def _drain(self) -> None:
        while self._in_flight:
            self._take()

    def _send(self, pixels: np.ndarray, peaks: tuple[Peak, ...], experiment: Experiment) -> None:
        """Have the chosen map of one frame made in the map's process."""
        if self._slot is None or self._child is None:
            raise HoloviewError(self._cannot)
        slot = self._sent % IN_FLIGHT
        self._slot.put(slot, pixels)
        job = WaveJob(peaks, experiment, self.settings.label, restart=self._restart, slot=slot)
        self._child.submit(job)
        self._sent += 1
        self._restart = False

    def _take(self) -> WaveMap | None:
        """Add the oldest map sent to the history (None where it failed: said in the panel)."""
        sent = self._in_flight.popleft()
        assert self._child is not None
        try:
            made = self._child.result()
        except HoloviewError as exc:
            self._failed(exc)
            return None
        self._problem = None
        with self._lock:
            history = self.history
            if sent.jumped or made.rebuilt:  # a replay's jump; a new demodulator (reference anew)
                if len(history):
                    logger.info(
                        "waves: %s; the window starts again",
                        "the replay jumped" if sent.jumped else "the demodulator was rebuilt",
                    )
                history.clear()
            if made.pixel_size != history.pixel_size or made.k_cut != history.k_cut:
                if len(history):
                    logger.info(
                        "waves: the map's pixel size or cut-off changed (%s m, %.4g rad/m); "
                        "the window starts again",
                        made.pixel_size,
                        made.k_cut,
                    )
                history.clear()
                history.pixel_size, history.k_cut = made.pixel_size, made.k_cut
            history.push(made.height, sent.t, sent.frame_id, relative=made.reference == "relative")
        self._publish(None)
        return made

    def _failed(self, exc: HoloviewError) -> None:
        """Say why a map did not come (in the panel); a process that ended, once in the log."""
        self._problem = str(exc)
        if self._child is not None and self._child.pid is None:  # no map sent to it comes
            if not self._stop.is_set():
                logger.warning("waves: %s", exc)
            self._in_flight.clear()

    def _needed_stride(self) -> int:
        """The power-of-two stride a map's time asks for (1 while the source waits for this
        worker, :attr:`paced`): a larger one where a map takes longer than the time between
        two kept frames, the smallest at which it takes :data:`TARGET_BUSY` of it; a smaller
        one at which it would take at most :data:`RELAX_BUSY`; else the stride in use."""
        if self.paced():
            return 1
        rate = self.camera_rate()
        if len(self._costs) < MIN_COSTS or rate <= 0:
            return self.stride
        busy = self.map_seconds() * rate  # a map's share of a camera frame's interval
        needed = self.stride
        backlog = self.backlog()
        if busy > needed:
            if backlog >= self.ring.capacity * RISE_BACKLOG:  # not only a moment behind
                while needed < MAX_STRIDE and busy / needed > TARGET_BUSY:
                    needed *= 2
        else:
            while needed > 1 and busy / (needed // 2) <= RELAX_BUSY:
                needed //= 2
        if backlog > max(self.ring.capacity // 2, self._backlog_at_change):
            needed = max(needed, min(2 * self.stride, MAX_STRIDE))  # far behind, and more so
        return needed

    def _adapt_stride(self) -> None:
        """Keep fewer frames when a map takes too long; more once there is time to spare."""
        stride, needed = self.stride, self._needed_stride()
        now = time.monotonic()
        if needed > stride:
            stride = needed
            self._relaxed_since = None
            if now - self._lowered_at < HELD_S:  # the smaller stride did not hold
                self._relax_s = min(2 * self._relax_s, MAX_RELAX_S)
        elif needed < stride:
            if self._relaxed_since is None:
                self._relaxed_since, self._relax_to = now, needed
            self._relax_to = max(self._relax_to, needed)
            if now - self._relaxed_since >= self._relax_s:  # the largest needed since
                stride = self._relax_to
                self._relaxed_since = None
                self._lowered_at = now
        else:
            self._relaxed_since = None
        if stride != self.stride:
            self._drain()  # the maps of the frames kept so far, then the window anew
            self._backlog_at_change = self.backlog()
            logger.info("waves: every %d camera frame(s) kept (was %d)", stride, self.stride)
            self.stride = stride
            with self._lock:
                self.history.clear()
                self.history.stride = stride
            self._restart = True

    # ---- the analyses ----------------------------------------------------------
    def _fit_loop(self) -> None:
        yield_to_others()
        last = -math.inf
        cost = 0.0
        while not self._stop.is_set():
            wait = self.fit_period(cost) - (time.monotonic() - last)
            if wait > 0:
                self._fit_wake.wait(wait)
                self._fit_wake.clear()
                if time.monotonic() - last < 1.0 / WAVES_HZ * 0.5:
                    continue  # woken early by a command: not sooner than half the period
            if self._stop.is_set():
                return
            last = time.monotonic()
            try:
                result = self._analyse()
            except Exception:  # a bug: log it, keep the window running
                logger.exception("waves analysis failed")
                self._report("the waves analysis failed (see the log)")
                result = None
            cost = time.monotonic() - last
            if result is not None:
                with self._lock:
                    self._waves = result
                if self.listener is not None:
                    self.listener()

    def fit_period(self, cost: float) -> float:
        """Seconds between the starts of two analyses that take ``cost`` seconds each."""
        share = FIT_SHARE if self.stride == 1 else FIT_SHARE_BEHIND
        return max(1.0 / WAVES_HZ, cost / share)

    def _analyse(self) -> LiveWaves | None:
        with self._lock:
            window = self.history.snapshot()
            settings = self.settings
            stride = self.stride
        self._seq += 1
        problem = self._problem
        camera = self.camera_rate()
        if window is None:
            why = problem or (
                f"waiting for maps of {settings.label}: none yet"
                if len(self.history) == 0
                else f"waiting for maps of {settings.label}: one so far"
            )
            return LiveWaves(
                seq=self._seq,
                label=settings.label,
                frames=len(self.history),
                rate=camera / stride if camera else 0.0,
                camera_rate=camera,
                stride=stride,
                gaps=0,
                latest=None,
                pixel_size=None,
                problems=(why,),
                map_seconds=self.map_seconds(),
                map_cpu_seconds=self.map_cpu_seconds(),
            )
        result = analyse_window(window, settings, seq=self._seq, camera_rate=camera)
        if problem is not None:
            result = replace(result, problems=(problem, *result.problems))
        return replace(
            result, map_seconds=self.map_seconds(), map_cpu_seconds=self.map_cpu_seconds()
        )
