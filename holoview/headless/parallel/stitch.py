"""A run's passes on many processes: chunks measured elsewhere, stitched in order here.

The passes of :mod:`holoview.headless.frame_passes`, their per-frame work on a
:class:`~holoview.headless.parallel.runners.ChunkRunner`, giving the
:class:`~holoview.headless.run_data.RunData` one process gives on the same frames, the
same numbers, whatever the number of workers or chunks:

- :func:`measure_chunks`: the workers measure every frame's carrier values
  (:func:`~holoview.headless.parallel.chunks.measure_chunk`), which depend on that frame alone;
  this process adds them to the run's :class:`~holoview.engine.series.PhaseSeries`
  frame after frame, in order, as the serial loop does, as soon as the chunks before
  have come: the phase steps against the previous finite value, and the joint
  estimate with its ambiguities where the prefactors are known before the run. Nothing
  is computed per chunk, so no chunk boundary can show in the results. Meanwhile this
  process measures the displacements on frames spread over the run
  (:func:`~holoview.headless.frame_passes.spread_pass`), each once the chunk holding
  it is in. In ``relative`` mode with ``--maps`` the workers make every frame's maps
  in the same pass (:mod:`holoview.headless.parallel.chunk_maps`), the displacements measured
  first;
- :func:`map_chunks` (``--maps`` in the ``absolute`` and ``synthetic`` modes, and after
  an auto run's identification): the workers make every frame's maps and fused map,
  each chunk from the mean phases this process replays from the series up to its start.

This process keeps what depends on the order of the frames (the series, the
displacements, the mean phases at each chunk's start) and writes the maps in order;
workers on this machine hand a chunk's maps over in a file (:func:`spill_folder`,
:class:`~holoview.headless.parallel.chunk_maps.ChunkMaps`), not pickled.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace

import numpy as np

from holoview.headless.frame_passes import MapsSpec
from holoview.headless.input_identity import InputIdentity
from holoview.headless.inputs import FrameTimes, InputFile
from holoview.headless.parallel.chunk_maps import MapsWork, map_bytes
from holoview.headless.parallel.chunks import ChunkResult, make_tasks, split_frames
from holoview.headless.parallel.runners import ChunkRunner
from holoview.headless.reader import DEFAULT_DEPTH
from holoview.headless.run_data import DAMAGED_BIT, NONFINITE_BIT, MapRecord, RunData, check_run
from holoview.processing.fourier.fftplans import current_wisdom
from holoview.processing.maps.mean_phases import MeanPhases, MeanPhaseState
from holoview.processing.peaks.detection import Peak

logger = logging.getLogger(__name__)

__all__ = ["map_chunks", "measure_chunks", "spill_folder"]

#: Where workers on this machine write their chunks' maps: in memory.
SPILL_ROOT = "/dev/shm"

#: Free bytes ``SPILL_ROOT`` must have to be used (a container's may be 64 MB): the
#: chunks in flight and those waiting for their turn are there at once.
SPILL_FREE_BYTES = 2 << 30


@contextlib.contextmanager
def spill_folder(runner: ChunkRunner, maps: bool) -> Iterator[str | None]:
    """A folder for the workers' maps files, removed after the pass (None: pickled back).

    Only for workers that share this machine's files, in a run that makes maps, where
    :data:`SPILL_ROOT` is there with :data:`SPILL_FREE_BYTES` free.
    """
    try:
        free = shutil.disk_usage(SPILL_ROOT).free if os.access(SPILL_ROOT, os.W_OK) else 0
    except OSError:
        free = 0
    if not (maps and runner.shares_files) or free < SPILL_FREE_BYTES:
        yield None
        return
    folder = tempfile.mkdtemp(prefix="holoview-maps-", dir=SPILL_ROOT)
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _record_chunk(record: MapRecord, frames: range, result: ChunkResult) -> None:
    """Count and write a chunk's maps in order; delete the file they came in."""
    assert result.maps is not None
    chunk = result.maps.opened()
    for k in range(len(result)):
        record.record(result.start + k, frames[result.start + k], chunk.frame(k))
    if result.maps.spilled is not None:
        os.unlink(result.maps.spilled)


