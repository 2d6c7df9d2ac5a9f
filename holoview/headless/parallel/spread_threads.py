"""The frames spread over a run demodulated in the parent's threads, the estimate in order.

:func:`~holoview.headless.frame_passes.spread_pass` demodulates about
:data:`~holoview.engine.map_step.COREGISTER_FRAMES` frames spread over a run and feeds
their maps to the displacement estimate, in the parent, before the workers make the
maps (or after the series, the workers idle meanwhile). :func:`spread_in_threads` makes
the same numbers on ``threads`` cores:

1. the frames' carrier values and flags measured, ``threads`` frames at a time (the
   probe is the frame's alone), unless the series has them;
2. the frames cut into ``threads`` runs of consecutive ones; each run's maps made in a
   thread by a step of its own, put first in the state the serial step holds at the
   run's start, as a chunk's worker is (:mod:`.chunk_maps`): the reference frame
   demodulated, the mean phases replayed from the values before the run
   (:func:`~holoview.headless.parallel.stitch.chunk_states`);
3. the maps taken in order (:meth:`~holoview.headless.frame_passes.SpreadMaps.made`):
   the estimate, which depends on order, is fed as the serial pass feeds it; the last
   frame, fused when its maps are recorded, is made last by its run's step, sharing the
   estimate.

The frames are read in one thread at a time (a lock; a video decodes in order).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from holoview.engine.frame_core import CarrierCore
from holoview.engine.map_step import FrameMaps, MapStep
from holoview.headless.frame_passes import MapsSpec, SpreadMaps, frame_maps
from holoview.headless.inputs import InputFile
from holoview.headless.parallel.stitch import chunk_states
from holoview.headless.parallel.threads import in_order
from holoview.headless.run_data import RunData, flag_bits
from holoview.processing.maps.coregister import Displacement
from holoview.processing.peaks.detection import Peak

__all__ = ["spread_in_threads"]


def spread_in_threads(
    source: InputFile,
    frames: range,
    data: RunData,
    spec: MapsSpec,
    *,
    record: bool,
    threads: int,
    measured: bool = False,
) -> list[Displacement]:
    """:func:`~holoview.headless.frame_passes.spread_pass` on ``threads`` cores (module doc).

    Parameters
    ----------
    source, frames, data, spec, record, measured
        As :func:`~holoview.headless.frame_passes.spread_pass`.
    threads : int
        Threads (cores) to use; the runs of frames are those of the serial pass cut in
        as many parts.

    Returns
    -------
    list of Displacement
        Also kept in ``data.displacements``: those of the serial pass, to the bit.
    """
    spread = SpreadMaps(source, len(frames), data, spec, record=record)
    positions = [int(p) for p in spread.positions]
    demod = spread.step.core.demodulator
    assert demod is not None
    lock = threading.Lock()
    seconds = {"read": 0.0, "maps": 0.0}

    def read(k: int) -> np.ndarray:
        with lock:
            t0 = time.perf_counter()
            frame = source.read(frames[positions[k]])
            seconds["read"] += time.perf_counter() - t0
        return frame

    if measured:
        values = data.values[positions]
        bits = data.frame_bits[positions]
    else:
        values, bits = _probed(
            source, demod.peaks, read, count=len(positions), threads=threads, seconds=seconds
        )
    cut = np.array_split(np.arange(len(positions)), min(threads, len(positions)))
    runs = [range(int(c[0]), int(c[-1]) + 1) for c in cut if len(c)]
    states = chunk_states(values, bits, runs, spec, start=demod.phase_state(), mode=demod.reference)
    box = replace(spec, grid="box")  # SpreadMaps.step's
    last = len(positions) - 1 if spread.fuses(positions[-1]) else None
    stop = threading.Event()

    def run_maps(k: int) -> tuple[MapStep, list[FrameMaps]]:
        state, reference = states[k]
        step = box.step(source.frame_shape, source.saturation)
        step.coregistration = spread.step.coregistration  # read only by the last frame
        if reference is not None:
            step.process(read(reference), values[reference], fuse=False, shifts=False)
        run_demod = step.core.demodulator
        assert run_demod is not None
        run_demod.restore_phase_state(state)
        made = []
        for j in runs[k]:
            if stop.is_set() or j == last:
                break
            frame = read(j)
            t0 = time.perf_counter()
            made.append(frame_maps(step, frame, values[j], int(bits[j]), fuse=False, shifts=False))
            with lock:
                seconds["maps"] += time.perf_counter() - t0
        return step, made

    step = spread.step
    # interrupted: the threads stop at their next frame, and are waited for
    with contextlib.closing(in_order(run_maps, range(len(runs)), threads, stop=stop)) as done:
        for run, (run_step, made) in zip(runs, done, strict=True):
            step = run_step  # the last run's makes the last frame's maps
            for j, maps in zip(run, made, strict=False):
                spread.made(positions[j], frames[positions[j]], maps)
    data.maps_seconds += seconds["maps"]
    data.demod_seconds += seconds["maps"]
    if last is not None:
        frame = read(last)
        spread.take(
            positions[last],
            frames[positions[last]],
            frame,
            values[last],
            int(bits[last]),
            step=step,
        )
    data.read_seconds += seconds["read"]
    return spread.finish()


def _probed(
    source: InputFile,
    peaks: tuple[Peak, ...],
    read: Callable[[int], np.ndarray],
    *,
    count: int,
    threads: int,
    seconds: dict[str, float],
) -> tuple[np.ndarray, np.ndarray]:
    """The carrier values and flag bits of the ``count`` frames ``read`` gives, in order."""
    local = threading.local()
    lock = threading.Lock()

    def probe(k: int) -> tuple[np.ndarray, int]:
        core = getattr(local, "core", None)
        if core is None:
            core = local.core = CarrierCore(source.frame_shape, source.saturation)
            core.configure(peaks)
        frame = read(k)
        t0 = time.perf_counter()
        measured = core.measure(frame)
        assert measured is not None
        with lock:
            seconds["maps"] += time.perf_counter() - t0
        return measured.values, flag_bits(measured.flags)

    with contextlib.closing(in_order(probe, range(count), threads)) as done:
        probed = list(done)
    values = np.array([v for v, _ in probed], dtype=np.complex128)
    bits = np.array([b for _, b in probed], dtype=np.uint8)
    return values, bits
