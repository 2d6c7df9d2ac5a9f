"""A headless run's passes over its frames, in one process.

1. :func:`measure_frames`: every frame's carrier values (the carrier probe,
   :class:`~holoview.engine.frame_core.CarrierCore`, what the live series worker runs)
   into the run's :class:`~holoview.engine.series.PhaseSeries` (estimated jointly
   by the analysis, after the pass: :mod:`holoview.headless.run_passes`): all the
   trends and rates need, at a quarter of a full FFT's time a frame.
2. :func:`spread_pass`: the maps of :data:`COREGISTER_FRAMES` frames spread over the
   run (and of the last), through the maps step
   (:class:`~holoview.engine.map_step.MapStep`): the peaks' displacements, measured
   before any map is fused, so that every frame's fused map is co-registered alike;
   and, without ``--maps``, the last frame's maps for the report. Its maps are on the
   demodulation box's grid whatever the run's (``--maps-grid``): the displacements of
   maps on the frame's grid are the box's, in frame pixels.
3. :func:`maps_pass` (``--maps``): every frame's maps and fused map, through the maps
   step, into the :class:`~holoview.headless.run_data.MapSink` as they come; the maps'
   mean phases follow the series' values of step 1, so that a worker given a chunk of
   the run places every map's 2 pi offset as this pass does
   (:mod:`holoview.headless.parallel.chunk_maps`).

Each pass reads its frames through a :class:`~holoview.headless.reader.FrameReader`,
so memory stays bounded by the few frames it reads ahead. :class:`MapsSpec` says what
a pass's maps step is, here and in the workers.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import CarrierCore, FrameCore
from holoview.engine.map_step import Coregistration, FrameMaps, MapStep, regridded
from holoview.headless.inputs import FrameTimes, InputFile
from holoview.headless.reader import DEFAULT_DEPTH, FrameReader
from holoview.headless.run_data import (
    DAMAGED_BIT,
    NONFINITE_BIT,
    MapRecord,
    RunData,
    check_run,
    flag_bits,
)
from holoview.processing.maps.coregister import Displacement
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.matched import Window
from holoview.processing.peaks.surface_spectrum import SurfaceSpectrum

logger = logging.getLogger(__name__)

__all__ = [
    "COREGISTER_FRAMES",
    "MapsSpec",
    "SpreadMaps",
    "frame_maps",
    "maps_pass",
    "measure_frames",
    "spread_pass",
    "spread_positions",
]

#: Frames, spread over a run, whose maps measure the peaks' displacements.
COREGISTER_FRAMES = 50


@dataclass(frozen=True)
class MapsSpec:
    """What a pass's maps step is (:meth:`step`): the same here and in every worker.

    Attributes
    ----------
    experiment : Experiment
        Window, radius, reference, unwrapping, wavelength and refractive indices.
    peaks : tuple of Peak
        The peaks demodulated, with the prefactors the maps take (signed as measured).
    neighbours : tuple of (fx, fy)
        The detected peaks that bound windows, cycles/pixel (the surface's sidebands
        are not peaks: :func:`~holoview.processing.peaks.radii.window_neighbours`).
    threads : int
        FFTW threads per frame.
    background : ndarray or None
        The background hologram of absolute phases, counts.
    exclude : tuple of bool
        Peaks kept out of the fused map besides those without alpha.
    displacements : tuple of Displacement
        The displacements measured before the pass (empty: none).
    windows : tuple of Window
        Each peak's window, decided once for the run (:meth:`matched`; empty: by the
        experiment's rule, the bound or the radius given, from the carriers).
    grid : {"box", "frame"}
        Where the maps are (``--maps-grid``): the demodulation box's grid or the
        frame's pixels.
    """

    experiment: Experiment
    peaks: tuple[Peak, ...]
    neighbours: tuple[tuple[float, float], ...]
    threads: int
    background: np.ndarray | None
    exclude: tuple[bool, ...] = ()
    displacements: tuple[Displacement, ...] = ()
    windows: tuple[Window, ...] = ()
    grid: str = "box"

    def matched(
        self, frame_shape: tuple[int, int], saturation: float | None, spectrum: SurfaceSpectrum
    ) -> MapsSpec:
        """This spec with each peak's window matched to ``spectrum``, here and in the workers."""
        core = FrameCore(
            frame_shape,
            self.experiment,
            self.peaks,
            saturation=saturation,
            threads=self.threads,
            neighbours=self.neighbours,
            spectrum=spectrum,
        )
        demod = core.build()
        assert demod is not None
        return replace(self, windows=demod.windows)

    def core(self, frame_shape: tuple[int, int], saturation: float | None) -> FrameCore:
        """A new core, its demodulator built (its own reference; the FFTW plans cached)."""
        core = FrameCore(
            frame_shape,
            self.experiment,
            self.peaks,
            saturation=saturation,
            threads=self.threads,
            background=self.background,
            neighbours=self.neighbours,
            windows=self.windows or None,
            grid=self.grid,
        )
        core.build()
        return core

    def step(self, frame_shape: tuple[int, int], saturation: float | None) -> MapStep:
        """A new maps step: displacements fixed when the spec has them, else measured."""
        core = self.core(frame_shape, saturation)
        demod = core.demodulator
        assert demod is not None
        fixed = None
        if self.displacements:
            labels = [p.label for p in demod.peaks]
            fixed = (labels, demod.box_shape, list(self.displacements))
        return MapStep(core, Coregistration(fixed), self.exclude or None)


