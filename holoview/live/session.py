"""A live session: source -> camera thread -> FrameRing -> demodulation worker (+ recorder).

No Qt here, so a session can be scripted, tested and run without a display: the window
polls :meth:`LiveSession.latest` from its redraw timer and sends commands with the
setters, which the worker (:mod:`holoview.live.worker`) applies between frames. The
recorder (``holoview-recorder``) takes *every* frame and stores the experiment in
force, and each change of it, in the recording. All threads stop with a sentinel (the
ring closes, or a stop flag) and are joined by :meth:`LiveSession.close`.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from holoview.acquire.camera_thread import CameraThread
from holoview.acquire.pixel_formats import PIXEL_FORMATS
from holoview.acquire.recorder import Recorder
from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.ring import FrameRing
from holoview.acquire.source import FrameMeta, Source
from holoview.engine.depth import DepthSummary
from holoview.engine.experiment import Experiment
from holoview.engine.true_labels import true_experiment
from holoview.errors import HoloviewError, InputError
from holoview.live.maps_pipeline import LiveResult
from holoview.live.replay_control import FASTEST, ReplayControl
from holoview.live.series_pipeline import TrendSummary
from holoview.live.wave_window import LiveWaves, WaveSettings
from holoview.live.wave_worker import WavesWorker
from holoview.live.worker import DemodWorker, SeriesWorker

logger = logging.getLogger(__name__)

__all__ = ["LiveSession", "RecordRequest", "RecordingProgress", "discover_sources"]

#: Memory the frame ring may take, bytes (it holds at least 8 frames).
RING_BYTES = 256 * 2**20


class LiveRates(NamedTuple):
    """Rates and counts the status bar shows.

    Attributes
    ----------
    camera_fps, series_fps, maps_fps : float
        Frames per second the camera delivered, the series measured, the maps worker
        demodulated.
    series_missed : int
        Frames the ring overwrote before the series could take them (the series is
        meant to take every frame).
    dropped : int
        Frames lost before the host (transport) and frames the recorder missed.
    """

    camera_fps: float
    series_fps: float
    maps_fps: float
    series_missed: int
    dropped: int


@dataclass(frozen=True)
class RecordRequest:
    """What the operator asked to record.

    Attributes
    ----------
    path : Path
        The HDF5 file to write.
    duration_s : float or None
        Stop this many seconds after the first frame recorded (None: no time limit).
    frames : int or None
        Stop after this many frames (None: no frame limit).
    """

    path: Path
    duration_s: float | None
    frames: int | None


@dataclass(frozen=True)
class RecordingProgress:
    """What the recorder has done so far: frames written, seconds, frames it missed."""

    path: Path
    frames: int
    elapsed_s: float
    dropped: int
    active: bool


class LiveSession:
    """One source streaming into a ring, processed live, optionally recorded.

    Parameters
    ----------
    spec : str
        Source specification: ``sim``, ``aravis[:ID]``, ``v4l2[:N]``, ``replay:PATH``.
    experiment : Experiment
        Optics, labelled peaks, window and reference mode.
    source_options : mapping, optional
        Passed to the source's constructor (e.g. ``frame_rate_hz`` of the simulator);
        replays loop unless ``loop=False`` is given, and hold on their last frame when
        not looping unless ``hold=False`` is given (then the stream ends there).
    every_frame : bool
        Process every frame in order (frames the ring overwrote first are counted as
        dropped) instead of the newest: for scripted runs on a source the worker keeps
        up with, such as a paced replay.

    Raises
    ------
    HoloviewError
        The source cannot be opened (camera gone, file broken or missing).
    """

    def __init__(
        self,
        spec: str,
        experiment: Experiment,
        *,
        source_options: Mapping[str, Any] | None = None,
        every_frame: bool = False,
    ) -> None:
        self.spec = spec
        self.every_frame = every_frame
        self.experiment = experiment
        self.source: Source = _open_source(spec, source_options or {})
        #: The replay's transport (play, pause, step, seek, speed, loop); None for a camera.
        self.replay: ReplayControl | None = ReplayControl.of(self.source)
        self.recorder: Recorder | None = None
        self._request: RecordRequest | None = None
        self._error_shown = False
        self._messages: list[str] = []
        self._closed = False
        self._maps_listener: Callable[[], None] | None = None
        #: The Waves panel's worker while the panel is open (:meth:`open_waves`).
        self.waves_worker: WavesWorker | None = None
        self._waves_settings: WaveSettings | None = None
        try:
            self._build()
        except BaseException:
            self.source.close()
            raise

    @classmethod
    def open(
        cls,
        spec: str,
        experiment: Experiment,
        *,
        source_options: Mapping[str, Any] | None = None,
        every_frame: bool = False,
    ) -> LiveSession:
        """Open ``spec`` and start streaming and processing (closed again if starting fails).

        Raises
        ------
        HoloviewError
            The source cannot be opened or started.
        """
        session = cls(spec, experiment, source_options=source_options, every_frame=every_frame)
        try:
            session.start()
        except BaseException:
            session.close()
            raise
        return session

    def _build(self) -> None:
        """Make the ring, camera thread, pipelines and workers for the source as it is now."""
        shape = self.source.frame_shape
        frame_bytes = shape[0] * shape[1] * np.dtype(self.source.dtype).itemsize
        capacity = int(np.clip(RING_BYTES // frame_bytes, 8, 512))
        self.ring = FrameRing(capacity, shape, self.source.dtype)
        self.camera = CameraThread(self.source, self.ring)
        saturation = self.saturation_value
        self.worker = DemodWorker(
            self.ring, self.experiment, saturation=saturation, every_frame=self.every_frame
        )
        self.worker.listener = self._maps_listener
        self.series_worker = SeriesWorker(self.ring, self.worker, saturation=saturation)
        self.camera.pace = self._pace_replay
        self.waves_worker = None
        if self._waves_settings is not None:
            self.waves_worker = WavesWorker(
                self.ring, self.worker, shape, self._waves_settings, saturation=saturation
            )
            self.waves_worker.paced = self._replay_paced

    # ---- life cycle --------------------------------------------------------
    def start(self) -> None:
        """Start streaming and processing."""
        self.worker.start()
        self.series_worker.start()  # its process starts beside the maps'
        self.worker.wait_ready()  # a second or two: the maps' process starts
        self.camera.start()
        if self.waves_worker is not None:
            self.waves_worker.start()

    def close(self) -> None:
        """Stop recording, the camera and the worker; join them; close the source."""
        if self._closed:
            return
        self._closed = True
        self.stop_recording()
        self.camera.stop()
        self._stop_waves()
        self.series_worker.stop()
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

    def known_experiment(self) -> tuple[Experiment, str] | None:
        """The labels the source itself knows, and where they come from; None if none.

        The simulated camera's true labels
        (:func:`~holoview.engine.true_labels.true_experiment`); a replayed recording's
        stored experiment (the last it carries: the labels in force when it ended).

        Raises
        ------
        HoloviewError
            A recording's stored experiment that cannot be read (named).
        """
        setup = getattr(self.source, "sim_setup", None)
        if setup is not None:
            return true_experiment(setup), "the simulator's setup"
        path = getattr(self.source, "path", None)
        if not isinstance(path, Path) or path.suffix.lower() not in (".h5", ".hdf5"):
            return None
        with RecordingReader(path) as reader:
            stored = reader.experiments()
        if not stored:
            return None
        where = f"{path.name}'s stored experiment"
        return Experiment.from_json(stored[-1][1], where=where), f"the recording {path.name}"

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
        self._stop_waves()
        self.series_worker.stop()
        self.worker.stop()
        try:
            readback = self.source.set(name, value)
        finally:
            self._build()
            self.start()
        return readback

    # ---- commands to the worker -------------------------------------------
    def set_experiment(self, experiment: Experiment) -> None:
        """Use a new experiment (labels, radius, reference) from the next frame.

        A running recording stores the change, holding from its next frame.
        """
        self.experiment = experiment
        self.worker.post("experiment", experiment)
        if self.recorder is not None and self.recorder.running:
            self.recorder.note_experiment(experiment.to_json())

    def set_pca(self, on: bool) -> None:
        """Turn the PCA identification of the trends on or off."""
        self.series_worker.post("pca", bool(on))

    def match_windows(self) -> None:
        """Match every window to the surface again from the next frame (the maps restart)."""
        self.worker.post("match")

    def reset_trends(self) -> None:
        """Restart the depth series and the maps' absolute reference from the next frame."""
        self.series_worker.post("reset")
        self.worker.post("reset")

    # ---- what the window reads --------------------------------------------
    def latest(self) -> LiveResult | None:
        """The newest maps result, or None."""
        return self.worker.latest()

    def on_maps(self, listener: Callable[[], None] | None) -> None:
        """Call ``listener`` (on the maps thread; it must only wake its owner) at each result.

        A window draws a result when it comes instead of at its next timer tick, which
        would add up to a tick to the latency.
        """
        self._maps_listener = listener
        self.worker.listener = listener

    def newest_frame(self) -> tuple[int, np.ndarray, FrameMeta] | None:
        """The camera's newest frame ``(seq, pixels, meta)`` (a copy), or None.

        For a view of the camera at its own rate, whatever rate the maps come at.
        """
        return self.ring.newest()

    def trend(self) -> TrendSummary | None:
        """The newest summary of the series (depths, fused depth, rate), or None."""
        return self.series_worker.latest()

    def rates(self) -> LiveRates:
        """Camera, series and maps rates, frames the series missed, frames dropped."""
        series = self.series_worker.status()
        dropped = series.transport_lost
        if self.recorder is not None:
            dropped += self.recorder.status().dropped
        return LiveRates(
            camera_fps=self.camera.rate_hz(),
            series_fps=self.series_worker.rate_hz(),
            maps_fps=self.worker.rate_hz(),
            series_missed=series.dropped,
            dropped=dropped,
        )

    def summary(self) -> DepthSummary | None:
        """Depths and rates of the series so far; call once the workers are stopped.

        Raises
        ------
        HoloviewError
            The series cannot be summarised (the message says why).
        """
        return self.series_worker.summary()

    def drain_messages(self) -> list[str]:
        """Problems met by the workers, the camera or the recorder since the last call."""
        out = self.worker.drain_messages() + self.series_worker.drain_messages() + self._messages
        self._messages = []
        return out

    # ---- the Waves panel ---------------------------------------------------
    def open_waves(self, settings: WaveSettings) -> None:
        """Start the waves worker on ``settings`` (or hand them to the running one)."""
        self._waves_settings = settings
        if self.waves_worker is not None:
            self.waves_worker.post("settings", settings)
            return
        self.waves_worker = WavesWorker(
            self.ring,
            self.worker,
            self.source.frame_shape,
            settings,
            saturation=self.saturation_value,
        )
        self.waves_worker.paced = self._replay_paced
        if self.camera.started:  # else :meth:`start` starts it
            self.waves_worker.start()

    def close_waves(self) -> None:
        """Stop the waves worker (the panel closed); nothing else changes."""
        self._waves_settings = None
        self._stop_waves()

    def waves(self) -> LiveWaves | None:
        """The Waves panel's newest analysis, or None (panel closed, none yet)."""
        worker = self.waves_worker
        return None if worker is None else worker.latest()

    def _stop_waves(self) -> None:
        worker, self.waves_worker = self.waves_worker, None
        if worker is not None:
            worker.stop()

    def _replay_paced(self) -> bool:
        """True while the source is a replay played as fast as it reads (it waits for the
        workers that take every frame)."""
        return self.replay is not None and self.replay.speed == FASTEST

    def _pace_replay(self, stop: threading.Event) -> None:
        """Before each frame: a replay played as fast as it reads waits for the series and
        the waves worker, so that neither misses a frame (the maps take the newest)."""
        if self._replay_paced():
            self.series_worker.wait_for_room(stop)
            worker = self.waves_worker
            if worker is not None:
                worker.wait_for_room(stop)

    # ---- recording ---------------------------------------------------------
    def start_recording(self, request: RecordRequest) -> None:
        """Record every frame from now to ``request.path`` (an HDF5 holoview recording)."""
        if self.recorder is not None and self.recorder.running:
            raise InputError("a recording is already running")
        if request.path.suffix.lower() not in (".h5", ".hdf5"):
            raise InputError(f"recording file {request.path.name} must end in .h5 or .hdf5")
        e = self.experiment
        setup = {"wavelength_m": e.wavelength_m, "pixel_pitch_m": e.pixel_pitch_m}
        setup |= {"n1": e.n1, "n2": e.n2}
        self.recorder = Recorder.for_source(
            self.ring,
            request.path,
            self.source,
            setup={k: v for k, v in setup.items() if v is not None},
            max_frames=request.frames,
            max_seconds=request.duration_s,
            experiment=e.to_json(),
        )
        self.recorder.start()
        self._error_shown = False
        self._request = request
        logger.info("recording to %s", request.path)

    def stop_recording(self) -> None:
        """Stop the recording and close its file."""
        if self.recorder is not None and self.recorder.running:
            self.recorder.stop()
            if self.recorder.error is not None:
                self._messages.append(str(self.recorder.error))
                self._error_shown = True

    def recording_progress(self) -> RecordingProgress | None:
        """The recording's progress.

        A recording stops by itself at its duration or frame count (the recorder keeps
        both), when the camera ends, or on a write error: nobody needs to call this.
        """
        recorder, request = self.recorder, self._request
        if recorder is None or request is None:
            return None
        if not recorder.running and recorder.error is not None and not self._error_shown:
            # a full disk, an I/O error: say it once
            self._messages.append(str(recorder.error))
            self._error_shown = True
        return RecordingProgress(
            path=request.path,
            frames=recorder.written,
            elapsed_s=recorder.elapsed_s,
            dropped=recorder.status().dropped,
            active=recorder.running,
        )


def _open_source(spec: str, options: Mapping[str, Any]) -> Source:
    """Open the source ``spec`` with constructor ``options``; replays loop (and hold) by default."""
    from holoview.acquire.factory import open_source, parse_source_spec

    kwargs = dict(options)
    if parse_source_spec(spec).kind == "replay":
        kwargs.setdefault("loop", True)
        kwargs.setdefault("hold", True)
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
