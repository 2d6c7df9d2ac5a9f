"""One headless run from start to end: :func:`process_file`, what ``holoview process`` calls.

Steps: open the input and settle the optics and frame times
(:mod:`~holoview.headless.inputs`); detect the peaks of the first processed frame and
choose those to demodulate (:mod:`~holoview.headless.selection`); stream every frame
through the demodulator, maps to ``results.h5`` as they come
(:mod:`~holoview.headless.pipeline`); name the peaks, fuse and fit
(:mod:`~holoview.headless.analysis`); write ``trends.csv``, ``summary.json``,
``results.h5`` (:mod:`~holoview.headless.outputs`) and ``report.png`` (or PDF, SVG:
:mod:`~holoview.headless.report`). Every user mistake is an
:class:`~holoview.errors.InputError` raised before anything is written where it can be
known that early. The output folder is locked for the run from its start (one run at a
time); the outputs are written under temporary names and put in place when the run
completes; what an earlier run left in the folder is replaced only then, and only with
``overwrite``; no output may be an input (:mod:`~holoview.headless.output_folder`).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from holoview.engine.experiment import Experiment, LabelledPeak
from holoview.engine.frame_core import matching_positions
from holoview.engine.resolve import on_lattice
from holoview.errors import InputError
from holoview.headless.analysis import Analysis, analyse, known_joint
from holoview.headless.chunks import plan_jobs
from holoview.headless.figures import FORMATS, figure_format
from holoview.headless.inputs import (
    InputFile,
    Optics,
    OpticsOptions,
    check_not_background_subtracted,
    check_run_settings,
    first_good_frame,
    frame_problem,
    parse_frame_range,
    resolve_optics,
)
from holoview.headless.output_folder import OutputFolder
from holoview.headless.outputs import (
    ResultsFile,
    summary_document,
    write_summary_json,
    write_trends_csv,
)
from holoview.headless.parallel import ChunkRunner, open_runner
from holoview.headless.pipeline import ProcessSettings, RunData, demodulate_frames, make_core
from holoview.headless.selection import (
    Carrier,
    Selection,
    select_auto,
    select_from_experiment,
)
from holoview.headless.stitch import demodulate_chunks
from holoview.processing.fourier.spectrum import display_spectrum
from holoview.processing.peaks.detection import Peak, find_peaks
from holoview.processing.peaks.matched import SurfaceSpectrum, measure_spectrum
from holoview.processing.peaks.radii import surface_band

logger = logging.getLogger(__name__)

#: Output file names in the output folder.
TRENDS_CSV = "trends.csv"
SUMMARY_JSON = "summary.json"
RESULTS_H5 = "results.h5"
#: The report in each format (a run writes one; an earlier run's, any).
REPORT_FILES = tuple(f"report.{kind}" for kind in FORMATS)
#: Every file a run may write: a folder holding any of them holds an earlier run.
OUTPUT_NAMES = (TRENDS_CSV, SUMMARY_JSON, RESULTS_H5, *REPORT_FILES)


#: Peaks identified by PCA when nothing names them (no options, no experiment stored).
DEFAULT_AUTO = 4


@dataclass(frozen=True)
class PeakChoice:
    """How to choose the peaks: at most one of an experiment file, labels, or a count.

    With none, the experiment the recording carries is used, or ``--auto``
    :data:`DEFAULT_AUTO` when it carries none.

    Attributes
    ----------
    experiment : Path or None
        An experiment file (:mod:`holoview.engine.experiment`).
    labels : dict of str to (fx, fy)
        Labelled carriers (cycles/pixel); with two or more of the model's families the
        model adds the others.
    auto : int or None
        The number of strongest peaks to identify by PCA.
    anchor : (str, (fx, fy)) or None
        Auto mode: the reference peak's label and carrier (default: the brightest, RB1).
    """

    experiment: Path | None = None
    labels: dict[str, Carrier] = field(default_factory=dict)
    auto: int | None = None
    anchor: tuple[str, Carrier] | None = None

    def mode(self) -> str:
        """``"experiment file"``, ``"labels"``, ``"auto"`` or ``"recording"`` (none given)."""
        given = [
            name
            for name, on in (
                ("experiment file", self.experiment is not None),
                ("labels", bool(self.labels)),
                ("auto", self.auto is not None),
            )
            if on
        ]
        if len(given) > 1:
            raise InputError("choose the peaks one way: --experiment FILE, --label or --auto N")
        if self.anchor is not None and given != ["auto"]:
            raise InputError("--anchor goes with --auto")
        return given[0] if given else "recording"


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


def _base_experiment(
    choice: PeakChoice, source: InputFile, first_frame: int
) -> tuple[Experiment, str, list[str]]:
    """The experiment a run starts from, where it came from, and notes.

    An experiment file, else the recording's own (labels, settings) when it carries one;
    ``--label`` replaces the peaks; with none, a recording without an experiment falls
    back to ``--auto``.
    """
    mode = choice.mode()
    if mode == "experiment file":
        assert choice.experiment is not None
        return Experiment.load(choice.experiment), mode, []
    stored, notes = source.experiment_at(first_frame)
    base = stored or Experiment(wavelength_m=None, pixel_pitch_m=None, n1=None, n2=None)
    if mode == "labels":
        peaks = tuple(LabelledPeak(k, c) for k, c in choice.labels.items())
        return replace(base, peaks=peaks), mode, notes
    if mode == "recording":
        if stored is not None and stored.peaks:
            return stored, "recording", notes
        why = "carries no usable experiment" if stored is None else "names no peak"
        notes.append(f"the recording {why}: peaks identified by --auto {DEFAULT_AUTO}")
        return base, "auto", notes
    return base, "auto", notes


def _settle(
    experiment: Experiment, settings: ProcessSettings, optics: Optics
) -> tuple[Experiment, ProcessSettings]:
    """Options over the experiment's demodulation settings; the resolved optics into it."""
    experiment = experiment.updated(
        window=settings.window, reference=settings.reference, unwrap=settings.unwrap
    )
    if settings.radius is not None:
        experiment = replace(experiment, radius=settings.radius)
    experiment = replace(
        experiment,
        wavelength_m=optics.wavelength_m,
        pixel_pitch_m=optics.pixel_pitch_m,
        n1=optics.n1,
        n2=optics.n2,
    )
    settings = replace(
        settings,
        window=experiment.window,
        reference=experiment.reference,
        unwrap=experiment.unwrap,
        radius=experiment.radius,
    )
    return experiment, settings


