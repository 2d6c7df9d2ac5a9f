"""The streaming loop of a headless run: every frame through the engine's per-frame core.

Per frame, the carrier probe (:class:`holoview.engine.frame_core.CarrierCore`, what the
live series worker runs) measures each selected peak's complex carrier value, whose
phase is the spatially averaged phase (paper section 4.2), into a
:class:`holoview.engine.series.PhaseSeries` kept for the whole run (a few numbers per
frame and peak): that is all the trends and rates need, at a quarter of a full FFT's
time. The maps (:class:`holoview.engine.frame_core.FrameCore`, the live maps' core)
are demodulated where they are wanted: every frame with ``--maps``, else only the
frames that measure the peaks' displacements and the last frame (with the one before
it, so that its relative map is against the previous frame). With a :class:`MapSink`
each frame's maps go to it at once, so memory stays bounded by the few frames the
:class:`~holoview.headless.reader.FrameReader` reads ahead.

Maps are at the demodulator's box resolution (pixel ``(p, q)`` at frame position
``(p rows / by, q cols / bx)``), float32, NaN where the pixel is not trusted (its
amplitude is below a quarter of the peak's). With known prefactors they are delta-h
in metres; in auto mode (prefactors from the PCA after the run) they are phases in
radians, converted by the sink afterwards. The peaks' displacements against the first
peak are measured over the run (:mod:`holoview.processing.maps.coregister`, on up to
:data:`COREGISTER_FRAMES` frames spread over it), so fused maps, made after the run
(:func:`fuse_frame`), are co-registered.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import (
    CarrierCore,
    Coregistration,
    FrameCore,
    fuse_maps,
    trusted_maps,
)
from holoview.engine.series import PhaseSeries
from holoview.errors import InputError
from holoview.headless.inputs import InputFile
from holoview.headless.reader import DEFAULT_DEPTH, FrameReader
from holoview.processing.maps.coregister import Displacement
from holoview.processing.maps.heights import phase_to_height
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.matched import SurfaceSpectrum, Window
from holoview.processing.peaks.radii import window_neighbours

logger = logging.getLogger(__name__)

#: Frames, spread over a run, whose maps measure the peaks' displacements.
COREGISTER_FRAMES = 50

#: Per-frame map flags of a peak counted over the demodulated frames.
MAP_PEAK_FLAGS = ("low_amplitude", "overlap")


@dataclass(frozen=True)
class ProcessSettings:
    """How a run demodulates (names as the ``holoview process`` options).

    Attributes
    ----------
    reference : {"relative", "absolute", "synthetic"} or None
        Reference mode of the maps (the mean-phase series is always relative to the
        first frame). None: the experiment's.
    window : {"raised-cosine", "top-hat", "tukey"} or None
        None: the experiment's.
    radius : float, str or None
        Window radius, cycles/pixel, or ``"matched"`` or ``"bound"``
        (:func:`~holoview.processing.peaks.radii.peak_windows`); None: the experiment's.
    unwrap : {"auto", "always", "never"} or None
        Spatial unwrapping of the maps. None: the experiment's.
    maps : bool
        Write the delta-h maps.
    area_m2 : float or None
        Basin area, m^2, for volume rates.
    threads : int
        FFTW threads per frame. One by default: the reader thread needs a core too,
        and on a loaded two-core machine a two-thread FFT waiting for a busy core
        took 450 ms instead of 10 ms per 1024 x 1024 frame.
    read_ahead : int
        Frames the reader thread reads ahead.
    background : str or None
        An object-free hologram for absolute phases: a frame index of the input, or
        a file (its first frame); None: the first processed frame.
    """

    reference: str | None = None
    window: str | None = None
    radius: float | str | None = None
    unwrap: str | None = None
    maps: bool = False
    area_m2: float | None = None
    threads: int = 1
    read_ahead: int = DEFAULT_DEPTH
    background: str | None = None


class MapSink(Protocol):
    """Where each frame's maps go (``results.h5`` in a run)."""

    def write_map(self, position: int, peak: int, values: np.ndarray) -> None:
        """Store peak ``peak``'s map of the ``position``-th processed frame."""


