"""A run on many processes: chunks measured elsewhere, stitched in order here.

:func:`demodulate_chunks` gives the :class:`~holoview.headless.pipeline.RunData` that
:func:`~holoview.headless.pipeline.demodulate_frames` gives on the same frames, the
same numbers, whatever the number of workers or chunks:

- the workers (:mod:`holoview.headless.parallel`) measure every frame's carrier values
  (:func:`~holoview.headless.chunks.measure_chunk`), which depend on that frame alone;
- this process adds them to the run's
  :class:`~holoview.engine.series.PhaseSeries` frame after frame, in order, as the
  serial loop does, as soon as the chunks before have come: the phase steps against
  the previous finite value, and the joint estimate with its ambiguities (a Kalman-like
  prediction from frame to frame) where the prefactors are known before the run;
  after the run (:mod:`holoview.headless.analysis`) the unwrapping in time, the depths
  and the rates (and the joint estimate of an auto run), once over the whole series.
  Nothing is computed per chunk, so no chunk boundary can show in the results;
- meanwhile this process demodulates the frames the maps need
  (:class:`~holoview.headless.pipeline.MapsPass`: about 50 frames spread over the run
  for the displacements, and the last ones), in order, with the same core: the maps'
  reference (previous or first frame) and the displacements see the same frames. A
  frame is demodulated once the chunk holding it is measured, so that it is known
  whether the frame was damaged, and so that an interrupted run keeps a prefix of
  frames that both halves have done;
- with ``--maps`` (every frame's maps, most of the run's time) the workers demodulate
  them too, in short chunks (:mod:`holoview.headless.chunk_maps`: each worker starts
  from the serial run's reference, and this process moves the maps by the whole turns
  of mean phase a worker could not know), and this process counts them, measures the
  displacements over them and writes them, in order.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from dataclasses import replace

import numpy as np

from holoview.engine.frame_core import FrameCore
from holoview.headless.analysis import JointSetup
from holoview.headless.chunk_maps import MapsSpec, TurnFix
from holoview.headless.chunks import CHUNK_FLAGS, ChunkResult, make_tasks, split_frames
from holoview.headless.input_identity import InputIdentity
from holoview.headless.inputs import InputFile
from holoview.headless.parallel import ChunkRunner
from holoview.headless.pipeline import MapSink, MapsPass, RunData, check_run, new_run_data
from holoview.headless.reader import DEFAULT_DEPTH, FrameReader

logger = logging.getLogger(__name__)

_DAMAGED_BIT = 1 << CHUNK_FLAGS.index("damaged")


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
                self.chunks[self._ready] = replace(chunk, maps=())  # their memory back
                self.done = self._ends[self._ready]
                self._ready += 1
                logger.debug("%d frames stitched in order", self.done)
            if self._progress is not None:
                self._progress(self._measured)

    def damaged(self, position: int) -> bool:
        """Whether the frame at ``position`` (of a chunk in) was damaged in transfer."""
        k = int(np.searchsorted(self._ends, position, side="right"))
        chunk = self.chunks[k]
        assert chunk is not None
        return bool(chunk.flags[position - chunk.start] & _DAMAGED_BIT)


def demodulate_chunks(
    source: InputFile,
    frames: range,
    times: np.ndarray,
    core: FrameCore,
    runner: ChunkRunner,
    *,
    sink: MapSink | None = None,
    read_ahead: int = DEFAULT_DEPTH,
    progress: Callable[[int], None] | None = None,
    joint: JointSetup | None = None,
    identity: InputIdentity | None = None,
) -> RunData:
    """:func:`~holoview.headless.pipeline.demodulate_frames`, the carriers on ``runner``.

    Parameters
    ----------
    source : InputFile
        The input (its path is what the workers open).
    frames : range
        Input frame indices to process.
    times : ndarray, shape (len(frames),)
        Their times, s.
    core : FrameCore
        Built for the selected peaks; the maps are demodulated with it here.
    runner : ChunkRunner
        Where the chunks are measured.
    sink : MapSink, optional
        Receives every frame's maps (every frame is then demodulated, in the workers).
    read_ahead : int
        Frames read ahead (by each worker, and here).
    progress : callable, optional
        Called with the number of frames measured, as chunks complete.
    joint : JointSetup, optional
        The joint estimate known before the frames
        (:func:`~holoview.headless.analysis.known_joint`): made here as the chunks come
        in, in order, while the workers measure the next ones, and kept by the analysis.
    identity : InputIdentity, optional
        The input's when the run started: every worker checks it before each chunk.

    Returns
    -------
    RunData
        As :func:`~holoview.headless.pipeline.demodulate_frames`; its timings add up the
        workers' (``read_seconds``, ``demod_seconds``), ``wall_seconds`` is the run's.
        After an interruption with frames done, the frames of the chunks complete from
        the first, ``interrupted`` set.
    """
    start_time = time.perf_counter()
    n = len(frames)
    data = new_run_data(core, n)
    data.workers = runner.name
    demodulator = core.build()
    assert demodulator is not None
    maps = MapsPass(core, data, n, sink)
    chunks = split_frames(n, runner.workers, maps=sink is not None)
    tasks = make_tasks(
        source.path,
        frames,
        chunks,
        peaks=demodulator.peaks,
        frame_shape=core.frame_shape,
        saturation=core.saturation,
        read_ahead=read_ahead,
        maps=MapsSpec.of(core) if sink is not None else None,
        identity=identity,
    )
    logger.info("%d frames in %d chunks on %s", n, len(chunks), runner.name)
    series = data.series
    if joint is not None:
        series.track_joint(joint.alphas, joint.couplings, joint.wavelength_m, joint.exclude)

    turns = TurnFix(demodulator.reference, len(demodulator.peaks))

    def add(result: ChunkResult) -> None:
        start = time.perf_counter()
        for k in range(len(result)):
            position = result.start + k
            series.add(float(times[position]), frames[position], result.measured(k))
        for k, frame_maps in enumerate(result.maps):
            turns.apply(frame_maps)
            maps.record(result.start + k, frames[result.start + k], frame_maps)
        data.read_seconds += result.read_seconds
        data.demod_seconds += result.measure_seconds + result.maps_seconds
        data.maps_seconds += result.maps_seconds
        data.worker_seconds += result.measure_seconds + result.maps_seconds
        data.parent_seconds += time.perf_counter() - start

    gathered = _Gathered(runner.run(tasks), [c.start for c in chunks], n, progress, add)
    positions = np.flatnonzero(maps.wanted) if sink is None else np.zeros(0, int)
    reader = FrameReader(source.read, [frames[int(p)] for p in positions], depth=read_ahead)
    try:
        with reader:
            for k, (index, frame) in enumerate(reader):
                position = int(positions[k])
                gathered.until(position)
                start = time.perf_counter()
                maps.feed(position, index, frame, gathered.damaged(position))
                data.parent_seconds += time.perf_counter() - start
        gathered.until(n - 1)
    except KeyboardInterrupt:
        runner.abort()
        if gathered.done == 0:
            raise
        logger.warning("interrupted after %d of %d frames: results of those", gathered.done, n)
        data.interrupted = True
        series.truncate(gathered.done)  # a chunk interrupted while added
    finally:
        gathered.close()
    maps.finish()
    data.read_seconds += reader.read_seconds
    data.wall_seconds = time.perf_counter() - start_time
    return check_run(data)