def _matching_spectrum(
    source: InputFile,
    frames: range,
    *,
    first_index: int,
    first: np.ndarray,
    reference: str,
    background: np.ndarray | None,
    band: float,
) -> SurfaceSpectrum:
    """What a run's windows are matched to: the changes its maps show, the waves detected.

    Against the background, the first frame; else the frames
    :func:`~holoview.engine.frame_core.matching_positions` names after the first good
    one, against it. Frames that cannot be used are left out (the first alone when none
    is left, as for synthetic phases).
    """
    if reference != "synthetic" and background is not None:
        return measure_spectrum(first, background, band=band)
    start = frames.index(first_index)
    later = []
    for position in matching_positions(reference, len(frames) - start):
        frame = source.read(frames[start + position])
        if frame_problem(frame) is None:
            later.append(frame)
    if not later:
        return measure_spectrum(first, band=band)
    return measure_spectrum(later, first, band=band)


def choose_peaks(
    choice: PeakChoice,
    *,
    mode: str,
    experiment: Experiment,
    detected: list[Peak],
    shape: tuple[int, int],
    optics: Optics,
) -> Selection:
    """The peaks of a run: the experiment's (``mode`` names where it came from) or auto."""
    if mode == "auto":
        optics.require("n2")
        return select_auto(choice.auto or DEFAULT_AUTO, detected, shape, choice.anchor)
    return select_from_experiment(experiment, detected, shape, mode)


def read_background(spec: str | None, source: InputFile) -> np.ndarray | None:
    """The background hologram ``--background`` names: a frame index of ``source``, or a file.

    Raises
    ------
    InputError
        For an index outside the input, a file that cannot be read, a frame of another
        shape than the input's, or one that is no hologram: constant (all zero),
        non-finite, damaged, or negative (:func:`check_background`).
    """
    if spec is None:
        return None
    if spec.lstrip("-").isdigit():
        index = int(spec)
        if not 0 <= index < len(source):
            raise InputError(
                f"--background {spec}: {source.path} has frames 0 to {len(source) - 1}"
            )
        frame = source.read(index)
    else:
        with InputFile(spec) as other:
            frame = other.read(0)
        if frame.shape != source.frame_shape:
            raise InputError(
                f"--background {spec}: frames of {frame.shape[0]} x {frame.shape[1]} pixels, "
                f"the input's are {source.frame_shape[0]} x {source.frame_shape[1]}"
            )
    check_background(frame, f"--background {spec}")
    return frame