@dataclass
class RunData:
    """What the loop kept: the per-frame series of every peak, and the last frame's maps.

    Attributes
    ----------
    series : PhaseSeries
        Carrier values, their noise, phase steps and flags of every processed frame
        (:mod:`holoview.engine.series`); ``frames``, ``times``, ``values`` and
        ``phase_steps`` read it.
    map_noise_rad : ndarray of float, shape (N, M)
        Per-pixel phase noise of each map, rad, on the frames demodulated (0 for a
        reference frame, NaN where a frame was not demodulated).
    map_flags : list of dict of str to int
        Per peak, demodulated frames flagged ``low_amplitude`` or ``overlap``.
    no_signal : int
        Demodulated frames with no trusted pixel in any peak.
    demodulated : int
        Frames demodulated into maps.
    box_shape : tuple of int
        Shape of every map, ``(by, bx)``.
    radius : float
        The largest window radius used, cycles/pixel (it sets ``box_shape``).
    windows : tuple of Window
        Each peak's window: radius, shape, the rule that chose it and why.
    last_maps : list of (ndarray or None)
        Each peak's map of the last demodulated frame (m, or rad in auto mode).
    last_frame : int
        Input index of the frame the last maps come from.
    displacements : list of Displacement
        Each peak's measured shift against the first peak, in map pixels (empty
        with one peak, or maps smaller than
        :data:`~holoview.processing.maps.coregister.MIN_MAP_SIDE`).
    maps_in_metres : bool
        Whether the maps are delta-h in m (every peak had alpha), else phases in rad.
    interrupted : bool
        The run was interrupted (Ctrl-C): the series hold the frames done before.
    read_seconds, demod_seconds, write_seconds, wall_seconds : float
        Time reading the input (on the reader threads), demodulating, writing maps,
        and in all, s (reading and demodulating summed over the processes).
    workers : str
        Where the carrier values were measured (``"1 process"``, ``"4 processes"``,
        ``"Dask at ..."``).
    maps_seconds : float
        Of ``demod_seconds``, the time demodulating maps (every frame with ``--maps``,
        else about 50 and the last), s.
    worker_seconds, parent_seconds : float
        A parallel run's time measuring carrier values in the workers (summed), and in
        the parent demodulating the maps and stitching the series in order (its
        sequential part, which bounds the frames per second whatever the workers), s;
        0 for a run in one process.
    """

    series: PhaseSeries
    map_noise_rad: np.ndarray
    map_flags: list[dict[str, int]]
    box_shape: tuple[int, int]
    radius: float
    windows: tuple[Window, ...] = ()
    last_maps: list[np.ndarray | None] = field(default_factory=list)
    last_frame: int = -1
    displacements: list[Displacement] = field(default_factory=list)
    maps_in_metres: bool = False
    interrupted: bool = False
    read_seconds: float = 0.0
    demod_seconds: float = 0.0
    write_seconds: float = 0.0
    wall_seconds: float = 0.0
    no_signal: int = 0
    demodulated: int = 0
    workers: str = "1 process"
    maps_seconds: float = 0.0
    worker_seconds: float = 0.0
    parent_seconds: float = 0.0

    @property
    def frames(self) -> np.ndarray:
        """Input frame indices, shape (N,)."""
        return self.series.frames

    @property
    def times(self) -> np.ndarray:
        """Frame times, s, from 0, shape (N,)."""
        return self.series.times

    @property
    def values(self) -> np.ndarray:
        """Carrier value per frame and peak (counts), shape (N, M); NaN: not demodulated."""
        return self.series.values

    @property
    def noise_rad(self) -> np.ndarray:
        """Per-pixel phase noise of each map, rad (NaN where not demodulated), shape (N, M)."""
        return self.map_noise_rad[: len(self.series)]

    @property
    def phase_steps(self) -> np.ndarray:
        """Whether each peak's mean phase stepped past the limit at each frame, (N, M)."""
        return self.series.phase_steps

    @property
    def frame_flags(self) -> dict[str, int]:
        """Frames flagged ``nonfinite`` and ``saturated`` (all), ``no_signal`` (demodulated)."""
        return {**self.series.frame_flags, "no_signal": self.no_signal}

    @property
    def peak_flags(self) -> list[dict[str, int]]:
        """Per peak, frames flagged ``phase_step`` (all), ``low_amplitude``, ``overlap``."""
        steps = self.series.step_counts
        return [{"phase_step": int(steps[j]), **f} for j, f in enumerate(self.map_flags)]