def measure_frames(
    source: InputFile,
    frames: range,
    times: FrameTimes,
    data: RunData,
    peaks: Sequence[Peak],
    *,
    read_ahead: int = DEFAULT_DEPTH,
    progress: Callable[[int], None] | None = None,
    maps: tuple[MapStep, MapRecord] | None = None,
    spread: SpreadMaps | None = None,
) -> RunData:
    """Stream ``frames`` of ``source`` into ``data``'s series: each frame's carrier values.

    Parameters
    ----------
    source : InputFile
        The input (read from a ``holoview-reader`` thread during the call).
    frames : range
        Input frame indices to process.
    times : FrameTimes
        Their times, s, and the frame intervals before each.
    data : RunData
        The run's record (its series set up).
    peaks : sequence of Peak
        The demodulator's peaks.
    read_ahead : int
        Frames read ahead.
    progress : callable, optional
        Called with the number of frames done, after each frame.
    maps : (MapStep, MapRecord), optional
        Make every frame's maps in the same pass (``--maps``, the displacements
        measured before: :func:`spread_pass`), recorded as they come.
    spread : SpreadMaps, optional
        Make the spread pass's maps in this pass, as its frames come (peaks known
        before the run, one process): each frame is read and measured once. Its
        displacements are kept (:meth:`SpreadMaps.finish`) unless interrupted.

    Returns
    -------
    RunData
        ``data``. After an interruption (KeyboardInterrupt) with at least one frame
        done, the series of the frames done and ``interrupted`` set; with none done,
        the interruption is raised again.
    """
    n = len(frames)
    series = data.series
    carriers = CarrierCore(source.frame_shape, source.saturation)
    carriers.configure(peaks)
    done = 0
    reader = FrameReader(source.read, frames, depth=read_ahead)
    try:
        with reader:
            for position, (index, frame) in enumerate(reader):
                t0 = time.perf_counter()
                measured = carriers.measure(frame)
                assert measured is not None
                series.add(
                    float(times.times[position]),
                    index,
                    measured,
                    intervals=times.interval(position),
                )
                bits = flag_bits(measured.flags)
                data.frame_bits[position] = bits
                t1 = time.perf_counter()
                data.demod_seconds += t1 - t0
                if maps is not None:
                    _record_maps(
                        data,
                        maps,
                        frame,
                        position=position,
                        index=index,
                        values=measured.values,
                        bits=bits,
                    )
                if spread is not None and spread.wanted[position]:
                    spread.take(position, index, frame, measured.values, bits)
                done = position + 1
                if progress is not None:
                    progress(done)
    except KeyboardInterrupt:
        if done == 0:
            raise
        logger.warning("interrupted after %d of %d frames: results of those", done, n)
        data.truncate(done)
    data.read_seconds += reader.read_seconds
    if spread is not None and not data.interrupted:
        spread.finish()
    return check_run(data)


