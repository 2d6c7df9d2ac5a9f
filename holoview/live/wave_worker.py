"""The Waves panel's worker: one chosen map from every camera frame, and its analyses, Qt-free.

The maps worker takes the newest frame at whatever rate is left, so its maps come
irregularly spaced and, on a slow machine, at a fraction of the camera's rate; a
spectrum needs them evenly spaced. The waves worker (``holoview-waves``) therefore takes
*every* frame from the ring itself and demodulates the one map the panel shows (a
labelled peak's, or the fused map of every peak with a height) with the engine's
per-frame core (:class:`~holoview.engine.frame_core.FrameCore`; its window's radius
held, :meth:`WavesWorker._window_radius`), into a
:class:`~holoview.live.wave_window.WaveHistory`:

- every frame while a map takes less than :data:`TARGET_BUSY` of the camera's frame
  interval (``stride`` 1); else every second frame (``frame_id`` even), every fourth,
  ...: the maps stay evenly spaced at ``camera rate / stride`` and the panel says that
  the frequency axis ends at half that rate. Once a smaller stride has sufficed for
  :data:`RELAX_S` seconds the stride becomes the largest that was needed meanwhile (one
  step: each change of stride starts the window again).
- a replay played as fast as it reads waits for it (:meth:`WavesWorker.wait_for_room`),
  so a replay at full speed fills the panel from every frame;
- frames lost before it read them are gaps in the history (by the frame times),
  never closed; a replay's jump, or a demodulator rebuilt (new peaks: its reference
  starts again), starts the history again.

A second thread (``holoview-waves-fit``) analyses the history at most :data:`WAVES_HZ`
times a second, and less often when an analysis takes more than :data:`FIT_SHARE` of the
time, or :data:`FIT_SHARE_BEHIND` while the maps keep fewer frames than the camera gives
(the cores go to the maps first); the analyses are
:func:`~holoview.live.wave_window.analyse_window`, the functions of ``holoview waves``.
The map thread runs at the priority of the series and the window, which must keep up too
(the panel's map of every frame is what it is opened for); the maps worker, whose rate
is whatever is left, and the analyses run at a lower one
(:data:`~holoview.live.worker.YIELDING_NICENESS`). A map costs one carrier window of one
frame: the frame's row FFTs, the column FFTs under that window alone
(:class:`~holoview.processing.fourier.half_spectrum.HalfSpectrum`) and one box's inverse
FFT.
"""

from __future__ import annotations

import collections
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from holoview.acquire.ring import FrameRing
from holoview.acquire.source import FrameMeta
from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FrameCore
from holoview.engine.map_step import MapStep
from holoview.engine.series import frame_time
from holoview.errors import HoloviewError, InputError
from holoview.live.continuity import Continuity
from holoview.live.wave_window import (
    FUSED,
    LiveWaves,
    WaveHistory,
    WaveSettings,
    analyse_window,
)
from holoview.live.worker import DemodWorker, RingWorker, wait_at_exit, yield_to_others
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.radii import peak_radii

logger = logging.getLogger(__name__)

