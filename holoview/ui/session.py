"""A live session: source -> camera thread -> FrameRing -> demodulation worker (+ recorder).

No Qt here: the window polls :meth:`LiveSession.latest` from its redraw timer and
sends commands with the setters, which the worker applies between frames. The
worker (a thread named ``holoview-demod``) takes the *newest* frame from the ring
(in order while at most :data:`PROCESSING_MAX_LAG` frames wait, so one slow frame
costs a little latency rather than a gap in the series), runs a
:class:`~holoview.ui.live_pipeline.LivePipeline` on it and publishes the result
under a lock; peak detection, much slower than a frame, runs beside it on
``holoview-peaks``; the recorder (``holoview-recorder``) takes *every* frame. All
threads stop with a sentinel (the ring closes, or a stop flag) and are joined by
:meth:`LiveSession.close`.
"""

from __future__ import annotations

import collections
import logging
import queue
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from holoview.acquire.camera_thread import CameraThread
from holoview.acquire.pixel_formats import PIXEL_FORMATS
from holoview.acquire.recorder import Recorder
from holoview.acquire.ring import CLOSED, FrameRing, RingConsumer, RingStatus
from holoview.acquire.source import Source
from holoview.errors import HoloviewError, InputError
from holoview.processing.peaks import Peak, find_peaks
from holoview.ui.live_pipeline import FFT_THREADS, LivePipeline, LiveResult
from holoview.ui.recording_panel import RecordingProgress, RecordRequest
from holoview.ui.settings import ExperimentSettings

logger = logging.getLogger(__name__)

__all__ = ["LiveResult", "LiveSession", "discover_sources"]