def fuse_frame(
    data: RunData,
    position: int,
    maps: Sequence[np.ndarray | None],
    scales: Sequence[float | None],
) -> np.ndarray | None:
    """Return the fused delta-h map (m) of the ``position``-th frame, co-registered.

    Parameters
    ----------
    data : RunData
        The run (noise, phase steps and displacements).
    position : int
        The frame's position in the run.
    maps : sequence of (ndarray or None)
        Each peak's delta-h map of that frame, m (None: not in metres).
    scales : sequence of (float or None)
        Metres per radian of each peak to fuse (None: left out).

    Returns
    -------
    ndarray of float32 or None
        :func:`holoview.engine.frame_core.fuse_maps` of the chosen peaks.
    """
    chosen = [maps[j] if s is not None else None for j, s in enumerate(scales)]
    noise = [
        None if s is None else _expected_error(data, position, j) * abs(s)
        for j, s in enumerate(scales)
    ]
    return fuse_maps(chosen, noise, list(data.phase_steps[position]), data.displacements or None)


def _expected_error(data: RunData, position: int, j: int) -> float:
    """Peak ``j``'s expected map error (rad) at a frame: its noise and its window's cut.

    As :attr:`~holoview.processing.maps.demod_results.PeakResult.error_height`; 0 on a
    reference frame (plain means).
    """
    noise = float(data.noise_rad[position, j])
    if not noise > 0 or not data.windows:
        return noise
    return float(np.hypot(noise, data.windows[j].cut))


def make_core(
    shape: tuple[int, int],
    experiment: Experiment,
    peaks: Sequence[Peak],
    settings: ProcessSettings,
    saturation: float | None = None,
    *,
    detected: Sequence[Peak] = (),
    background: np.ndarray | None = None,
    spectrum: SurfaceSpectrum | None = None,
    placed: Sequence[bool] | None = None,
) -> FrameCore:
    """Return the per-frame core of a run, its demodulator built (InputError if it cannot work).

    ``detected``: every peak found in the first frame; no automatic window reaches one
    (the surface's sidebands are not peaks: :func:`window_neighbours`).
    ``background``: the object-free hologram absolute phases are taken against.
    ``spectrum``: the spectrum the windows are matched to. ``placed``: per detected peak,
    whether naming put it on the lattice (a sideband flag it overrules).
    """
    core = FrameCore(
        shape,
        experiment,
        peaks,
        saturation=saturation,
        threads=settings.threads,
        neighbours=window_neighbours(detected, placed),
        background=background,
        spectrum=spectrum,
    )
    core.build()
    return core


def _maps_wanted(n: int, every: int, relative: bool) -> np.ndarray:
    """Positions demodulated without a sink: displacement frames and the last one.

    In relative mode the frame before the last is demodulated too, so that the last
    map (the report's) is against the previous frame; a displacement frame's map is
    against the one demodulated before it, which only gives it more to measure.
    """
    wanted = np.zeros(n, dtype=bool)
    wanted[::every] = True
    wanted[n - 1] = True
    if relative and n > 1:
        wanted[n - 2] = True
    return wanted


@dataclass
class FrameMaps:
    """One frame's maps, and what a run counts of them (:func:`frame_maps`).

    Attributes
    ----------
    demodulated : bool
        The frame went through the demodulator (False: damaged in transfer).
    maps : list of ndarray
        Each peak's :func:`~holoview.engine.frame_core.trusted_maps` (empty: none, for
        a frame not demodulated or not finite).
    noise : tuple of float
        Each peak's per-pixel phase noise, rad.
    peak_flags : tuple of frozenset of str
        Each peak's flags.
    flags : frozenset of str
        The frame's flags (``no_signal``, ``reference``, ...).
    values : tuple of complex
        Each peak's carrier value as the demodulator measured it, counts.
    unwrapped : tuple of float
        Each peak's mean phase unwrapped in time by this demodulator, rad (the target
        of the maps' 2 pi offset in the absolute and synthetic modes).
    scales : tuple of float
        Each map's units per radian (m/rad for delta-h, 1 for a phase).
    """

    demodulated: bool
    maps: list[np.ndarray] = field(default_factory=list)
    noise: tuple[float, ...] = ()
    peak_flags: tuple[frozenset[str], ...] = ()
    flags: frozenset[str] = frozenset()
    values: tuple[complex, ...] = ()
    unwrapped: tuple[float, ...] = ()
    scales: tuple[float, ...] = ()


