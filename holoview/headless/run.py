"""One headless run from start to end: :func:`process_file`, what ``holoview process`` calls.

Steps: open the input and settle the optics and frame times
(:mod:`~holoview.headless.inputs`); detect the peaks of the first processed frame and
choose those to demodulate (:mod:`~holoview.headless.selection`); stream every frame
through the demodulator, maps to ``results.h5`` as they come
(:mod:`~holoview.headless.pipeline`); name the peaks, fuse and fit
(:mod:`~holoview.headless.analysis`); write ``trends.csv``, ``summary.json``,
``results.h5`` (:mod:`~holoview.headless.outputs`) and ``report.png``
(:mod:`~holoview.headless.report`). Every user mistake is an
:class:`~holoview.errors.InputError` raised before the output folder is touched where
it can be known that early. The outputs are written under temporary names and put in
place when the run completes; what an earlier run left in the folder is replaced only
then, and only with ``overwrite`` (:mod:`~holoview.headless.output_folder`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from holoview.errors import InputError
from holoview.headless.analysis import Analysis, analyse
from holoview.headless.inputs import (
    InputFile,
    Optics,
    OpticsOptions,
    check_run_settings,
    first_good_frame,
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
from holoview.headless.pipeline import ProcessSettings, RunData, demodulate_frames, make_demodulator
from holoview.headless.selection import (
    Carrier,
    Selection,
    load_peaks_file,
    select_auto,
    select_by_model,
    select_from_entries,
)
from holoview.processing.peaks import Peak, find_peaks
from holoview.processing.spectrum import display_spectrum

logger = logging.getLogger(__name__)

#: Output file names in the output folder.
TRENDS_CSV = "trends.csv"
SUMMARY_JSON = "summary.json"
RESULTS_H5 = "results.h5"
REPORT_PNG = "report.png"


@dataclass(frozen=True)
class PeakChoice:
    """How to choose the peaks: exactly one of a peaks file, labels, or a count.

    Attributes
    ----------
    peaks_file : Path or None
        A JSON peaks file.
    labels : dict of str to (fx, fy)
        Two or more labelled carriers (cycles/pixel) for the model.
    auto : int or None
        The number of strongest peaks to identify by PCA.
    anchor : (str, (fx, fy)) or None
        Auto mode: the reference peak's label and carrier (default: the brightest, RB1).
    """

    peaks_file: Path | None = None
    labels: dict[str, Carrier] = field(default_factory=dict)
    auto: int | None = None
    anchor: tuple[str, Carrier] | None = None

    def mode(self) -> str:
        """``"file"``, ``"labels"`` or ``"auto"``; InputError unless exactly one is given."""
        given = [
            name
            for name, on in (
                ("file", self.peaks_file is not None),
                ("labels", bool(self.labels)),
                ("auto", self.auto is not None),
            )
            if on
        ]
        if len(given) != 1:
            raise InputError("choose the peaks one way: --peaks FILE, --auto N or --label (twice)")
        if self.anchor is not None and given[0] != "auto":
            raise InputError("--anchor goes with --auto")
        return given[0]


@dataclass(frozen=True)
class ProcessOutcome:
    """What a run produced (the files are in ``out``)."""

    out: Path
    selection: Selection
    data: RunData
    analysis: Analysis
    summary: dict[str, Any]
    files: tuple[Path, ...]


def choose_peaks(
    choice: PeakChoice, detected: list[Peak], shape: tuple[int, int], optics: Optics
) -> Selection:
    """Apply a :class:`PeakChoice` to the peaks detected in the first frame."""
    mode = choice.mode()
    if mode == "file":
        assert choice.peaks_file is not None
        return select_from_entries(load_peaks_file(choice.peaks_file), detected, shape, optics)
    if mode == "labels":
        return select_by_model(choice.labels, detected, shape, optics)
    optics.require("n2")
    assert choice.auto is not None
    return select_auto(choice.auto, detected, shape, choice.anchor)


def process_file(
    input_path: str | Path,
    out: str | Path,
    *,
    choice: PeakChoice,
    optics_options: OpticsOptions | None = None,
    settings: ProcessSettings | None = None,
    frames: str | None = None,
    report: bool = True,
    progress: Callable[[int, int], None] | None = None,
    overwrite: bool = False,
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
        recording's own values.
    settings : ProcessSettings, optional
        Reference mode, window, radius, unwrapping, maps, basin area.
    frames : str, optional
        ``START:STOP`` of the input's frames (all by default).
    report : bool
        Draw ``report.png``.
    progress : callable, optional
        ``progress(done, total)`` after each frame.
    overwrite : bool
        Replace an earlier run's results in ``out`` when this run completes.

    Returns
    -------
    ProcessOutcome
        Its ``files`` are empty when an interrupted run kept the earlier results.

    Raises
    ------
    InputError
        For an unreadable input, missing or wrong parameters, a bad peaks file or
        labels, peaks the PCA cannot identify, or earlier results without ``overwrite``.
    OutputError
        An output could not be written (the folder keeps what it held).
    """
    settings = settings or ProcessSettings()
    options = optics_options or OpticsOptions()
    out_dir = Path(out)
    names = (TRENDS_CSV, SUMMARY_JSON, RESULTS_H5, REPORT_PNG)
    with (
        OutputFolder(out_dir, names, overwrite=overwrite) as outputs,
        InputFile(input_path) as source,
    ):
        optics = resolve_optics(source.setup, options)
        optics.require("wavelength_m")
        selected = parse_frame_range(frames, len(source))
        times = source.times(selected, options.fps_hz)
        check_run_settings(
            area_m2=settings.area_m2, radius=settings.radius, frame_shape=source.frame_shape
        )
        _, first = first_good_frame(source, selected)
        detected = find_peaks(first, radius=settings.radius, threads=settings.threads)
        selection = choose_peaks(choice, detected, source.frame_shape, optics)
        demodulator = make_demodulator(
            source.frame_shape, selection, optics, settings, source.saturation
        )
        logger.info(
            "%s: %d frames, peaks %s, window radius %.4f cycles/pixel, maps %s",
            source.path,
            len(selected),
            ", ".join(p.label or "?" for p in selection.peaks),
            demodulator.radius,
            demodulator.box_shape,
        )
        outputs.create()
        results = ResultsFile(
            outputs.path(RESULTS_H5),
            labels=[p.label or f"P{j}" for j, p in enumerate(selection.peaks)],
            n_frames=len(selected),
            box_shape=demodulator.box_shape,
            maps=settings.maps,
        )
        try:
            data = demodulate_frames(
                source,
                selected,
                times,
                demodulator,
                sink=results if settings.maps else None,
                read_ahead=settings.read_ahead,
                progress=None if progress is None else lambda k: progress(k, len(selected)),
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
            selection_mode=selection.mode,
            data=data,
            analysis=analysis,
            frame_shape=source.frame_shape,
        )
        write_trends_csv(outputs.path(TRENDS_CSV), data, analysis)
        write_summary_json(outputs.path(SUMMARY_JSON), summary)
        if report:
            from holoview.headless.report import write_report

            write_report(
                outputs.path(REPORT_PNG),
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
    return ProcessOutcome(out_dir, selection, data, analysis, summary, tuple(files))