def run_inputs(input_path: str | Path, choice: PeakChoice, settings: ProcessSettings) -> list[Path]:
    """Every file or folder a run reads: the input, an experiment file, a background file."""
    inputs = [Path(input_path)]
    if choice.experiment is not None:
        inputs.append(Path(choice.experiment))
    spec = settings.background
    if spec is not None and not spec.lstrip("-").isdigit():
        inputs.append(Path(spec))
    return inputs


def check_background(frame: np.ndarray, where: str) -> None:
    """Refuse a background that is no hologram: absolute phases against it would be noise.

    A background is an object-free hologram: an intensity with fringes. A constant
    frame (all zero), one with NaN, one damaged in transfer, and one of negative or
    zero mean intensity (a negated or background-subtracted frame) are refused.
    """
    problem = frame_problem(frame)
    if problem is not None:
        raise InputError(f"{where}: the frame {problem}; give an object-free hologram")
    mean = float(np.mean(frame, dtype=np.float64))
    if mean <= 0:
        raise InputError(
            f"{where}: the frame's mean intensity is {mean:.3g} (values {frame.min():.3g} to "
            f"{frame.max():.3g}): a hologram is an intensity; give an object-free hologram"
        )
    check_not_background_subtracted(frame, where)


def process_file(
    input_path: str | Path,
    out: str | Path,
    *,
    choice: PeakChoice,
    optics_options: OpticsOptions | None = None,
    settings: ProcessSettings | None = None,
    frames: str | None = None,
    report: str | bool | None = "png",
    progress: Callable[[int, int], None] | None = None,
    overwrite: bool = False,
    jobs: int | None = 1,
    scheduler: str | None = None,
    runner: ChunkRunner | None = None,
) -> ProcessOutcome:
    """Process a recording headless and write the results into the folder ``out``.

    Parameters
    ----------
    input_path : str or Path
        A holoview recording, multi-page TIFF, folder of images, or video.
    out : str or Path
        Output folder (created if missing; see ``overwrite``).
    choice : PeakChoice
        How to choose the peaks.
    optics_options : OpticsOptions, optional
        Wavelength (m), pixel pitch (m), n1, n2 or fluid, fps; they override the
        experiment's and the recording's own values.
    settings : ProcessSettings, optional
        Reference mode, window, radius, unwrapping (each over the experiment's), maps,
        basin area.
    frames : str, optional
        ``START:STOP`` of the input's frames (all by default).
    report : str or bool or None
        The report's format: ``"png"``, ``"pdf"`` or ``"svg"`` (``report.png`` ...);
        True is ``"png"``; None or False: no report.
    progress : callable, optional
        ``progress(done, total)`` after each frame.
    overwrite : bool
        Replace an earlier run's results in ``out`` when this run completes.
    jobs : int or None
        Processes measuring the frames (:func:`~holoview.headless.chunks.plan_jobs`;
        None: every core but one when the run is long enough); with ``scheduler``
        ``"local"``, the local cluster's workers.
    scheduler : str, optional
        A Dask scheduler's address, or ``"local"``
        (:mod:`holoview.headless.parallel`).
    runner : ChunkRunner, optional
        Workers already started (a batch of recordings shares them); ``jobs`` and
        ``scheduler`` are then not used.

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
    """
    settings = settings or ProcessSettings()
    if report is True:
        report = "png"
    if report:
        figure_format(f"report.{report}", "--report-format")
    if settings.background is not None:
        if settings.reference not in (None, "absolute"):
            raise InputError(
                f"--background is the reference of absolute phases: it goes with "
                f"--reference absolute, not {settings.reference}"
            )
        settings = replace(settings, reference="absolute")
    options = optics_options or OpticsOptions()
    out_dir = Path(out)
    with (
        OutputFolder(
            out_dir,
            OUTPUT_NAMES,
            overwrite=overwrite,
            inputs=run_inputs(input_path, choice, settings),
        ) as outputs,
        InputFile(input_path) as source,
        contextlib.ExitStack() as stack,
    ):
        selected = parse_frame_range(frames, len(source))
        if runner is None:  # started first: the workers start while this process prepares
            planned = plan_jobs(jobs, len(selected), source.kind)
            if scheduler is not None and planned == 1 and source.kind == "video":
                scheduler = None  # plan_jobs said why: a video is read in one process
            if planned > 1 or scheduler is not None:
                runner = stack.enter_context(open_runner(planned, scheduler))
        elif runner.workers > 1 and plan_jobs(runner.workers, len(selected), source.kind) == 1:
            runner = None
        base, mode, notes = _base_experiment(choice, source, selected[0])
        from_file = base if mode == "experiment file" else None
        optics = resolve_optics(source.setup, options, from_file)
        optics.require("wavelength_m")
        experiment, settings = _settle(base, settings, optics)
        frame_times = source.times(selected, options.fps_hz)
        times = frame_times.times
        check_run_settings(
            area_m2=settings.area_m2, radius=settings.radius, frame_shape=source.frame_shape
        )
        first_index, first = first_good_frame(source, selected)
        background = read_background(settings.background, source)
        detected = find_peaks(first, radius=experiment.fixed_radius, threads=settings.threads)
        selection = choose_peaks(
            choice,
            mode=mode,
            experiment=experiment,
            detected=detected,
            shape=source.frame_shape,
            optics=optics,
        )
        for note in (*notes, *source.notes):
            logger.warning("%s", note)
        level = logging.WARNING if frame_times.warning else logging.INFO
        logger.log(level, "%s: %s", source.path, frame_times.note)
        notes += [*source.notes, frame_times.note]
        selection = replace(selection, notes=(*notes, *selection.notes))
        matched = experiment.radius_rule == "matched"
        core = make_core(
            source.frame_shape,
            experiment,
            selection.peaks,
            settings,
            source.saturation,
            detected=detected,
            background=background,
            placed=on_lattice(selection.labelling, len(detected)),
            spectrum=_matching_spectrum(
                source,
                selected,
                first_index=first_index,
                first=first,
                reference=experiment.reference,
                background=background,
                band=surface_band(detected),
            )
            if matched
            else None,
        )
        demodulator = core.demodulator
        assert demodulator is not None
        selection = replace(selection, notes=(*selection.notes, *core.notes))
        logger.info(
            "%s: %d frames, peaks %s (from the %s), window radius %.4f cycles/pixel, maps %s",
            source.path,
            len(selected),
            ", ".join(p.label or "?" for p in selection.peaks),
            selection.source,
            demodulator.radius,
            demodulator.box_shape,
        )
        results = ResultsFile(
            outputs.path(RESULTS_H5),
            labels=[p.label or f"P{j}" for j, p in enumerate(selection.peaks)],
            n_frames=len(selected),
            box_shape=demodulator.box_shape,
            maps=settings.maps,
        )
        try:
            sink = results if settings.maps else None
            step = None if progress is None else lambda k: progress(k, len(selected))
            if runner is None:
                data = demodulate_frames(
                    source,
                    selected,
                    times,
                    core,
                    sink=sink,
                    read_ahead=settings.read_ahead,
                    progress=step,
                )
            else:
                data = demodulate_chunks(
                    source,
                    selected,
                    times,
                    core,
                    runner,
                    sink=sink,
                    read_ahead=settings.read_ahead,
                    progress=step,
                    joint=known_joint(selection, optics),
                )
            analysis = analyse(data, selection, optics)
            results.finish(
                data=data,
                analysis=analysis,
                optics=optics,
                settings=settings,
                input_path=str(source.path),
                frame_shape=source.frame_shape,
                converted=data.maps_in_metres,
            )
        finally:
            results.close()
        summary = summary_document(
            input_info=source.info,
            optics=optics,
            settings=settings,
            selection_mode=selection.source,
            data=data,
            analysis=analysis,
            frame_shape=source.frame_shape,
        )
        summary["experiment"] = experiment.to_dict()
        write_trends_csv(outputs.path(TRENDS_CSV), data, analysis)
        write_summary_json(outputs.path(SUMMARY_JSON), summary)
        if report:
            from holoview.headless.report import write_report

            write_report(
                outputs.path(f"report.{report}"),
                spectrum=display_spectrum(first, threads=settings.threads),
                detected=detected,
                data=data,
                analysis=analysis,
                settings=settings,
                optics=optics,
                title=f"{Path(input_path).name}: frames {data.frames[0]}..{data.frames[-1]}"
                + (" (interrupted)" if data.interrupted else ""),
            )
        files = outputs.finish(interrupted=data.interrupted)
    return ProcessOutcome(out_dir, selection, experiment, data, analysis, summary, tuple(files))