def frame_maps(core: FrameCore, frame: np.ndarray, damaged: bool) -> FrameMaps:
    """Demodulate ``frame`` through ``core`` (advancing its reference) unless ``damaged``."""
    if damaged:
        return FrameMaps(demodulated=False)
    result = core.process(frame)
    demodulator = core.demodulator
    assert result is not None and demodulator is not None
    peaks, wavelength = result.peaks, demodulator.wavelength
    return FrameMaps(
        demodulated=True,
        maps=trusted_maps(result) if peaks else [],
        noise=tuple(r.noise for r in peaks),
        peak_flags=tuple(r.flags for r in peaks),
        flags=result.flags,
        values=tuple(r.carrier_value for r in peaks),
        unwrapped=tuple(r.mean_phase_unwrapped for r in peaks),
        scales=tuple(  # a map in metres has its peak's alpha and the wavelength
            1.0 if r.delta_h is None else float(phase_to_height(1.0, r.peak.alpha, wavelength))
            for r in peaks
        ),
    )


class MapsPass:
    """The maps of a run, frame after frame in order: the stateful half of the loop.

    The carrier values of a frame depend on that frame alone; the maps do not (their
    reference is the previous demodulated frame, or the first; the displacements are
    measured over frames in order). A run feeds this pass the frames it wants
    (:attr:`wanted`), in order, whether it measures the carriers in the same loop
    (:func:`demodulate_frames`) or on other processes
    (:func:`holoview.headless.stitch.demodulate_chunks`): both give the same maps.
    Frames demodulated elsewhere (:func:`frame_maps` in a worker) are given to
    :meth:`record` instead, in order.

    Parameters
    ----------
    core : FrameCore
        Built for the selected peaks (its reference starts at the first frame fed).
    data : RunData
        The run's record, whose map noise, flags, counts and timings this pass fills.
    n : int
        Frames in the run.
    sink : MapSink, optional
        Receives every frame's maps (every frame is then wanted).

    Attributes
    ----------
    wanted : ndarray of bool, shape (n,)
        The positions whose frames the pass needs.
    """

    def __init__(self, core: FrameCore, data: RunData, n: int, sink: MapSink | None) -> None:
        demodulator = core.build()
        assert demodulator is not None
        self._core = core
        self._data = data
        self._sink = sink
        self._labels = tuple(p.label for p in demodulator.peaks)
        self._every = max(1, n // COREGISTER_FRAMES)
        relative = demodulator.reference == "relative"
        self.wanted = np.ones(n, bool) if sink else _maps_wanted(n, self._every, relative)
        self._coregistration = Coregistration()
        self._last: list[np.ndarray] = []
        self._blank = np.full(data.box_shape, np.nan, np.float32)

    def feed(self, position: int, index: int, frame: np.ndarray, damaged: bool) -> None:
        """Demodulate the ``position``-th frame (input ``index``) unless ``damaged``.

        Frames not :attr:`wanted` are ignored; a damaged or non-finite frame leaves
        NaN maps in the sink.
        """
        if not self.wanted[position]:
            return
        t0 = time.perf_counter()
        maps = frame_maps(self._core, frame, damaged)
        self.record(position, index, maps, time.perf_counter() - t0)

    def record(self, position: int, index: int, frame: FrameMaps, seconds: float = 0.0) -> None:
        """Count the ``position``-th frame's maps (input ``index``), which took ``seconds``."""
        data = self._data
        t0 = time.perf_counter()
        if frame.demodulated:
            _count(data, position, frame)
        maps = frame.maps
        if maps and position % self._every == 0:
            self._coregistration.add_maps(
                self._labels, data.box_shape, maps, reference="reference" in frame.flags
            )
        t1 = time.perf_counter()
        data.demod_seconds += seconds + t1 - t0
        data.maps_seconds += seconds + t1 - t0
        if maps:
            self._last, data.last_frame = maps, index
        if self._sink is not None:
            for j in range(len(data.map_flags)):
                self._sink.write_map(position, j, maps[j] if maps else self._blank)
        data.write_seconds += time.perf_counter() - t1

    def finish(self) -> None:
        """Keep the last maps and the displacements in the run's record."""
        if self._last:
            self._data.last_maps = list(self._last)
        self._data.displacements = self._coregistration.displacements() or []


def new_run_data(core: FrameCore, n: int) -> RunData:
    """An empty record of a run of ``n`` frames through ``core`` (built), its series sized."""
    demodulator = core.build()
    assert demodulator is not None
    m = len(demodulator.peaks)
    series = PhaseSeries([p.label or f"P{j}" for j, p in enumerate(demodulator.peaks)], n)
    return RunData(
        series=series,
        map_noise_rad=np.full((n, m), np.nan),
        map_flags=[dict.fromkeys(MAP_PEAK_FLAGS, 0) for _ in range(m)],
        box_shape=demodulator.box_shape,
        radius=demodulator.radius,
        windows=demodulator.windows,
        last_maps=[None] * m,
        maps_in_metres=all(p.alpha is not None for p in demodulator.peaks),
    )


def check_run(data: RunData) -> RunData:
    """Return ``data``; InputError when no frame could be demodulated."""
    if not np.any(np.isfinite(data.values)):
        raise InputError("no frame could be demodulated (every frame is NaN or infinite)")
    return data


def demodulate_frames(
    source: InputFile,
    frames: range,
    times: np.ndarray,
    core: FrameCore,
    *,
    sink: MapSink | None = None,
    read_ahead: int = DEFAULT_DEPTH,
    progress: Callable[[int], None] | None = None,
) -> RunData:
    """Stream ``frames`` of ``source``: the carrier values of each, maps where wanted.

    Parameters
    ----------
    source : InputFile
        The input (read from a ``holoview-reader`` thread during the call).
    frames : range
        Input frame indices to process.
    times : ndarray, shape (len(frames),)
        Their times, s.
    core : FrameCore
        Built for the selected peaks (its reference starts at the first frame); the
        carrier probe measures the same peaks.
    sink : MapSink, optional
        Receives every frame's maps (every frame is then demodulated).
    read_ahead : int
        Frames read ahead.
    progress : callable, optional
        Called with the number of frames done, after each frame.

    Returns
    -------
    RunData
        After an interruption (KeyboardInterrupt) with at least one frame done, the
        series of the frames done and ``interrupted`` set; with none done, the
        interruption is raised again.
    """
    n = len(frames)
    data = new_run_data(core, n)
    series = data.series
    demodulator = core.build()
    assert demodulator is not None
    carriers = CarrierCore(core.frame_shape, core.saturation)
    carriers.configure(demodulator.peaks)
    maps = MapsPass(core, data, n, sink)
    start = time.perf_counter()
    done = 0
    reader = FrameReader(source.read, frames, depth=read_ahead)
    try:
        with reader:
            for position, (index, frame) in enumerate(reader):
                t0 = time.perf_counter()
                measured = carriers.measure(frame)
                assert measured is not None
                series.add(float(times[position]), index, measured)
                data.demod_seconds += time.perf_counter() - t0
                maps.feed(position, index, frame, "damaged" in measured.flags)
                done = position + 1
                if progress is not None:
                    progress(done)
    except KeyboardInterrupt:
        if done == 0:
            raise
        logger.warning("interrupted after %d of %d frames: results of those", done, n)
        data.interrupted = True
        series.truncate(done)
    maps.finish()
    data.read_seconds = reader.read_seconds
    data.wall_seconds = time.perf_counter() - start
    return check_run(data)


def _count(data: RunData, position: int, frame: FrameMaps) -> None:
    """Keep a demodulated frame's map noise and count its map flags."""
    data.demodulated += 1
    if "no_signal" in frame.flags:
        data.no_signal += 1
    for j, (noise, flags) in enumerate(zip(frame.noise, frame.peak_flags, strict=True)):
        data.map_noise_rad[position, j] = noise
        for flag in flags:
            if flag in data.map_flags[j]:
                data.map_flags[j][flag] += 1