#: Memory the frame ring may take, bytes (it holds at least 8 frames).
RING_BYTES = 256 * 2**20
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
    """

    def __init__(self, ring: FrameRing, pipeline: LivePipeline) -> None:
        self.pipeline = pipeline
        pipeline.detect_inline = False
        self.peaks = PeakWorker()
        self._consumer: RingConsumer = ring.consumer(
            "processing", mode="newest", max_lag=PROCESSING_MAX_LAG
        )
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
        if self.pipeline.peaks_due() and self.peaks.submit(pixels, self.pipeline.experiment.radius):
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


class LiveSession:
    """One source streaming into a ring, processed live, optionally recorded.

    Parameters
    ----------
    spec : str
        Source specification: ``sim``, ``aravis[:ID]``, ``v4l2[:N]``, ``replay:PATH``.
    experiment : ExperimentSettings
        Optics, labelled peaks, window and reference mode.
    source_options : mapping, optional
        Passed to the source's constructor (e.g. ``frame_rate_hz`` of the simulator);
        replays loop unless ``loop=False`` is given.

    Raises
    ------
    HoloviewError
        The source cannot be opened (camera gone, file broken or missing).
    """

    def __init__(
        self,
        spec: str,
        experiment: ExperimentSettings,
        *,
        source_options: Mapping[str, Any] | None = None,
    ) -> None:
        self.spec = spec
        self.experiment = experiment
        self.source: Source = _open_source(spec, source_options or {})
        self.recorder: Recorder | None = None
        self._request: RecordRequest | None = None
        self._recording_started = 0.0
        self._recording_elapsed = 0.0
        self._messages: list[str] = []
        self._closed = False
        try:
            self._build()
        except BaseException:
            self.source.close()
            raise

    def _build(self) -> None:
        """Make the ring, camera thread, pipeline and worker for the source as it is now."""
        shape = self.source.frame_shape
        frame_bytes = shape[0] * shape[1] * np.dtype(self.source.dtype).itemsize
        capacity = int(np.clip(RING_BYTES // frame_bytes, 8, 512))
        self.ring = FrameRing(capacity, shape, self.source.dtype)
        self.camera = CameraThread(self.source, self.ring)
        self.pipeline = LivePipeline(self.experiment, shape, saturation=self.saturation_value)
        self.worker = DemodWorker(self.ring, self.pipeline)

    # ---- life cycle --------------------------------------------------------
    def start(self) -> None:
        """Start streaming and processing."""
        self.camera.start()
        self.worker.start()

    def close(self) -> None:
        """Stop recording, the camera and the worker; join them; close the source."""
        if self._closed:
            return
        self._closed = True
        self.stop_recording()
        self.camera.stop()
        self.worker.stop()
        try:
            self.source.close()
        except HoloviewError as exc:
            logger.warning("closing %s: %s", self.spec, exc)

    @property
    def running(self) -> bool:
        """True while the camera thread streams."""
        return self.camera.running

    @property
    def stop_reason(self) -> str:
        """Why the camera thread ended ('' while it runs)."""
        if self.camera.running:
            return ""
        if self.camera.error is not None:
            return str(self.camera.error)
        return "end of stream" if not self._closed else "stopped"

    @property
    def description(self) -> str:
        """The source in words: name, frame shape, dtype."""
        rows, cols = self.source.frame_shape
        return f"{self.source.name} {cols} x {rows} {np.dtype(self.source.dtype).name}"

    @property
    def saturation_value(self) -> float:
        """The largest raw value of the source's pixel format."""
        bits = self._significant_bits()
        return float(2**bits - 1)

    def _significant_bits(self) -> int:
        fmt = None
        if self.source.has_setting("pixel_format"):
            try:
                fmt = PIXEL_FORMATS.get(str(self.source.get("pixel_format")))
            except HoloviewError as exc:
                logger.warning("%s: pixel format unreadable: %s", self.source.name, exc)
        return fmt.bits if fmt is not None else np.dtype(self.source.dtype).itemsize * 8

    # ---- source settings ---------------------------------------------------
    def source_setup(self) -> dict[str, Any]:
        """The optical setup the source knows (simulator, replayed recording), else empty."""
        return dict(self.source.setup)

    def describe_settings(self) -> Mapping[str, Any]:
        """The source's setting descriptions, by name."""
        return self.source.describe_settings()

    def read_settings(self) -> dict[str, Any]:
        """Every setting's value read back from the source."""
        return self.source.get_all()

    def set_setting(self, name: str, value: Any) -> Any:
        """Set a source setting; return the value read back.

        A setting locked while streaming (ROI, pixel format on most cameras) is set
        with the stream stopped: recording, camera thread and worker stop, the value
        is written, and streaming starts again with a ring of the new frame shape.
        """
        info = self.source.describe_settings().get(name)
        if info is None or not info.locked_while_streaming or not self.camera.running:
            return self.source.set(name, value)
        self.stop_recording()
        self.camera.stop()
        self.worker.stop()
        try:
            readback = self.source.set(name, value)
        finally:
            self._build()
            self.start()
        return readback

    # ---- commands to the worker -------------------------------------------
    def set_experiment(self, experiment: ExperimentSettings) -> None:
        """Use new experiment settings (labels, radius, reference) from the next frame."""
        self.experiment = experiment
        self.worker.post("experiment", experiment)

    def set_pca(self, on: bool) -> None:
        """Turn the PCA identification of the trends on or off."""
        self.worker.post("pca", bool(on))

    def reset_trends(self) -> None:
        """Restart the depth series from the next frame."""
        self.worker.post("reset")

    # ---- what the window reads --------------------------------------------
    def latest(self) -> LiveResult | None:
        """The newest processed result, or None."""
        return self.worker.latest()

    def rates(self) -> tuple[float, float, int]:
        """Return (camera fps, processing fps, frames dropped: transport + recorder overflow)."""
        status = self.worker.status()
        dropped = status.transport_lost
        if self.recorder is not None:
            dropped += self.recorder.status().dropped
        return self.camera.rate_hz(), self.worker.rate_hz(), dropped

    def drain_messages(self) -> list[str]:
        """Problems met by the worker, the camera or the recorder since the last call."""
        out = self.worker.drain_messages() + self._messages
        self._messages = []
        return out

    # ---- recording ---------------------------------------------------------
    def start_recording(self, request: RecordRequest) -> None:
        """Record every frame from now to ``request.path`` (an HDF5 holoview recording)."""
        if self.recorder is not None and self.recorder.running:
            raise InputError("a recording is already running")
        if request.path.suffix.lower() not in (".h5", ".hdf5"):
            raise InputError(f"recording file {request.path.name} must end in .h5 or .hdf5")
        e = self.experiment
        self.recorder = Recorder.for_source(
            self.ring,
            request.path,
            self.source,
            setup={
                "wavelength_m": e.wavelength_m,
                "pixel_pitch_m": e.pixel_pitch_m,
                "n1": e.n1,
                "n2": e.n2,
            },
            max_frames=request.frames,
        )
        self.recorder.start()
        self._request = request
        self._recording_started = time.monotonic()
        self._recording_elapsed = 0.0
        logger.info("recording to %s", request.path)

    def stop_recording(self) -> None:
        """Stop the recording and close its file."""
        if self.recorder is not None and self.recorder.running:
            self.recorder.stop()
            self._recording_elapsed = time.monotonic() - self._recording_started
            if self.recorder.error is not None:
                self._messages.append(str(self.recorder.error))

    def recording_progress(self) -> RecordingProgress | None:
        """The recording's progress; stops it once its duration is reached.

        A frame-count recording stops by itself (the recorder's ``max_frames``).
        """
        recorder, request = self.recorder, self._request
        if recorder is None or request is None:
            return None
        if recorder.running:
            self._recording_elapsed = time.monotonic() - self._recording_started
            limit_s = request.duration_s
            done_time = limit_s is not None and self._recording_elapsed >= limit_s
            if done_time or not self.camera.running:
                self.stop_recording()
        return RecordingProgress(
            path=request.path,
            frames=recorder.written,
            elapsed_s=self._recording_elapsed,
            dropped=recorder.status().dropped,
            active=recorder.running,
        )


def _open_source(spec: str, options: Mapping[str, Any]) -> Source:
    """Open the source ``spec`` with constructor ``options``; replays loop by default."""
    from holoview.acquire.factory import open_source, parse_source_spec

    kwargs = dict(options)
    if parse_source_spec(spec).kind == "replay":
        kwargs.setdefault("loop", True)
    return open_source(spec, **kwargs)


def discover_sources() -> tuple[list[str], list[str]]:
    """Return (source specifications found, problems met looking); ``sim`` comes first.

    GenICam cameras come from Aravis (``aravis:ID``), V4L2 devices from ``/dev/video*``
    (``v4l2:N``).
    """
    from holoview.acquire.aravis import list_cameras

    specs, problems = ["sim"], []
    try:
        specs += [f"aravis:{camera['id']}" for camera in list_cameras()]
    except HoloviewError as exc:
        problems.append(f"GenICam cameras not searched: {exc}")
    devices = sorted(Path("/dev").glob("video[0-9]*"), key=lambda p: int(p.name[5:]))
    specs += [f"v4l2:{device.name[5:]}" for device in devices]
    return specs, problems
