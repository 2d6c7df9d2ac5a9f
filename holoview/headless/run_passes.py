"""Which passes a headless run makes over its frames, in what order, in one process or many.

The passes (:mod:`holoview.headless.frame_passes`; on many processes
:mod:`holoview.headless.parallel.stitch`): the series of every frame, the displacements on frames
spread over the run, and with ``--maps`` every frame's maps. Their order follows from
what each needs:

- every map is fused as it is made, so the displacements come before the maps;
- an auto run's maps take the prefactors its identification gives, which needs the
  whole series: series, identification, displacements, maps;
- a run whose prefactors are known makes its maps in the same pass as its series
  (each frame read once), in one process or, in ``relative`` mode, in the workers;
  in the ``absolute`` and ``synthetic`` modes the workers need the mean phases at
  their chunk's start, which the series gives: series first (the displacements beside
  it), then the maps (:func:`~holoview.headless.parallel.stitch.map_chunks`).

An interruption (a KeyboardInterrupt: Ctrl-C, or a stop signal the command turned into
one) keeps the frames whose every pass is done. A run interrupted before its maps pass
made any frame's maps (during its series, its naming, its displacements, or before the
maps pass's first frame or chunk is in) keeps the series of the frames done, and no maps
(``RunData.maps_dropped``; a note says so); one interrupted later keeps the frames whose
maps are made, in one process or many. Only an interruption before any frame's series
is done leaves nothing (it is raised again).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, replace

from holoview.engine.experiment import Experiment
from holoview.headless.analysis import Naming, known_joint, name_peaks
from holoview.headless.frame_passes import (
    MapsSpec,
    SpreadMaps,
    maps_pass,
    measure_frames,
    spread_pass,
)
from holoview.headless.input_identity import InputIdentity
from holoview.headless.inputs import FrameTimes, InputFile, Optics
from holoview.headless.parallel.runners import ChunkRunner
from holoview.headless.parallel.spread_threads import spread_in_threads
from holoview.headless.parallel.stitch import map_chunks, measure_chunks
from holoview.headless.run_data import MapRecord, MapSink, RunData, new_run_data
from holoview.headless.selection import Selection
from holoview.headless.settings import ProcessSettings

logger = logging.getLogger(__name__)

__all__ = ["RunFrames", "run_passes"]


@dataclass(frozen=True)
class RunFrames:
    """What the passes of a run take: its frames, peaks, settings and where they go.

    Attributes
    ----------
    source : InputFile
        The input.
    frames : range
        Input frame indices to process.
    times : FrameTimes
        Their times, s, and the frame intervals before each.
    selection : Selection
        The peaks chosen (labelled, or to be identified in auto mode).
    spec : MapsSpec
        The maps step of the selected peaks (no displacements yet).
    experiment : Experiment
        The run's settled experiment.
    optics : Optics
        The run's optics.
    settings : ProcessSettings
        Its settings.
    identity : InputIdentity or None
        The input's when the run started: the workers check it before each chunk.
    threads : int
        The cores this process may use for its own work where its workers are not
        running (:func:`~holoview.headless.parallel.threads.parent_threads`): the
        frames spread over the run demodulated in threads
        (:mod:`~holoview.headless.parallel.spread_threads`).
    """

    source: InputFile
    frames: range
    times: FrameTimes
    selection: Selection
    spec: MapsSpec
    experiment: Experiment
    optics: Optics
    settings: ProcessSettings
    identity: InputIdentity | None = None
    threads: int = 1


def run_passes(
    run: RunFrames,
    *,
    runner: ChunkRunner | None,
    sink: MapSink | None,
    progress: Callable[[int, int], None] | None = None,
    series_only: bool = False,
) -> tuple[RunData, Naming]:
    """Make the run's passes (module documentation); return its record and its peaks' naming.

    Parameters
    ----------
    run : RunFrames
        The run.
    runner : ChunkRunner or None
        Workers (None: this process alone).
    sink : MapSink or None
        Receives every frame's maps (``--maps``).
    progress : callable, optional
        ``progress(done, total)``: the frames' work done of all the passes over every
        frame (two with ``--maps`` when the maps follow the series, else one).
    series_only : bool
        The series and the naming alone (a window's whole run,
        :mod:`holoview.headless.run_series`): no displacements and no maps, so no
        ``sink``.

    Raises
    ------
    KeyboardInterrupt
        Interrupted before any frame was done.
    InputError
        As the passes and the identification raise.
    """
    if series_only and sink is not None:
        raise ValueError("a series-only run makes no maps: give no sink")
    source, frames = run.source, run.frames
    spec = run.spec
    n = len(frames)
    demod = spec.core(source.frame_shape, source.saturation).demodulator
    assert demod is not None
    data = new_run_data(demod.peaks, demod.box_shape, demod.radius, n, demod.windows)
    known = run.selection.mode != "auto"
    maps = sink is not None
    relative = demod.reference == "relative"
    together = maps and known and (runner is None or relative)
    total = n * (2 if maps and not together else 1)
    first = None if progress is None else (lambda k: progress(k, total))
    second = None if progress is None else (lambda k: progress(n + k, total))
    # the joint estimate as the frames come where the parent would otherwise wait for its
    # workers; in one process it waits for the analysis, which makes it over every frame
    # done (the same numbers: frame after frame, in order), out of the frame loop's way
    joint = known_joint(run.selection, run.optics) if runner is not None else None
    if joint is not None:
        joint.track(data.series)
    read_ahead = run.settings.read_ahead
    if together:
        _spread(run, data, spec, record=False)
        spec = replace(spec, displacements=tuple(data.displacements))
        record = MapRecord(data, sink, fused=bool(data.fused_labels))
        if runner is None:
            step = spec.step(source.frame_shape, source.saturation)
            measure_frames(
                source,
                frames,
                run.times,
                data,
                demod.peaks,
                read_ahead=read_ahead,
                progress=first,
                maps=(step, record),
            )
        else:
            measure_chunks(
                source,
                frames,
                run.times,
                data,
                demod.peaks,
                runner=runner,
                identity=run.identity,
                read_ahead=read_ahead,
                progress=first,
                maps=(spec, record),
            )
        return data, name_peaks(data, run.selection, run.optics)
    # typed here: mypy took the None for the name's type and skipped the branch below
    beside: Callable[[Callable[[int], None]], None] | None = None
    if known and runner is not None and not series_only:

        def beside(until: Callable[[int], None]) -> None:
            spread_pass(
                source, frames, data, spec, record=not maps, read_ahead=read_ahead, until=until
            )

    # known peaks in one process: the spread frames' maps in the series pass (each frame
    # read and measured once); else after the series, from its values
    inline = None
    if known and runner is None and not series_only:
        inline = SpreadMaps(source, n, data, spec, record=not maps)
    if runner is None:
        measure_frames(
            source,
            frames,
            run.times,
            data,
            demod.peaks,
            read_ahead=read_ahead,
            progress=first,
            spread=inline,
        )
    else:
        measure_chunks(
            source,
            frames,
            run.times,
            data,
            demod.peaks,
            runner=runner,
            identity=run.identity,
            read_ahead=read_ahead,
            progress=first,
            spread=beside,
        )
    naming = _named(data, run)
    if not known:
        spec = replace(spec, peaks=naming.peaks(run.selection), exclude=naming.exclude)
        data.map_units = tuple("m" if a is not None else "rad" for a in naming.signed)
    if data.interrupted:  # the frames done are the series': no displacements, no maps
        _no_maps(data, maps)
        return data, naming
    if series_only:
        return data, naming
    try:
        if beside is None and inline is None:
            _spread(run, data, spec, record=not maps, measured=True)
        if sink is not None:
            spec = replace(spec, displacements=tuple(data.displacements))
            record = MapRecord(data, sink, fused=bool(data.fused_labels))
            if runner is None:
                maps_pass(
                    source, frames, data, spec, record, read_ahead=read_ahead, progress=second
                )
            else:
                map_chunks(
                    source,
                    frames,
                    data,
                    spec,
                    record,
                    runner=runner,
                    identity=run.identity,
                    read_ahead=read_ahead,
                    progress=second,
                )
    except KeyboardInterrupt:  # the maps passes raise it again only before any frame's maps
        done = len(data.series)
        logger.warning("interrupted before the maps: results of the %d frames' series", done)
        data.truncate(done)
        _no_maps(data, maps)
    return data, naming


def _spread(
    run: RunFrames, data: RunData, spec: MapsSpec, *, record: bool, measured: bool = False
) -> None:
    """The spread pass while this process works alone: on its threads (the same numbers)."""
    source, frames = run.source, run.frames
    if run.threads > 1:
        spread_in_threads(
            source, frames, data, spec, record=record, threads=run.threads, measured=measured
        )
    else:
        spread_pass(
            source,
            frames,
            data,
            spec,
            record=record,
            read_ahead=run.settings.read_ahead,
            measured=measured,
        )


def _named(data: RunData, run: RunFrames) -> Naming:
    """The peaks' naming of the frames done; an interruption while naming names them again.

    The naming needs every frame's series, so it cannot stop half-way: a stop during it
    marks the run interrupted (no displacements, no maps follow) and the frames done are
    named again for their results; a second stop then stops the command.
    """
    try:
        return name_peaks(data, run.selection, run.optics)
    except KeyboardInterrupt:
        logger.warning(
            "interrupted while naming the peaks: results of the %d frames' series",
            len(data.series),
        )
        data.truncate(len(data.series))
        return name_peaks(data, run.selection, run.optics)


def _no_maps(data: RunData, maps: bool) -> None:
    """Mark an interrupted ``--maps`` run's maps as not made: ``results.h5`` holds none."""
    if maps:
        data.maps_dropped = True
        data.notes.append("interrupted before its maps were made: results.h5 holds none")