__all__ = [
    "BACKLOG",
    "FIT_SHARE",
    "FIT_SHARE_BEHIND",
    "HOLD_BINS",
    "MAX_STRIDE",
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
#: Frames waiting in the ring beyond which a replay played as fast as it reads waits.
BACKLOG = 24
#: Largest stride (camera frames per map).
MAX_STRIDE = 16
#: Most of the time between two kept frames a map may take (median of the last 16).
TARGET_BUSY = 0.8
#: Maps timed (since the demodulator was built) before the stride follows their cost.
MIN_COSTS = 8
#: Seconds a smaller stride must have sufficed before the stride is lowered to it.
RELAX_S = 5.0
#: FFT bins a chosen peak's detected carrier may move before its map is demodulated at
#: the new carrier (a new demodulator: the window starts again).
HOLD_BINS = 2.0
#: Seconds between two frames added to the fused map's displacement estimate: every frame
#: (at 0.5 s a full-speed replay's 300 frames gave the estimate a handful of frames, the
#: fused maps moved between them, and sigma came out 14 % low in half the runs).
COREGISTER_S = 0.0


def _chosen(peaks: tuple[Peak, ...], label: str) -> list[Peak]:
    """The peaks whose maps make the map ``label`` (InputError when there is none)."""
    if label == FUSED:  # every peak, as the maps worker's fused map (the engine chooses)
        if sum(1 for p in peaks if p.label and p.alpha is not None) < 2:
            raise InputError(
                "no fused map: fewer than two labelled peaks have a height prefactor; "
                "label peaks in the Spectrum or choose one peak's map"
            )
        return [p for p in peaks if p.label]
    found = [p for p in peaks if p.label == label]
    if not found:
        raise InputError(
            f"no peak labelled {label}: label it in the Spectrum or choose another map"
        )
    if found[0].alpha is None:
        raise InputError(f"{label} has no height prefactor: its map is a phase, not a height")
    return found


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
        self._core: FrameCore | None = None
        self._maps_step: MapStep | None = None
        self._radius: tuple[tuple[object, ...], float] | None = None
        self._fused_labels: frozenset[str | None] | None = None
        self._held_peaks: list[Peak] | None = None
        self._coregistered_at = -math.inf
        self._continuity = Continuity()
        self._costs: collections.deque[float] = collections.deque(maxlen=16)  # s per map
        self._cpu: collections.deque[float] = collections.deque(maxlen=16)  # CPU s per map
        self._relaxed_since: float | None = None
        self._relax_to = 1
        #: True while the source waits for this worker (a replay played as fast as it
        #: reads, :meth:`wait_for_room`): every frame is then kept, whatever a map costs,
        #: also for the frames still in the ring once the replay has reached its end.
        self.paced: Callable[[], bool] = lambda: False
        self._camera_times: collections.deque[float] = collections.deque(maxlen=65)
        self._problem: str | None = None
        self._room = threading.Condition()
        self._waves: LiveWaves | None = None
        self._seq = 0
        self._fit_wake = threading.Event()
        self._fit_thread = threading.Thread(
            target=self._fit_loop, name="holoview-waves-fit", daemon=True
        )

    # ---- life cycle ----------------------------------------------------------
    def start(self) -> None:
        """Start the thread and its analysis thread."""
        super().start()
        self._fit_thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop and join both threads."""
        super().stop(timeout)
        self._fit_wake.set()
        with self._room:
            self._room.notify_all()
        if self._fit_thread.ident is not None:
            self._fit_thread.join(timeout)
        wait_at_exit(self, self._thread.is_alive() or self._fit_thread.is_alive())

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
        """Time one map takes, s (median of the last 16; 0 before any)."""
        costs = list(self._costs)
        return float(np.median(costs)) if costs else 0.0

    def map_cpu_seconds(self) -> float:
        """CPU time one map takes this worker's thread, s (median of the last 16; 0 before any).

        :meth:`map_seconds` less this is the time the map waited: for a core (the
        machine's other work) or for the GIL (this process's other threads).
        """
        costs = list(self._cpu)
        return float(np.median(costs)) if costs else 0.0

    def backlog(self) -> int:
        """Frames waiting in the ring for this worker."""
        return self._consumer.status().unread

    def wait_for_room(self, stop: threading.Event, limit: int = BACKLOG) -> None:
        """Wait until fewer than ``limit`` frames wait for this worker (or it or ``stop`` ends).

        A replay played as fast as it reads calls it before each frame; meanwhile the
        worker keeps every frame.
        """
        with self._room:
            while not stop.is_set() and self.running and self.backlog() >= limit:
                self._room.wait(0.1)

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
        with self._room:
            self._room.notify_all()
        t = frame_time(meta.t_device, meta.t_host)
        with self._lock:
            self._camera_times.append(t)
        jumped = self._continuity.breaks(meta)
        if jumped and self._core is not None:
            self._core.break_sequence()
        self._adapt_stride()
        if meta.frame_id % self.stride:
            return
        peak_set = self.maps.peak_set()
        if peak_set is None:
            return
        tick, cpu = time.perf_counter(), time.thread_time()
        demodulator = None if self._core is None else self._core.demodulator
        try:
            height, pixel_size, k_cut = self._map(pixels, *peak_set)
        except HoloviewError as exc:  # said in the panel, not the banner
            self._problem = str(exc)
            return
        self._problem = None
        built = self._core is None or self._core.demodulator is not demodulator
        with self._lock:
            history = self.history
            if jumped or built:  # a replay's jump; a new demodulator (its reference anew)
                if len(history):
                    logger.info(
                        "waves: %s; the window starts again",
                        "the replay jumped" if jumped else "the demodulator was rebuilt",
                    )
                history.clear()
            if pixel_size != history.pixel_size or k_cut != history.k_cut:
                if len(history):
                    logger.info(
                        "waves: the map's pixel size or cut-off changed (%s m, %.4g rad/m); "
                        "the window starts again",
                        pixel_size,
                        k_cut,
                    )
                history.clear()
                history.pixel_size, history.k_cut = pixel_size, k_cut
            history.push(height, t, meta.frame_id, relative=self._core_reference() == "relative")
        if built:  # a new demodulator's first frame plans its FFTs: not a map's cost
            self._costs.clear()
            self._cpu.clear()
        else:
            self._costs.append(time.perf_counter() - tick)
            self._cpu.append(time.thread_time() - cpu)
        self._publish(None)

    def _core_reference(self) -> str:
        core = self._core
        return "absolute" if core is None else core.experiment.reference

    def _needed_stride(self) -> int:
        """The smallest power-of-two stride at which a map takes :data:`TARGET_BUSY` of the time
        between two kept frames (1 while the source waits for this worker, :attr:`paced`)."""
        if self.paced():
            return 1
        rate = self.camera_rate()
        if len(self._costs) < MIN_COSTS or rate <= 0:
            return self.stride
        per_map = self.map_seconds()
        needed = 1
        while needed < MAX_STRIDE and per_map * rate / needed > TARGET_BUSY:
            needed *= 2
        if self.backlog() > self.ring.capacity // 2:  # far behind whatever the costs say
            needed = max(needed, min(2 * self.stride, MAX_STRIDE))
        return needed

    def _adapt_stride(self) -> None:
        """Keep fewer frames when a map takes too long; more once there is time to spare."""
        stride, needed = self.stride, self._needed_stride()
        now = time.monotonic()
        if needed > stride:
            stride = needed
            self._relaxed_since = None
        elif needed < stride:
            if self._relaxed_since is None:
                self._relaxed_since, self._relax_to = now, needed
            self._relax_to = max(self._relax_to, needed)
            if now - self._relaxed_since >= RELAX_S:  # straight to the largest needed since
                stride = self._relax_to
                self._relaxed_since = None
        else:
            self._relaxed_since = None
        if stride != self.stride:
            logger.info("waves: every %d camera frame(s) kept (was %d)", stride, self.stride)
            self.stride = stride
            with self._lock:
                self.history.clear()
                self.history.stride = stride
            if self._core is not None:
                self._core.break_sequence()

    def _map(
        self, pixels: np.ndarray, peaks: tuple[Peak, ...], experiment: Experiment
    ) -> tuple[np.ndarray, tuple[float, float] | None, float]:
        """The chosen map of one frame (m), its pixel size (m) and cut-off (rad/m)."""
        label = self.settings.label
        chosen = _chosen(peaks, label)
        if label == FUSED:  # the peaks fused stay while they are there: a family the model
            held = self._fused_labels  # adds later would rebuild and restart the window
            if held is None or not held <= {p.label for p in chosen}:
                held = self._fused_labels = frozenset(p.label for p in chosen)
            chosen = [p for p in chosen if p.label in held]
        chosen = self._held(chosen)
        experiment = replace(experiment, radius=self._window_radius(chosen, peaks, experiment))
        if self._core is None or self._maps_step is None:
            self._core = FrameCore(self.frame_shape, experiment, chosen, saturation=self.saturation)
            self._maps_step = MapStep(self._core)
        self._core.configure(experiment, chosen)
        fused = label == FUSED
        now = time.monotonic()
        estimate = fused and now - self._coregistered_at >= COREGISTER_S
        maps = self._maps_step.process(pixels, estimate=estimate, fuse=fused)
        demod = maps.result
        if demod is None or not maps.maps:
            raise InputError(f"no map of {label} from this frame ({', '.join(maps.flags)})")
        if estimate:
            self._coregistered_at = now
        height = maps.fused if fused else maps.maps[0]
        if height is None:
            raise InputError("no fused map: fewer than two peaks give a height on this frame")
        rows, cols = self.frame_shape
        by, bx = demod.box_shape
        pitch = experiment.pixel_pitch_m
        pixel_size = None if pitch is None else (pitch * rows / by, pitch * cols / bx)
        demodulator = self._core.demodulator
        radius = demod.radius if demodulator is None else min(demodulator.radii)
        k_cut = math.inf if pitch is None else 2.0 * math.pi * radius / pitch
        return height, pixel_size, k_cut

    def _held(self, chosen: list[Peak]) -> list[Peak]:
        """The chosen peaks as first demodulated, while their labels and prefactors stay and
        no carrier has moved by more than :data:`HOLD_BINS` FFT bins.

        The maps worker snaps the carriers to each detection, which on a wavy surface
        wanders by a bin; a demodulator rebuilt for that would restart the window. A
        carrier held a bin off tilts every map by the same plane, which no step between
        frames and no frequency but zero sees.
        """
        held = self._held_peaks
        rows, cols = self.frame_shape
        if (
            held is not None
            and [(p.label, p.alpha) for p in held] == [(p.label, p.alpha) for p in chosen]
            and all(
                abs(p.carrier[0] - q.carrier[0]) * cols <= HOLD_BINS
                and abs(p.carrier[1] - q.carrier[1]) * rows <= HOLD_BINS
                for p, q in zip(held, chosen, strict=True)
            )
        ):
            return held
        self._held_peaks = chosen
        return chosen

    def _window_radius(
        self, chosen: list[Peak], peaks: tuple[Peak, ...], experiment: Experiment
    ) -> float:
        """The window radius of the maps, cycles/pixel, held while the map and labels stay.

        The experiment's radius where it sets a number; else (automatic, ``"bound"`` or
        ``"matched"``) the widest that reaches no other
        demodulated carrier (labelled or placed by the model), their twins or zero
        frequency (:func:`~holoview.processing.peaks.radii.peak_radii` without the
        detected neighbours; the smallest of the chosen peaks' for the fused map). The
        detected peaks are left out: on a wavy surface detection finds the waves'
        sidebands around every carrier, which are surface content to pass, and the
        maps worker's automatic radius shrinks to their spacing.
        """
        if isinstance(experiment.radius, (int, float)):
            return float(experiment.radius)
        key = (self.settings.label, tuple(p.label for p in chosen))
        if self._radius is None or self._radius[0] != key:
            carriers = np.array([p.carrier for p in peaks], dtype=np.float64)
            radii = peak_radii(self.frame_shape, carriers, None, np.zeros((0, 2)))
            wanted = {p.label for p in chosen}
            self._radius = (
                key,
                min(r for p, r in zip(peaks, radii, strict=True) if p.label in wanted),
            )
        return self._radius[1]

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
