"""A run's frames in contiguous chunks, and what a worker does with one.

The carrier values of a frame (:class:`~holoview.engine.frame_core.CarrierCore`: the
spectrum at each peak's exact carrier, its phase noise and the frame's flags) depend on
that frame alone, and they are most of a run's time. A worker process measures them
for one chunk of frames (:func:`measure_chunk`): it opens the input itself, read-only,
builds its own probe (its own FFTW plans) and streams the chunk through a
:class:`~holoview.headless.reader.FrameReader`, so that its memory is a few frames
and the chunk's carrier values (a few numbers a frame), whatever the run's length.
Everything that depends on the order of the frames (the phase steps, the unwrapping in
time, the joint estimate, the displacements, the rates) is computed once, in order,
from the gathered values (:mod:`holoview.headless.parallel.stitch`). No frame is needed twice:
the chunks do not overlap. With ``--maps`` the worker makes every frame's maps of its
chunk too, and the fused map (most of such a run's time), through the run's maps step
from the state the serial run holds there (:mod:`holoview.headless.parallel.chunk_maps`), in
shorter chunks.

:func:`plan_jobs` settles ``--jobs``: the default is every usable core but one (the
parent reads the maps' frames and stitches), when the run is long enough to gain.
"""

from __future__ import annotations

import itertools
import logging
import os
import socket
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from holoview.engine.frame_core import CarrierCore
from holoview.errors import InputError
from holoview.headless.input_identity import InputIdentity
from holoview.headless.inputs import InputFile
from holoview.headless.parallel import chunk_maps
from holoview.headless.parallel.chunk_maps import ChunkMaps, MapsWork
from holoview.headless.reader import DEFAULT_DEPTH, FrameReader
from holoview.headless.run_data import FRAME_FLAG_BITS, flag_bits
from holoview.processing.fourier.fftplans import usable_cpus
from holoview.processing.peaks.detection import Peak
from holoview.processing.series.carrier_probe import CarrierValues

logger = logging.getLogger(__name__)

#: Frames a job should have at least for a process to pay for its start (about a second
#: to import and plan, against about 4 ms a 1024 x 1024 frame).
MIN_FRAMES_PER_JOB = 250

#: Chunks per job: more chunks than jobs even out their speeds and let the progress
#: bar move; each chunk costs a task and an open of the input.
CHUNKS_PER_JOB = 4

#: Most frames in one chunk (a lost worker's chunk is measured again: keep it short).
MAX_CHUNK_FRAMES = 2000

#: Input kinds read by index cheaply; a video is decoded from its start to seek.
SEEKABLE_KINDS = ("hdf5", "tiff", "folder", "numpy")

#: The frame flags a chunk reports, in the order of its flag bits.
CHUNK_FLAGS = FRAME_FLAG_BITS