class _Gathered:
    """The chunks' results as they arrive, and the prefix of frames all measured."""

    def __init__(
        self,
        results: Iterator[ChunkResult],
        starts: list[int],
        n: int,
        progress: Callable[[int], None] | None,
        in_order: Callable[[ChunkResult], None],
    ) -> None:
        self._results = results
        self._in_order = in_order
        self._slot = {start: k for k, start in enumerate(starts)}
        self._ends = [*starts[1:], n]
        self.chunks: list[ChunkResult | None] = [None] * len(starts)
        self.done = 0  # frames in the chunks complete from the first
        self._ready = 0  # chunks complete from the first
        self._progress = progress
        self._measured = 0

    def close(self) -> None:
        """Let the runner cancel what is still pending."""
        close = getattr(self._results, "close", None)
        if close is not None:
            close()

    def until(self, position: int) -> None:
        """Wait until the chunk holding ``position`` and every one before it are in."""
        while self.done <= position:
            result = next(self._results)
            self.chunks[self._slot[result.start]] = result
            self._measured += len(result)
            while self._ready < len(self.chunks) and self.chunks[self._ready] is not None:
                chunk = self.chunks[self._ready]
                assert chunk is not None
                self._in_order(chunk)
                self.chunks[self._ready] = replace(chunk, maps=None)  # their memory back
                self.done = self._ends[self._ready]
                self._ready += 1
                logger.debug("%d frames stitched in order", self.done)
            if self._progress is not None:
                self._progress(self._measured)


def _gather(
    runner: ChunkRunner,
    gathered: _Gathered,
    data: RunData,
    n: int,
    *,
    what: str = "",
    meanwhile: Callable[[Callable[[int], None]], None] | None = None,
) -> None:
    """Take every chunk in order (``meanwhile`` first); an interruption keeps the prefix done."""
    try:
        if meanwhile is not None:
            meanwhile(gathered.until)
        gathered.until(n - 1)
    except KeyboardInterrupt:
        runner.abort()
        if gathered.done == 0:
            raise
        logger.warning(
            "interrupted after %d of %d frames%s: results of those", gathered.done, n, what
        )
        data.truncate(gathered.done)  # a chunk interrupted while added
    finally:
        gathered.close()


def measure_chunks(
    source: InputFile,
    frames: range,
    times: FrameTimes,
    data: RunData,
    peaks: Sequence[Peak],
    *,
    runner: ChunkRunner,
    identity: InputIdentity | None = None,
    read_ahead: int = DEFAULT_DEPTH,
    progress: Callable[[int], None] | None = None,
    spread: Callable[[Callable[[int], None]], None] | None = None,
    maps: tuple[MapsSpec, MapRecord] | None = None,
) -> RunData:
    """:func:`~holoview.headless.frame_passes.measure_frames`, the frames on ``runner``.

    Parameters
    ----------
    source : InputFile
        The input (its path is what the workers open).
    frames : range
        Input frame indices to process.
    times : FrameTimes
        Their times, s, and the frame intervals before each.
    data : RunData
        The run's record (its series set up, a joint estimate tracked where known).
    peaks : sequence of Peak
        The demodulator's peaks.
    runner : ChunkRunner
        Where the chunks are measured.
    identity : InputIdentity, optional
        The input's when the run started: every worker checks it before each chunk.
    read_ahead : int
        Frames read ahead (by each worker, and here).
    progress : callable, optional
        Called with the number of frames measured, as chunks complete.
    spread : callable, optional
        ``spread(until)``: this process's pass over frames spread over the run, run
        while the workers measure, calling ``until(position)`` before it takes a frame.
    maps : (MapsSpec, MapRecord), optional
        The workers make every frame's maps in the same pass (relative mode; the
        displacements measured before), recorded here in order.

    Returns
    -------
    RunData
        ``data``, as :func:`~holoview.headless.frame_passes.measure_frames` gives it; its
        timings add up the workers'. After an interruption with frames done, the
        frames of the chunks complete from the first, ``interrupted`` set.
    """
    with spill_folder(runner, maps is not None) as spill:
        return _measure_chunks(
            source,
            frames,
            times,
            data,
            peaks,
            runner=runner,
            identity=identity,
            read_ahead=read_ahead,
            progress=progress,
            spread=spread,
            maps=maps,
            spill=spill,
        )