def spread_positions(n: int, relative: bool) -> tuple[np.ndarray, int]:
    """The positions of a run's spread pass, and every how many frames one measures.

    One frame every ``n // COREGISTER_FRAMES`` measures the displacements; the last is
    demodulated too (the report's maps), and in relative mode the one before it, so
    that the last map is against the previous frame (a displacement frame's map is
    against the one demodulated before it, which only gives it more to measure).

    Examples
    --------
    >>> positions, every = spread_positions(10, relative=True)
    >>> positions.tolist(), every
    ([0, 1, 2, 3, 4, 5, 6, 7, 8, 9], 1)
    >>> spread_positions(200, relative=False)[0][-3:].tolist()
    [192, 196, 199]
    """
    every = max(1, n // COREGISTER_FRAMES)
    wanted = np.zeros(n, dtype=bool)
    wanted[::every] = True
    wanted[n - 1] = True
    if relative and n > 1:
        wanted[n - 2] = True
    return np.flatnonzero(wanted), every


class SpreadMaps:
    """The maps of the frames spread over a run (:func:`spread_positions`), as they come.

    Each frame at a measuring position adds its maps to the displacement estimate;
    with ``record``, the frames' maps are counted into ``data`` and the last one's
    kept, fused (the report's). Fed by :func:`spread_pass`, or by :func:`measure_frames`
    where the spread frames' maps are made in the series pass.

    Parameters
    ----------
    source : InputFile
        The input.
    n : int
        Frames in the run.
    data : RunData
        The run's record: its displacements, fused labels and, with ``record``, its map
        counts and last maps are this pass's.
    spec : MapsSpec
        The maps step (its displacements are measured here).
    record : bool
        Count these frames' maps into ``data`` and keep the last (no ``--maps`` pass).

    Attributes
    ----------
    positions : ndarray of int
        The run's positions whose frames are demodulated, in order.
    wanted : ndarray of bool, shape (n,)
        The same, as a mask.
    """

    def __init__(
        self, source: InputFile, n: int, data: RunData, spec: MapsSpec, *, record: bool
    ) -> None:
        self.positions, self._every = spread_positions(n, spec.experiment.reference == "relative")
        self.wanted = np.zeros(n, dtype=bool)
        self.wanted[self.positions] = True
        self._n = n
        self._data = data
        self._record = record
        # on the box's grid whatever the run's: displacements of frame-grid maps are the box's
        self.step = replace(spec, grid="box").step(source.frame_shape, source.saturation)
        self._counts = MapRecord(data) if record else None

    def take(
        self,
        position: int,
        index: int,
        frame: np.ndarray,
        values: np.ndarray,
        bits: int,
        *,
        step: MapStep | None = None,
    ) -> None:
        """Demodulate the frame at ``position`` (input ``index``), its carrier values and bits.

        With :attr:`step`, or ``step``: another in the state :attr:`step` would hold
        there, sharing its co-registration.
        """
        t0 = time.perf_counter()
        maps = frame_maps(
            step or self.step,
            frame,
            values,
            bits,
            estimate=self.estimates(position),
            fuse=self.fuses(position),
            shifts=False,
        )
        if self._counts is not None:
            self._counts.record(position, index, maps)
        seconds = time.perf_counter() - t0
        self._data.maps_seconds += seconds
        self._data.demod_seconds += seconds

    def estimates(self, position: int) -> bool:
        """Whether the frame at ``position`` adds its maps to the displacement estimate."""
        return position % self._every == 0

    def fuses(self, position: int) -> bool:
        """Whether the frame at ``position`` is fused (the last one's, recorded)."""
        return self._record and position == self._n - 1

    def made(self, position: int, index: int, maps: FrameMaps) -> None:
        """Take the maps of the frame at ``position`` (input ``index``) made elsewhere.

        Made by a step in the state :attr:`step` would hold there, without the estimate
        (:func:`frame_maps` with ``estimate`` False): the maps are added to the estimate
        here, so that, taken in order, the estimate is the one :meth:`take` makes.
        """
        result = maps.result
        if self.estimates(position) and result is not None and result.peaks:
            self.step.coregistration.add_maps(
                tuple(r.peak.label for r in result.peaks),
                result.box_shape,
                maps.maps,
                reference="reference" in result.flags,
            )
        if self._counts is not None:
            self._counts.record(position, index, maps)

    def finish(self) -> list[Displacement]:
        """Keep the displacements measured and the fused labels in the run's record."""
        data = self._data
        demod = self.step.core.demodulator
        assert demod is not None
        measured_shifts = self.step.coregistration.displacements() or []
        if measured_shifts and data.box_shape != demod.box_shape:
            measured_shifts = regridded(measured_shifts, demod.box_shape, data.box_shape)
        data.displacements = list(measured_shifts)
        data.fused_labels = _fused_labels(self.step)
        return data.displacements


def spread_pass(
    source: InputFile,
    frames: range,
    data: RunData,
    spec: MapsSpec,
    *,
    record: bool,
    read_ahead: int = DEFAULT_DEPTH,
    until: Callable[[int], None] | None = None,
    measured: bool = False,
) -> list[Displacement]:
    """Measure the displacements over frames spread over the run (:class:`SpreadMaps`).

    The frames' carrier values are measured here (the same probe, the same numbers as
    the series'), so that the pass may come before the series, or beside it; after
    it (``measured``), the series' values are taken.

    Parameters
    ----------
    source : InputFile
        The input.
    frames : range
        The run's input frame indices (those of an interrupted run's frames done).
    data : RunData
        The run's record (:class:`SpreadMaps`).
    spec : MapsSpec
        The maps step (its displacements are measured here, on the box's grid, and
        given on the spec's).
    record : bool
        Count these frames' maps into ``data`` and keep the last (no ``--maps`` pass).
    read_ahead : int
        Frames read ahead.
    until : callable, optional
        ``until(position)``: called before the frame at ``position`` is taken (a
        parallel run takes the workers' chunks in meanwhile).
    measured : bool
        The series of every frame is in ``data`` already, of the same peaks in the same
        order: its carrier values and flag bits are used rather than measured again.

    Returns
    -------
    list of Displacement
        Also kept in ``data.displacements`` (empty when not measured).
    """
    spread = SpreadMaps(source, len(frames), data, spec, record=record)
    positions = spread.positions
    probe = None
    if not measured:
        demod = spread.step.core.demodulator
        assert demod is not None
        probe = CarrierCore(source.frame_shape, source.saturation)
        probe.configure(demod.peaks)
    reader = FrameReader(source.read, [frames[int(p)] for p in positions], depth=read_ahead)
    with reader:
        for k, (index, frame) in enumerate(reader):
            position = int(positions[k])
            if until is not None:
                until(position)
            if probe is None:
                values, bits = data.values[position], int(data.frame_bits[position])
            else:
                t0 = time.perf_counter()
                probed = probe.measure(frame)
                assert probed is not None
                values, bits = probed.values, flag_bits(probed.flags)
                seconds = time.perf_counter() - t0
                data.maps_seconds += seconds
                data.demod_seconds += seconds
            spread.take(position, index, frame, values, bits)
    data.read_seconds += reader.read_seconds
    return spread.finish()


def _fused_labels(step: MapStep) -> tuple[str, ...]:
    """The labels of the peaks the step fuses (none when fewer than two)."""
    demod = step.core.demodulator
    assert demod is not None
    labels = tuple(
        p.label or f"P{j}"
        for j, (p, use) in enumerate(zip(demod.peaks, step.fused_peaks(), strict=True))
        if use and p.alpha is not None
    )
    return labels if len(labels) >= 2 else ()


def frame_maps(
    step: MapStep,
    frame: np.ndarray,
    values: np.ndarray,
    bits: int,
    *,
    estimate: bool = False,
    fuse: bool = True,
    shifts: bool = True,
) -> FrameMaps:
    """The maps step of one frame of a run, given its carrier values and probe flag bits.

    A frame the series flagged damaged is not demodulated, one flagged non-finite has
    no maps (:meth:`~holoview.headless.run_data.RunData.demodulable`): the demodulator
    sees exactly the frames whose values its mean phases are replayed from.
    """
    if bits & DAMAGED_BIT:
        return FrameMaps(demodulated=False)
    if bits & NONFINITE_BIT:
        return FrameMaps(demodulated=True, flags=frozenset({"nonfinite"}))
    return step.process(frame, values, estimate=estimate, fuse=fuse, shifts=shifts)


def _record_maps(
    data: RunData,
    maps: tuple[MapStep, MapRecord],
    frame: np.ndarray,
    *,
    position: int,
    index: int,
    values: np.ndarray,
    bits: int,
) -> None:
    """Make one frame's maps with ``maps``' step, record them, and count the time spent."""
    t0 = time.perf_counter()
    made = frame_maps(maps[0], frame, values, bits)
    t1 = time.perf_counter()
    maps[1].record(position, index, made)
    data.demod_seconds += t1 - t0
    data.maps_seconds += t1 - t0


def maps_pass(
    source: InputFile,
    frames: range,
    data: RunData,
    spec: MapsSpec,
    record: MapRecord,
    *,
    read_ahead: int = DEFAULT_DEPTH,
    progress: Callable[[int], None] | None = None,
) -> RunData:
    """Every frame's maps and fused map into ``record``'s sink, in order (``--maps``).

    Parameters
    ----------
    source : InputFile
        The input.
    frames : range
        The run's input frame indices.
    data : RunData
        The run's record, its series measured (the maps' mean phases follow its
        values); its map counts are this pass's.
    spec : MapsSpec
        The maps step, its displacements measured (:func:`spread_pass`).
    record : MapRecord
        Counts each frame's maps into ``data`` and writes them.
    read_ahead : int
        Frames read ahead.
    progress : callable, optional
        Called with the number of frames done, after each frame.

    Returns
    -------
    RunData
        ``data``; after an interruption (KeyboardInterrupt) with frames done, their
        series only and ``interrupted`` set; with none done, the interruption is raised
        again.
    """
    n = len(data.series)
    step = spec.step(source.frame_shape, source.saturation)
    reader = FrameReader(source.read, frames[:n], depth=read_ahead)
    done = 0
    try:
        with reader:
            for position, (index, frame) in enumerate(reader):
                values, bits = data.values[position], int(data.frame_bits[position])
                _record_maps(
                    data,
                    (step, record),
                    frame,
                    position=position,
                    index=index,
                    values=values,
                    bits=bits,
                )
                done = position + 1
                if progress is not None:
                    progress(done)
    except KeyboardInterrupt:
        if done == 0:
            raise
        logger.warning("interrupted after %d of %d frames' maps: results of those", done, n)
        data.truncate(done)
    data.read_seconds += reader.read_seconds
    return data
