"""What the live maps do with the newest frame: the engine's core, on a schedule.

Per frame: the display spectrum (at most :data:`SPECTRUM_HZ`), peak detection (at most
:data:`PEAKS_HZ`; carriers drift slowly; each of the two at most a :data:`SIDE_SHARE`
of the worker's time), the experiment's labels snapped to the detected peaks and the
model's families added (:func:`holoview.engine.resolve.resolve_peaks`), and the
maps step (:class:`holoview.engine.map_step.MapStep`: every peak's map, the phase-step
rule, the displacements, added to at most :data:`COREGISTER_HZ` and a :data:`SIDE_SHARE`
of the time, and the fused map); at each detection, at most a :data:`SIDE_SHARE` of the
time unless the operator asks, the windows' match to the surface is checked
(:class:`holoview.engine.window_matching.WindowMatcher`: matched again when the operator
asks or the surface's bandwidth changed, with a note shown for :data:`NOTE_SECONDS`).
A measurement takes seconds: the live maps server runs it in a process of its own
(:meth:`MapsPipeline.match_job`, :meth:`MapsPipeline.use_match`) and the new windows
are taken between two frames; the maps restart then, said by the note, and the first
frame after any restart, the new reference, is marked (:attr:`LiveResult.reference`:
its maps are zeros against themselves, which the window does not draw). The
demodulator's peaks (:attr:`MapsPipeline.peaks`) go to the series worker, which takes
every frame (:mod:`holoview.live.series_pipeline`). Every number comes from the engine, the same
code ``holoview process`` runs; this module only decides when to call what, and packs
a :class:`LiveResult` for the window.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from holoview.acquire.source import FrameMeta
from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FFT_THREADS, FrameCore
from holoview.engine.map_step import Coregistration, MapStep
from holoview.engine.resolve import Resolution, on_lattice, resolve_peaks
from holoview.engine.window_matching import MatchJob, Rematch, WindowMatcher, windows_in_use
from holoview.live.continuity import Continuity
from holoview.processing.fourier.spectrum import display_spectrum
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.peaks.detection import Peak, find_peaks
from holoview.processing.peaks.radii import surface_band, window_neighbours

logger = logging.getLogger(__name__)

__all__ = ["CoregistrationJob", "LiveResult", "MapsPipeline", "block_max", "spectrum_image"]

#: Highest rate of the display spectrum, Hz.
SPECTRUM_HZ = 10.0
#: Highest rate of peak detection, Hz.
PEAKS_HZ = 1.0
#: Most of the worker's time the display spectrum and the peak detection may each take
#: (their rates drop below the ones above when a frame is large or the machine slow).
SIDE_SHARE = 0.1
#: Largest side of the spectrum image handed to the window (block maxima beyond).
SPECTRUM_DISPLAY_MAX = 512
#: Highest rate at which maps are added to the displacement estimate, Hz.
COREGISTER_HZ = 2.0
#: How long a note that the windows changed stays shown, seconds.
NOTE_SECONDS = 10.0

Carrier = tuple[float, float]


@dataclass(frozen=True)
class LiveResult:
    """Everything the window draws for one processed frame.

    Arrays are shared, never modified after publication. Heights in metres, phases
    in radians, carriers (``peaks``: the detected peaks that bound windows, not the
    surface's sidebands), the largest window radius and each labelled peak's
    (``radii``) in cycles per pixel, times in seconds.
    ``shifts_px`` holds the measured displacements ``(dy, dx)`` of the maps against
    the map ``grid_of``, in camera pixels; the fused map is on that map's grid.
    ``frame_index`` is the frame's index in a replayed file (-1 for a camera) and
    ``segment`` its unbroken run of frames (:mod:`holoview.live.continuity`).
    ``contradiction`` names a label the carrier lattice contradicts (the engine's rule,
    :func:`holoview.engine.resolve.resolve_peaks`; an error headless), None when none.
    ``reference``: the maps restarted at this frame (new peaks or windows, a reset):
    it is their new reference, and its maps are zeros by construction. ``t_done``: the
    host time (``time.time()``, as ``t_host``) the maps were done: the frame waited
    ``t_done - processing_s - t_host`` for the maps worker.
    """

    seq: int
    frame: np.ndarray
    frame_id: int
    t_host: float
    processing_s: float
    spectrum: np.ndarray | None
    peaks: list[Carrier]
    labelled: dict[str, Carrier]
    predicted: dict[str, Carrier]
    radius: float | None
    radii: dict[str, float] = field(default_factory=dict)
    heights_m: dict[str, np.ndarray] = field(default_factory=dict)
    fused_m: np.ndarray | None = None
    phases_rad: dict[str, np.ndarray] = field(default_factory=dict)
    shifts_px: dict[str, tuple[float, float]] = field(default_factory=dict)
    grid_of: str | None = None
    notes: tuple[str, ...] = ()
    frame_index: int = -1
    segment: int = 0
    contradiction: str | None = None
    reference: bool = False
    t_done: float = 0.0


@dataclass(frozen=True)
class CoregistrationJob:
    """One frame's maps for the displacement estimate, handed to a thread of its own.

    Adding maps to the estimate takes several times a frame's maps (on a 1024 x 1024
    frame with six peaks, 140-290 ms against 20-30 ms on the 2-core box): on the maps
    worker it made every frame it was added on late. The maps are the published ones
    (never modified).
    """

    labels: tuple[str | None, ...]
    box_shape: tuple[int, int]
    maps: tuple[np.ndarray, ...]
    reference: bool

    def run(self, coregistration: Coregistration) -> Coregistration | None:
        """Add the maps to ``coregistration`` (the measuring one, kept by the thread);
        its displacements now, as fixed ones for the maps step (None before any)."""
        coregistration.add_maps(self.labels, self.box_shape, self.maps, reference=self.reference)
        found = coregistration.displacements(self.labels, self.box_shape)
        return None if found is None else Coregistration((self.labels, self.box_shape, found))


def spectrum_image(frame: np.ndarray) -> np.ndarray:
    """The spectrum image the window shows of ``frame`` (block maxima to at most
    :data:`SPECTRUM_DISPLAY_MAX` a side)."""
    return block_max(display_spectrum(frame, threads=FFT_THREADS), SPECTRUM_DISPLAY_MAX)


def block_max(image: np.ndarray, limit: int) -> np.ndarray:
    """Shrink ``image`` by an integer factor with block maxima so no side exceeds ``limit``.

    Maxima keep narrow peaks visible where averaging would blur them away.
    """
    factor = max(1, math.ceil(max(image.shape) / limit))
    if factor == 1:
        return image
    rows, cols = image.shape[0] // factor, image.shape[1] // factor
    out = image[0 : rows * factor : factor, 0 : cols * factor : factor].copy()
    for dy in range(factor):
        for dx in range(factor):
            if dy or dx:
                np.maximum(
                    out, image[dy : rows * factor : factor, dx : cols * factor : factor], out=out
                )
    return out


class MapsPipeline:
    """Turn frames into :class:`LiveResult` objects; used by one thread at a time.

    Commands (:meth:`apply`) change the experiment, or restart the absolute reference
    from the next frame.

    Parameters
    ----------
    experiment : Experiment
        Optics, labelled peaks, window and reference mode.
    frame_shape : tuple of int
        ``(rows, cols)`` of the frames, pixels.
    saturation : float, optional
        Raw value at which the camera saturates.
    """

    def __init__(
        self,
        experiment: Experiment,
        frame_shape: tuple[int, int],
        saturation: float | None = None,
    ) -> None:
        self.experiment = experiment
        self.frame_shape = frame_shape
        #: Detect peaks inside :meth:`process` when due; the live maps server
        #: (:class:`~holoview.live.maps_server.MapsServer`) turns this off and feeds
        #: :meth:`set_peaks` from its own peak thread instead (the first
        #: detection is always made inline, so the first frame is demodulated at the
        #: detected carriers, as ``holoview process`` does).
        self.detect_inline = True
        #: Do the work much slower than a frame's maps inside :meth:`process` when due:
        #: the display spectrum, the windows' match to the surface, adding maps to the
        #: displacement estimate. The live maps server turns this off and runs each on a
        #: thread of its own (:meth:`spectrum_job`, :meth:`match_job`,
        #: :meth:`coregistration_job`), handing the results back between frames
        #: (:meth:`use_spectrum`, :meth:`use_match`, :meth:`use_coregistration`).
        self.side_work_inline = True
        self._spectrum_due: np.ndarray | None = None
        self._coregistration_due: CoregistrationJob | None = None
        self._seq = 0
        self._spectrum: np.ndarray | None = None
        self._spectrum_at = -math.inf
        self._spectrum_cost = 0.0
        self._peaks: list[Peak] | None = None
        self._peaks_at = -math.inf
        self._peaks_cost = 0.0
        self._core = FrameCore(frame_shape, experiment, saturation=saturation)
        self._maps = MapStep(self._core)
        self._coregistered_at = -math.inf
        self._coregistration_cost = 0.0
        self._resolution_key: tuple[object, ...] | None = None
        self._resolution = Resolution(peaks=())
        self._continuity = Continuity()
        self._matcher = WindowMatcher()
        self._measure_due = False
        self._match_requested = False
        self._matched_at = -math.inf
        self._match_cost = 0.0
        self._window_note: tuple[str, float] | None = None

    # ---- commands ----------------------------------------------------------
    def apply(self, name: str, value: object) -> None:
        """Apply a command: ``experiment`` (new settings), ``reset`` or ``match`` (the
        windows matched to the surface again at the next frame)."""
        if name == "experiment":
            if not isinstance(value, Experiment):
                raise TypeError(f"experiment command needs an Experiment, not {value!r}")
            radius_changed = value.radius != self.experiment.radius
            if radius_changed or value.window != self.experiment.window:
                self._core.match(None)  # windows of another rule or shape: matched afresh
            self.experiment = value
            if radius_changed:
                self._peaks_at = -math.inf  # detect again with the new radius
        elif name == "reset":
            self._core.reset_reference()
        elif name == "match":
            self._match_requested = True
            self._measure_due = True
        else:
            raise ValueError(f"unknown command {name!r}")

    @property
    def demodulator(self) -> Demodulator | None:
        """The demodulator in use (None before the first frame with peaks)."""
        return self._core.demodulator

    @property
    def peaks(self) -> tuple[Peak, ...]:
        """The demodulator's peaks: labelled, with alpha where known (the series' peaks).

        The same tuple until the demodulator is rebuilt (a label or alpha changed, a
        carrier moved a whole bin).
        """
        demod = self._core.demodulator
        return () if demod is None else demod.peaks

    # ---- peak detection ----------------------------------------------------
    def peaks_due(self, now: float | None = None) -> bool:
        """Whether peak detection is due (at most :data:`PEAKS_HZ`, :data:`SIDE_SHARE`)."""
        now = time.monotonic() if now is None else now
        return now - self._peaks_at >= max(1.0 / PEAKS_HZ, self._peaks_cost / SIDE_SHARE)

    def peaks_started(self) -> None:
        """Note that a detection started now (on another thread)."""
        self._peaks_at = time.monotonic()

    def peaks_done(self, cost_s: float) -> None:
        """Note what the last detection cost, seconds (it spaces the next one)."""
        self._peaks_at = time.monotonic()
        self._peaks_cost = cost_s

    def set_peaks(self, peaks: list[Peak]) -> None:
        """Use newly detected peaks from the next frame on (and check the windows' match)."""
        self._peaks = list(peaks)
        self._measure_due = True

    def _detect(self, frame: np.ndarray) -> None:
        tick = time.perf_counter()
        self.set_peaks(find_peaks(frame, radius=self.experiment.fixed_radius, threads=FFT_THREADS))
        self.peaks_done(time.perf_counter() - tick)

    def resolution(self) -> Resolution:
        """The peaks to demodulate now, the model's predicted carriers and the notes."""
        key = (id(self._peaks), self.experiment)
        if key != self._resolution_key:
            previous = {p.label: p for p in self._resolution.peaks if p.label}
            self._resolution = resolve_peaks(
                self.experiment, self._peaks or [], self.frame_shape, previous=previous
            )
            self._resolution_key = key
        return self._resolution

    def _recent_note(self, now: float) -> tuple[str, ...]:
        """The note that the windows changed, while it is recent."""
        if self._window_note is None or now - self._window_note[1] > NOTE_SECONDS:
            return ()
        return (self._window_note[0],)

    # ---- one frame ---------------------------------------------------------
    def process(self, frame: np.ndarray, meta: FrameMeta) -> LiveResult:
        """Process one frame; raise HoloviewError for a problem the operator can fix.

        A frame of another segment than the last (a replay jumped) is not paired with
        the frame before it (:meth:`FrameCore.break_sequence`).
        """
        start = time.perf_counter()
        if self._continuity.breaks(meta):
            self._core.break_sequence()
        now = time.monotonic()
        if now - self._spectrum_at >= max(1.0 / SPECTRUM_HZ, self._spectrum_cost / SIDE_SHARE):
            self._spectrum_at = now
            if self.side_work_inline or self._spectrum is None:  # the first one with the maps
                tick = time.perf_counter()
                self.use_spectrum(spectrum_image(frame), time.perf_counter() - tick)
            else:
                self._spectrum_due = frame
        if self._peaks is None or (self.detect_inline and self.peaks_due(now)):
            self._detect(frame)
        resolution = self.resolution()
        detected = self._peaks or []
        placed = on_lattice(resolution.labelling, detected)
        self._core.configure(self.experiment, resolution.peaks, window_neighbours(detected, placed))
        if self.side_work_inline:
            job = self.match_job(frame, copy=False)
            if job is not None:
                tick = time.perf_counter()
                rematch = job.run(self._matcher)
                self.use_match(rematch, time.perf_counter() - tick, now)
        estimate = now - self._coregistered_at >= max(
            1.0 / COREGISTER_HZ, self._coregistration_cost / SIDE_SHARE
        )
        maps = self._maps.process(frame, estimate=estimate and self.side_work_inline)
        if estimate and maps.maps:
            self._coregistered_at = now
            if not self.side_work_inline and maps.result is not None:
                self._coregistration_due = CoregistrationJob(
                    tuple(r.peak.label for r in maps.result.peaks),
                    maps.result.box_shape,
                    tuple(maps.maps),
                    "reference" in maps.flags,
                )
        heights: dict[str, np.ndarray] = {}
        phases: dict[str, np.ndarray] = {}
        if maps.result is not None:
            for r in maps.result.peaks:
                name = r.peak.label or "?"
                phases[name] = r.phase
                if r.delta_h is not None:
                    heights[name] = r.delta_h
        self._seq += 1
        return LiveResult(
            seq=self._seq,
            frame=frame,
            frame_id=meta.frame_id,
            t_host=meta.t_host,
            processing_s=time.perf_counter() - start,
            spectrum=self._spectrum,
            peaks=window_neighbours(self._peaks or []),
            labelled=resolution.labelled,
            predicted=resolution.predicted,
            radius=self._core.radius,
            radii=self._core.radii(),
            heights_m=heights,
            fused_m=maps.fused,
            phases_rad=phases,
            shifts_px=maps.shifts_px,
            grid_of=maps.grid_of,
            notes=(*resolution.notes, *self._core.notes, *self._recent_note(now)),
            frame_index=meta.file_index,
            segment=meta.segment,
            contradiction=resolution.contradiction,
            reference=maps.result is not None and "reference" in maps.result.flags,
            t_done=time.time(),
        )

    # ---- the display spectrum made on another thread -------------------------
    def spectrum_job(self) -> np.ndarray | None:
        """The frame whose display spectrum is due (:func:`spectrum_image`; once); None."""
        frame, self._spectrum_due = self._spectrum_due, None
        return frame

    def use_spectrum(self, image: np.ndarray, cost_s: float) -> None:
        """Show ``image`` as the spectrum from the next result on; it took ``cost_s`` seconds
        to make (which spaces the next one: :data:`SIDE_SHARE`)."""
        self._spectrum = image
        self._spectrum_cost = cost_s

    # ---- displacements measured on another thread ----------------------------
    def coregistration_job(self) -> CoregistrationJob | None:
        """The maps due to be added to the displacement estimate (once each); None when none."""
        job, self._coregistration_due = self._coregistration_due, None
        return job

    def use_coregistration(self, found: Coregistration | None, cost_s: float = 0.0) -> None:
        """Fuse with displacements measured on another thread from the next frame on;
        they took ``cost_s`` seconds (which spaces the next: :data:`SIDE_SHARE`)."""
        self._coregistration_cost = cost_s
        if found is not None:
            self._maps.coregistration = found

    # ---- windows matched to the surface --------------------------------------
    @property
    def matcher(self) -> WindowMatcher:
        """The matcher (its state: the last frame measured); one thread uses it at a time."""
        return self._matcher

    def match_job(self, frame: np.ndarray, copy: bool = True) -> MatchJob | None:
        """The measurement due at ``frame`` (a detection came, or the operator asked); None
        when none is. Each due measurement is handed out once; one that is not asked for
        waits until the last took at most :data:`SIDE_SHARE` of the time since it began (a
        measurement takes seconds of CPU on a large frame, which the maps and the series
        need on a machine of few cores).

        Call it after :meth:`process` has taken ``frame`` (the windows in use are the
        core's then). ``copy``: the job takes a copy of ``frame`` (it runs on another
        thread while the caller goes on).
        """
        now = time.monotonic()
        spaced = now - self._matched_at >= self._match_cost / SIDE_SHARE
        if not self._measure_due or not (spaced or self._match_requested):
            return None
        self._measure_due = False
        self._matched_at = now
        requested, self._match_requested = self._match_requested, False
        return MatchJob(
            windows_in_use(self._core),
            np.array(frame, copy=True) if copy else frame,
            surface_band(self._peaks or []),
            requested,
        )

    def use_match(
        self, rematch: Rematch | None, cost_s: float = 0.0, now: float | None = None
    ) -> None:
        """Use windows matched again from the next frame (the maps restart, said by a note).

        ``cost_s``: the seconds the measurement took (it spaces the next one). A match is
        dropped when the experiment no longer matches its windows (a radius given while
        it was measured).
        """
        self._match_cost = cost_s
        if rematch is None or self.experiment.radius_rule != "matched":
            return
        rematch.apply(self._core)
        logger.info("%s", rematch.note)
        self._window_note = (rematch.note, time.monotonic() if now is None else now)