def _measure_chunks(
    source: InputFile,
    frames: range,
    times: FrameTimes,
    data: RunData,
    peaks: Sequence[Peak],
    *,
    runner: ChunkRunner,
    identity: InputIdentity | None,
    read_ahead: int,
    progress: Callable[[int], None] | None,
    spread: Callable[[Callable[[int], None]], None] | None,
    maps: tuple[MapsSpec, MapRecord] | None,
    spill: str | None,
) -> RunData:
    n = len(frames)
    data.workers = runner.name
    chunks = split_frames(
        n,
        runner.workers,
        maps=maps is not None,
        map_bytes=map_bytes(data.box_shape, len(peaks)),
    )
    works = None
    if maps is not None:
        wisdom = current_wisdom()
        fused = bool(data.fused_labels)
        works = [
            MapsWork(maps[0], wisdom, fused, before=tuple(frames[: chunk.start]), spill=spill)
            for chunk in chunks
        ]
    tasks = make_tasks(
        source.path,
        frames,
        chunks,
        peaks=peaks,
        frame_shape=source.frame_shape,
        saturation=source.saturation,
        read_ahead=read_ahead,
        maps=works,
        identity=identity,
    )
    logger.info("%d frames in %d chunks on %s", n, len(chunks), runner.name)
    series = data.series

    def add(result: ChunkResult) -> None:
        start = time.perf_counter()
        for k in range(len(result)):
            position = result.start + k
            series.add(
                float(times.times[position]),
                frames[position],
                result.measured(k),
                intervals=times.interval(position),
            )
            data.frame_bits[position] = result.flags[k]
        if maps is not None and result.maps is not None:
            _record_chunk(maps[1], frames, result)
        _account(data, result, time.perf_counter() - start)

    gathered = _Gathered(runner.run(tasks), [c.start for c in chunks], n, progress, add)
    _gather(runner, gathered, data, n, meanwhile=spread)
    return check_run(data)


def _account(data: RunData, result: ChunkResult, parent_seconds: float) -> None:
    data.read_seconds += result.read_seconds
    data.demod_seconds += result.measure_seconds + result.maps_seconds
    data.maps_seconds += result.maps_seconds
    data.worker_seconds += result.measure_seconds + result.maps_seconds
    data.parent_seconds += parent_seconds


def chunk_states(
    values: np.ndarray,
    frame_bits: np.ndarray,
    chunks: Sequence[range],
    spec: MapsSpec,
    *,
    start: MeanPhaseState,
    mode: str,
) -> list[tuple[MeanPhaseState, int | None]]:
    """Per chunk, the mean phases and the reference frame's position the serial pass has there.

    The serial maps pass (:func:`~holoview.headless.frame_passes.maps_pass`) advances
    its mean phases (:class:`~holoview.processing.maps.mean_phases.MeanPhases`) on the
    series' values of every frame it demodulates; this replays it, with the same
    arithmetic, from ``start`` (a fresh demodulator's state). ``values`` (K, M) and
    ``frame_bits`` (K,) are those of the frames the pass takes, in its order (a run's
    series, or the frames spread over it), the chunks' positions index them.
    """
    m = len(spec.peaks)
    phases = MeanPhases(m, mode)
    phases.restore(start)
    first = last = None
    background = spec.background is not None
    out: list[tuple[MeanPhaseState, int | None]] = []
    for chunk in chunks:
        reference = None
        if mode == "relative":
            reference = last
        elif mode == "absolute" and not background:
            reference = first
        out.append((phases.state(), reference))
        for position in chunk:
            if int(frame_bits[position]) & (DAMAGED_BIT | NONFINITE_BIT):
                continue  # not demodulated (RunData.demodulable)
            for j in range(m):
                phases.advance(j, complex(values[position, j]))
            first = position if first is None else first
            last = position
    return out


