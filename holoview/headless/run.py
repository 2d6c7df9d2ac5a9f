"""One headless run from start to end: :func:`process_file`, what ``holoview process`` calls.

Steps: open the input and settle the optics and frame times
(:mod:`~holoview.headless.inputs`); detect the peaks of the first processed frame and
choose those to demodulate (:mod:`~holoview.headless.selection`); pass over the frames:
the series, the displacements, and the maps to ``results.h5`` as they come
(:mod:`~holoview.headless.run_passes`); name the peaks, fuse and fit
(:mod:`~holoview.headless.analysis`); write ``trends.csv``, ``summary.json``
(:mod:`~holoview.headless.results.outputs`), ``results.h5``
(:mod:`~holoview.headless.results.results_file`) and ``report.png`` (or PDF, SVG:
:mod:`~holoview.headless.results.report`). Every user mistake is an
:class:`~holoview.errors.InputError` raised before anything is written where it can be
known that early (:mod:`~holoview.headless.prepare`). The output folder is locked for
the run from its start (one run at a time); the outputs are written under temporary
names and put in place when the run completes; what an earlier run left in the folder
is replaced only then, and only with ``overwrite``; no output may be an input
(:mod:`~holoview.headless.results.output_folder`).
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from holoview.engine.experiment import Experiment
from holoview.headless.analysis import Analysis, analyse
from holoview.headless.input_identity import InputIdentity
from holoview.headless.inputs import InputFile, parse_frame_range
from holoview.headless.parallel.chunks import plan_jobs
from holoview.headless.parallel.runners import ChunkRunner, open_runner
from holoview.headless.prepare import PreparedRun, prepare_run, run_inputs
from holoview.headless.results.figures import FORMATS
from holoview.headless.results.output_folder import OutputFolder
from holoview.headless.results.outputs import (
    summary_document,
    write_summary_json,
    write_trends_csv,
)
from holoview.headless.results.results_file import ResultsFile
from holoview.headless.run_data import RunData
from holoview.headless.run_passes import run_passes
from holoview.headless.selection import Selection
from holoview.headless.settings import ProcessOptions
from holoview.processing.fourier.spectrum import display_spectrum

logger = logging.getLogger(__name__)

#: Output file names in the output folder.
TRENDS_CSV = "trends.csv"
SUMMARY_JSON = "summary.json"
RESULTS_H5 = "results.h5"
#: The report in each format (a run writes one; an earlier run's, any).
REPORT_FILES = tuple(f"report.{kind}" for kind in FORMATS)
#: Every file a run may write: a folder holding any of them holds an earlier run.
OUTPUT_NAMES = (TRENDS_CSV, SUMMARY_JSON, RESULTS_H5, *REPORT_FILES)


@dataclass(frozen=True)
class ProcessOutcome:
    """What a run produced (the files are in ``out``)."""

    out: Path
    selection: Selection
    experiment: Experiment
    data: RunData
    analysis: Analysis
    summary: dict[str, Any]
    files: tuple[Path, ...]


def process_file(
    input_path: str | Path,
    out: str | Path,
    options: ProcessOptions | None = None,
    *,
    progress: Callable[[int, int], None] | None = None,
    runner: ChunkRunner | None = None,
) -> ProcessOutcome:
    """Process a recording headless and write the results into the folder ``out``.

    Parameters
    ----------
    input_path : str or Path
        A holoview recording, multi-page TIFF, folder of images, or video.
    out : str or Path
        Output folder (created if missing; see ``options.overwrite``).
    options : ProcessOptions, optional
        How to choose the peaks, the optics, the settings, the frames, the report, and
        where the frames are measured (the defaults: the recording's own experiment,
        every frame, ``report.png``, one process).
    progress : callable, optional
        ``progress(done, total)`` after each frame of each pass over every frame.
    runner : ChunkRunner, optional
        Workers already started (a batch of recordings shares them); the options'
        ``jobs`` and ``scheduler`` are then not used.

    Returns
    -------
    ProcessOutcome
        Its ``files`` are empty when an interrupted run kept the earlier results.

    Raises
    ------
    InputError
        For an unreadable input, missing or wrong parameters, a bad experiment file or
        labels (a label on no detected peak, an unknown label without alpha), peaks the
        PCA cannot identify, earlier results without ``overwrite``, an output that is
        an input, a folder another run holds, ``jobs`` below 1, a scheduler that does
        not answer, or workers that cannot read the input.
    OutputError
        An output could not be written, or (without ``overwrite``) results appeared
        in the folder during the run (the folder keeps what it held).

    Examples
    --------
    >>> from holoview.headless.settings import PeakChoice, ProcessOptions
    >>> options = ProcessOptions(choice=PeakChoice(auto=4), report=None)
    >>> options.settings.maps
    False
    """
    options = (options or ProcessOptions()).checked()
    out_dir = Path(out)
    with (
        OutputFolder(
            out_dir,
            OUTPUT_NAMES,
            overwrite=options.overwrite,
            inputs=run_inputs(input_path, options.choice, options.settings),
        ) as outputs,
        InputFile(input_path) as source,
        contextlib.ExitStack() as stack,
    ):
        identity = InputIdentity.of(source.path, source.info.get("uuid"))
        selected = parse_frame_range(options.frames, len(source))
        runner = _workers(options, source, selected, runner, stack)
        prepared = prepare_run(source, selected, options, identity)
        try:
            data, analysis = _run_frames(prepared, outputs.path(RESULTS_H5), runner, progress)
        except Exception:
            identity.check()  # a file replaced while read can fail in any way
            raise
        summary = _write_outputs(prepared, outputs, data, analysis, options.report)
        identity.check()  # the frames were all of the input the run started on
        files = outputs.finish(interrupted=data.interrupted)
    return ProcessOutcome(
        out_dir,
        prepared.selection,
        prepared.experiment,
        data,
        analysis,
        summary,
        tuple(files),
    )


def _workers(
    options: ProcessOptions,
    source: InputFile,
    selected: range,
    runner: ChunkRunner | None,
    stack: contextlib.ExitStack,
) -> ChunkRunner | None:
    """The run's workers: those given, or started now (they start while this one prepares).

    None where the run is better done in one process (too short, a video).
    """
    if runner is not None:
        if runner.workers > 1 and plan_jobs(runner.workers, len(selected), source.kind) == 1:
            return None
        return runner
    scheduler = options.scheduler
    planned = plan_jobs(options.jobs, len(selected), source.kind)
    if scheduler is not None and planned == 1 and source.kind == "video":
        scheduler = None  # plan_jobs said why: a video is read in one process
    if planned > 1 or scheduler is not None:
        return stack.enter_context(open_runner(planned, scheduler))
    return None


def _run_frames(
    prepared: PreparedRun,
    path: Path,
    runner: ChunkRunner | None,
    progress: Callable[[int, int], None] | None,
) -> tuple[RunData, Analysis]:
    """The passes over the frames, maps into ``results.h5`` at ``path``; then the analysis."""
    run = prepared.frames
    maps = run.settings.maps
    results = ResultsFile(
        path,
        labels=[p.label or f"P{j}" for j, p in enumerate(run.selection.peaks)],
        n_frames=len(run.frames),
        box_shape=prepared.box_shape,
        maps=maps,
    )
    try:
        started = time.perf_counter()
        data, naming = run_passes(
            run, runner=runner, sink=results if maps else None, progress=progress
        )
        data.wall_seconds = time.perf_counter() - started
        analysis = analyse(data, run.selection, run.optics, naming)
        results.finish(
            data=data,
            analysis=analysis,
            optics=run.optics,
            settings=run.settings,
            input_path=str(run.source.path),
            frame_shape=run.source.frame_shape,
        )
    finally:
        results.close()
    return data, analysis


def _write_outputs(
    prepared: PreparedRun,
    outputs: OutputFolder,
    data: RunData,
    analysis: Analysis,
    report: str | bool | None,
) -> dict[str, Any]:
    """Write ``trends.csv``, ``summary.json`` and the report; return the summary."""
    run = prepared.frames
    source = run.source
    summary = summary_document(
        input_info=source.info,
        optics=run.optics,
        settings=run.settings,
        selection_mode=run.selection.source,
        data=data,
        analysis=analysis,
        frame_shape=source.frame_shape,
    )
    summary["experiment"] = run.experiment.to_dict()
    write_trends_csv(outputs.path(TRENDS_CSV), data, analysis)
    write_summary_json(outputs.path(SUMMARY_JSON), summary)
    if report:
        from holoview.headless.results.report import write_report

        write_report(
            outputs.path(f"report.{report}"),
            spectrum=display_spectrum(prepared.first, threads=run.settings.threads),
            detected=prepared.detected,
            data=data,
            analysis=analysis,
            settings=run.settings,
            optics=run.optics,
            title=f"{source.path.name}: frames {data.frames[0]}..{data.frames[-1]}"
            + (" (interrupted)" if data.interrupted else ""),
        )
    return summary