def plan_jobs(jobs: int | None, n_frames: int, kind: str, cores: int | None = None) -> int:
    """The processes a run of ``n_frames`` frames uses for ``--jobs JOBS``.

    The one rule for ``--jobs``, local processes and a local Dask cluster alike.

    Parameters
    ----------
    jobs : int or None
        What the user asked; None: every usable core but one, when each gets at least
        :data:`MIN_FRAMES_PER_JOB` frames (else 1).
    n_frames : int
        Frames in the run.
    kind : str
        The input's kind (:attr:`InputFile.kind`): a video runs in one process.
    cores : int, optional
        Usable cores (default: :func:`~holoview.processing.fourier.fftplans.usable_cpus`).

    Returns
    -------
    int
        At least 1; more jobs than usable cores, or than frames, are cut to those, with
        a warning (a worker process per core is the most that gains: each costs a
        start, memory, and a core the others need).

    Raises
    ------
    InputError
        For ``jobs`` below 1.
    """
    if jobs is not None and jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {jobs}")
    if kind not in SEEKABLE_KINDS:
        if jobs is not None and jobs > 1:
            logger.warning(
                "--jobs %d: a %s is read from its start to reach a frame; processed in one process",
                jobs,
                kind,
            )
        return 1
    cores = usable_cpus() if cores is None else cores
    if jobs is None:
        return max(1, min(cores - 1, n_frames // MIN_FRAMES_PER_JOB))
    most, why = n_frames, f"the run has {n_frames} frames"
    if cores < most:
        most, why = cores, f"this machine has {cores} usable cores"
    if jobs > most:
        logger.warning("--jobs %d: %s; using %d", jobs, why, max(1, most))
        return max(1, most)
    return jobs


def split_frames(
    n_frames: int, jobs: int, *, maps: bool = False, map_bytes: int = 0
) -> list[range]:
    """Contiguous chunks of positions ``0..n_frames-1``, in order, for ``jobs`` workers.

    :data:`CHUNKS_PER_JOB` chunks a job (one with one job), none longer than
    :data:`MAX_CHUNK_FRAMES` (when the workers make every frame's ``maps``, of
    ``map_bytes`` bytes a frame: :func:`~holoview.headless.parallel.chunk_maps.chunk_frames`),
    their lengths differing by one at most.

    Examples
    --------
    >>> split_frames(10, 1)
    [range(0, 10)]
    >>> [len(c) for c in split_frames(100, 2)]
    [12, 13, 13, 12, 12, 13, 13, 12]
    """
    if n_frames < 1:
        return []
    count = 1 if jobs <= 1 else jobs * CHUNKS_PER_JOB
    most = chunk_maps.chunk_frames(map_bytes) if maps else MAX_CHUNK_FRAMES
    count = max(count, -(-n_frames // most))
    count = min(count, n_frames)
    edges = np.linspace(0, n_frames, count + 1).round().astype(int)
    return [range(int(a), int(b)) for a, b in itertools.pairwise(edges)]


@dataclass(frozen=True)
class ChunkTask:
    """What a worker needs to measure one chunk.

    Attributes
    ----------
    path : str
        The input, an absolute path every worker can see.
    start : int
        Position of the chunk's first frame in the run.
    indices : tuple of int
        The input frame indices of the chunk, in order.
    peaks : tuple of Peak
        The demodulator's peaks (their carriers, cycles/pixel).
    frame_shape : tuple of int
        ``(rows, cols)`` the run expects.
    saturation : float or None
        Raw value at which the camera saturates (counts).
    read_ahead : int
        Frames the worker's reader reads ahead.
    maps : MapsWork or None
        Make every frame's maps too (:mod:`holoview.headless.parallel.chunk_maps`); when it
        carries the chunk's carrier values, they are not measured again.
    identity : InputIdentity or None
        What the input was when the run started: the worker checks that it still is.
    """

    path: str
    start: int
    indices: tuple[int, ...]
    peaks: tuple[Peak, ...]
    frame_shape: tuple[int, int]
    saturation: float | None
    read_ahead: int = DEFAULT_DEPTH
    maps: MapsWork | None = None
    identity: InputIdentity | None = None


@dataclass(frozen=True)
class ChunkResult:
    """The carrier values of one chunk
    (:class:`~holoview.processing.series.carrier_probe.CarrierValues`), and its maps.

    Attributes
    ----------
    start : int
        Position of the chunk's first frame in the run.
    values : ndarray of complex128, shape (K, M)
        Carrier values, counts (NaN for a flagged frame); empty when given.
    noise : ndarray of float64, shape (K, M)
        Their phase noise, rad.
    mean_counts : ndarray of float64, shape (K,)
        Each frame's mean pixel value, counts.
    flags : ndarray of uint8, shape (K,)
        Bit ``b`` set: the frame has flag :data:`CHUNK_FLAGS` ``[b]``.
    read_seconds, measure_seconds : float
        Time reading and measuring, s.
    worker : str
        ``host:pid`` of the process that measured it.
    maps : ChunkMaps or None
        With the task's ``maps``: each frame's maps and what a run counts of them.
    maps_seconds : float
        Time making the maps (the reference frame's included), s.
    """

    start: int
    values: np.ndarray
    noise: np.ndarray
    mean_counts: np.ndarray
    flags: np.ndarray
    read_seconds: float
    measure_seconds: float
    worker: str
    maps: ChunkMaps | None = None
    maps_seconds: float = 0.0

    def __len__(self) -> int:
        return int(self.flags.shape[0])

    def measured(self, k: int) -> CarrierValues:
        """The ``k``-th frame's values, as the probe gave them."""
        bits = int(self.flags[k])
        flags = frozenset(f for b, f in enumerate(CHUNK_FLAGS) if bits >> b & 1)
        return CarrierValues(
            self.values[k].copy(), self.noise[k].copy(), float(self.mean_counts[k]), flags
        )


def make_tasks(
    path: Path,
    frames: Sequence[int],
    chunks: Sequence[range],
    *,
    peaks: Sequence[Peak],
    frame_shape: tuple[int, int],
    saturation: float | None,
    read_ahead: int = DEFAULT_DEPTH,
    maps: Sequence[MapsWork] | None = None,
    identity: InputIdentity | None = None,
) -> list[ChunkTask]:
    """One task per chunk of positions into ``frames`` (input indices).

    ``maps``: one :class:`~holoview.headless.parallel.chunk_maps.MapsWork` per chunk, when the
    workers make every frame's maps too. With ``identity`` (the input's when the run
    started) a worker refuses an input replaced since.
    """
    where = str(Path(path).resolve())
    return [
        ChunkTask(
            path=where,
            start=chunk.start,
            indices=tuple(int(frames[p]) for p in chunk),
            peaks=tuple(peaks),
            frame_shape=(int(frame_shape[0]), int(frame_shape[1])),
            saturation=saturation,
            read_ahead=read_ahead,
            maps=None if maps is None else maps[k],
            identity=identity,
        )
        for k, chunk in enumerate(chunks)
    ]


def _open(task: ChunkTask) -> InputFile:
    """The task's input, checked to be the run's (InputError naming the worker's host)."""
    try:
        source = InputFile(task.path)
    except InputError as exc:
        host = socket.gethostname()
        raise InputError(f"a worker on {host} cannot read the input: {exc}") from None
    if task.identity is not None:
        now = InputIdentity.of(task.path, source.info.get("uuid"))
        try:
            task.identity.check(now, who=f"a worker on {socket.gethostname()}")
        except InputError:
            source.close()
            raise
    if source.frame_shape != task.frame_shape:
        source.close()
        raise InputError(
            f"a worker on {socket.gethostname()} sees {task.path} with frames of "
            f"{source.frame_shape}, not {task.frame_shape}: another file by that name?"
        )
    return source


def measure_chunk(task: ChunkTask) -> ChunkResult:
    """Measure the carrier values of one chunk, and with ``task.maps`` make its maps.

    Raises
    ------
    InputError
        The worker cannot open or read the input, finds it replaced since the run
        started (the task's ``identity``), or finds frames of another shape (the
        message names the worker's host).
    """
    try:
        return _measure_chunk(task)
    except Exception:
        if task.identity is not None:  # a file replaced while read can fail in any way
            task.identity.check(who=f"a worker on {socket.gethostname()}")
        raise


def _measure_chunk(task: ChunkTask) -> ChunkResult:
    """:func:`measure_chunk`, before a failure is put down to a replaced input."""
    worker = f"{socket.gethostname()}:{os.getpid()}"
    with _open(task) as source:
        n, m = len(task.indices), len(task.peaks)
        given = task.maps is not None and task.maps.values is not None
        values = np.full((0 if given else n, m), np.nan + 0j)
        noise = np.full((0 if given else n, m), np.nan)
        mean_counts = np.full(0 if given else n, np.nan)
        flags = np.zeros(n, np.uint8)
        if task.maps is not None and task.maps.frame_bits is not None:
            flags[:] = task.maps.frame_bits
        carriers = CarrierCore(task.frame_shape, task.saturation)
        carriers.configure(task.peaks)
        spent = maps_spent = 0.0
        maker = None
        if task.maps is not None:
            t0 = time.perf_counter()
            maker = task.maps.maker(source, task.frame_shape, task.saturation, n)
            maps_spent += time.perf_counter() - t0
        with FrameReader(source.read, task.indices, depth=task.read_ahead) as reader:
            for k, (_, frame) in enumerate(reader):
                t0 = time.perf_counter()
                if given:
                    assert task.maps is not None and task.maps.values is not None
                    frame_values = task.maps.values[k]
                else:
                    measured = carriers.measure(frame)
                    assert measured is not None
                    values[k] = measured.values
                    noise[k] = measured.noise
                    mean_counts[k] = measured.mean_counts
                    flags[k] = flag_bits(measured.flags)
                    frame_values = values[k]
                t1 = time.perf_counter()
                spent += t1 - t0
                if maker is not None:
                    maker.add(k, frame, frame_values, int(flags[k]))
                    maps_spent += time.perf_counter() - t1
        return ChunkResult(
            start=task.start,
            values=values,
            noise=noise,
            mean_counts=mean_counts,
            flags=flags,
            read_seconds=reader.read_seconds,
            measure_seconds=spent,
            worker=worker,
            maps=None if maker is None else maker.result(),
            maps_seconds=maps_spent,
        )