def map_chunks(
    source: InputFile,
    frames: range,
    data: RunData,
    spec: MapsSpec,
    record: MapRecord,
    *,
    runner: ChunkRunner,
    identity: InputIdentity | None = None,
    read_ahead: int = DEFAULT_DEPTH,
    progress: Callable[[int], None] | None = None,
) -> RunData:
    """:func:`~holoview.headless.frame_passes.maps_pass`, the frames' maps on ``runner``.

    Parameters
    ----------
    source : InputFile
        The input.
    frames : range
        The run's input frame indices.
    data : RunData
        The run's record, its series measured.
    spec : MapsSpec
        The maps step, its displacements measured.
    record : MapRecord
        Counts and writes each frame's maps, in order.
    runner : ChunkRunner
        Where the chunks' maps are made.
    identity : InputIdentity, optional
        The input's when the run started: every worker checks it before each chunk.
    read_ahead : int
        Frames read ahead by each worker.
    progress : callable, optional
        Called with the number of frames done, as chunks complete.

    Returns
    -------
    RunData
        ``data``; after an interruption with frames done, the frames of the chunks
        complete from the first, ``interrupted`` set.
    """
    with spill_folder(runner, True) as spill:
        return _map_chunks(
            source,
            frames,
            data,
            spec,
            record,
            runner=runner,
            identity=identity,
            read_ahead=read_ahead,
            progress=progress,
            spill=spill,
        )


def _map_chunks(
    source: InputFile,
    frames: range,
    data: RunData,
    spec: MapsSpec,
    record: MapRecord,
    *,
    runner: ChunkRunner,
    identity: InputIdentity | None,
    read_ahead: int,
    progress: Callable[[int], None] | None,
    spill: str | None,
) -> RunData:
    n = len(data.series)
    core = spec.core(source.frame_shape, source.saturation)
    demod = core.demodulator
    assert demod is not None
    wisdom = current_wisdom()
    chunks = split_frames(
        n, runner.workers, maps=True, map_bytes=map_bytes(data.box_shape, len(demod.peaks))
    )
    states = chunk_states(
        data.values,
        data.frame_bits,
        chunks,
        spec,
        start=demod.phase_state(),
        mode=demod.reference,
    )
    fused = bool(data.fused_labels)
    works = []
    for chunk, (state, reference) in zip(chunks, states, strict=True):
        works.append(
            MapsWork(
                spec,
                wisdom,
                fused,
                values=data.values[chunk.start : chunk.stop].copy(),
                frame_bits=data.frame_bits[chunk.start : chunk.stop].copy(),
                state=state,
                reference=None if reference is None else frames[reference],
                reference_values=None if reference is None else data.values[reference].copy(),
                spill=spill,
            )
        )
    tasks = make_tasks(
        source.path,
        frames,
        chunks,
        peaks=spec.peaks,
        frame_shape=source.frame_shape,
        saturation=source.saturation,
        read_ahead=read_ahead,
        maps=works,
        identity=identity,
    )

    def add(result: ChunkResult) -> None:
        start = time.perf_counter()
        _record_chunk(record, frames, result)
        _account(data, result, time.perf_counter() - start)

    gathered = _Gathered(runner.run(tasks), [c.start for c in chunks], n, progress, add)
    _gather(runner, gathered, data, n, what="' maps")
    return data
