"""``holoview process``: headless processing of a recording into results files and a figure.

The offline replay and test mode of docs/design.md: the same processing as the GUI, no
display (:mod:`holoview.headless`). Output files and their layout are documented in
:mod:`holoview.headless.results.outputs`, :mod:`holoview.headless.results.results_layout`
and the README. ``--jobs`` and ``--scheduler`` spread
the frames over processes or a Dask cluster (:mod:`holoview.headless.parallel.runners`); a
folder of recordings or a glob is a batch (:mod:`holoview.headless.batch`).
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from holoview.cli.options import (
    add_experiment_option,
    add_label_option,
    add_optics_options,
    optics_options,
    parse_labels,
    radius_value,
)
from holoview.cli.signals import emit
from holoview.cli.waves import add_wave_options, summary_line, wave_options
from holoview.errors import InputError

if TYPE_CHECKING:
    from tqdm import tqdm

    from holoview.headless.settings import ProcessOptions
from holoview.headless.results.figures import FORMATS

logger = logging.getLogger(__name__)


def folder_path(text: str) -> Path:
    """An argparse type: a folder path, not empty (``--out ""`` would be the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("give a folder, not an empty name")
    return Path(text)


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register ``process``."""
    parser = subparsers.add_parser(
        "process",
        help="process a recording headless: trends, rates, maps, report",
        description="Demodulate every frame of INPUT (a holoview recording, a multi-page "
        "TIFF, a folder of images or a video) at the chosen peaks and write trends.csv, "
        "summary.json, results.h5 and report.png (or --report-format) into DIR. INPUT may "
        "also be a folder of recordings or a quoted glob ('runs/*.h5'): then DIR/NAME per "
        "recording and DIR/index.csv of every run's rates.",
    )
    parser.add_argument(
        "input",
        type=Path,
        metavar="INPUT",
        help="recording, TIFF, folder or video; or a folder of recordings, or a glob",
    )
    parser.add_argument(
        "--out", type=folder_path, required=True, metavar="DIR", help="output folder"
    )
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the results of an earlier run in DIR (only once this run completes)",
    )
    peaks = parser.add_argument_group(
        "peaks (one way; with none, the experiment the recording carries, else --auto 4)"
    )
    add_experiment_option(
        peaks,
        "an experiment file (holoview-experiment JSON: labelled peaks, optics, window, "
        "reference), as the GUI saves it and `holoview peaks --json` writes it",
    )
    add_label_option(peaks)
    peaks.add_argument(
        "--auto",
        type=int,
        metavar="N",
        help="the N strongest peaks, identified by temporal PCA, the brightest as RB1",
    )
    peaks.add_argument(
        "--anchor",
        metavar="LABEL=FX,FY",
        help="with --auto: the PCA's reference peak and its twin instead of the brightest",
    )
    add_optics_options(parser)
    parser.add_argument(
        "--fps", type=float, metavar="F", help="frame rate, frames/s (replaces the file's times)"
    )
    demod = parser.add_argument_group("demodulation (default: the experiment's)")
    demod.add_argument(
        "--reference",
        choices=("relative", "absolute", "synthetic"),
        help="reference of the maps (default relative: against the previous frame)",
    )
    demod.add_argument(
        "--window", choices=("raised-cosine", "top-hat", "tukey"), help="spectral window"
    )
    demod.add_argument(
        "--radius",
        type=radius_value,
        metavar="R",
        help="window radius: 'matched' (per peak, matched to the surface's spectrum; the "
        "automatic default), 'bound' (per peak, the widest reaching no other peak) or a "
        "number, cycles/pixel, for every peak",
    )
    demod.add_argument("--unwrap", choices=("auto", "always", "never"), help="spatial unwrapping")
    demod.add_argument(
        "--background",
        metavar="FILE|INDEX",
        help="object-free hologram that absolute phases are taken against: a frame index "
        "of INPUT or a file (its first frame); implies --reference absolute",
    )
    demod.add_argument(
        "--threads",
        type=int,
        default=1,
        metavar="N",
        help="FFTW threads per frame (default 1; more only on an otherwise idle machine)",
    )
    spread = parser.add_argument_group("parallel runs")
    spread.add_argument(
        "--jobs",
        type=int,
        metavar="N",
        help="processes measuring the frames, chunks of the recording each (default: "
        "every core but one, when the recording is long enough to gain); with "
        "--scheduler local, the local cluster's workers",
    )
    spread.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the chunks on the Dask cluster whose scheduler is at ADDRESS "
        "(host:port; its workers must see INPUT at the same path), or 'local' for a "
        "local Dask cluster",
    )
    parser.add_argument("--maps", action="store_true", help="also write the delta-h maps")
    parser.add_argument(
        "--maps-grid",
        choices=("box", "frame"),
        default="box",
        help="with --maps: the maps' pixels: 'box' (default), the demodulation box's grid "
        "(e.g. 48 x 48 for 256 x 256 frames); 'frame', the camera frame's pixels (the "
        "windowed sideband inverted at the frame's size, as a plain Fourier filter gives "
        "it, for pixel-for-pixel comparisons; more time and disk per frame)",
    )
    parser.add_argument(
        "--report-format",
        choices=FORMATS,
        default="png",
        help="the report's format: report.png (default), report.pdf or report.svg",
    )
    parser.add_argument(
        "--waves",
        action="store_true",
        help="with --maps: then run holoview waves on the fused maps into DIR (its options "
        "below; --fluid and --threads serve both)",
    )
    parser.add_argument("--frames", metavar="START:STOP", help="process these frames only")
    parser.add_argument("--area", type=float, metavar="M2", help="basin area, m^2 (volume rates)")
    add_wave_options(parser)
    return parser


def _progress_bar(quiet: bool) -> tuple[tqdm[NoReturn], Callable[[int, int], None]]:
    """A bar on stderr (none with ``quiet``) and the function that moves it to done/total."""
    from tqdm import tqdm

    bar = tqdm(unit="frame", disable=quiet or None, file=sys.stderr, dynamic_ncols=True)

    def update(done: int, total: int) -> None:
        if bar.total != total:
            bar.reset(total=total)
        bar.update(done - bar.n)

    return bar, update


def _rate_text(rate: float | None, stderr: float | None) -> str:
    from holoview.processing.series.rate_fits import format_rate

    return "no rate" if rate is None else format_rate(rate, stderr, ascii=True)


def run(args: argparse.Namespace) -> int:
    """Process, show progress, print one line of what came out."""
    from holoview.headless.batch import find_recordings
    from holoview.headless.run import process_file
    from holoview.headless.selection import parse_assignment
    from holoview.headless.settings import PeakChoice, ProcessOptions, ProcessSettings
    from holoview.processing.fourier.fftplans import usable_cpus

    waves = None
    if args.waves:
        if not args.maps:
            raise InputError("--waves analyses the maps: give --maps too")
        waves = wave_options(args)
    if args.threads < 1:
        raise InputError(f"--threads must be at least 1, got {args.threads}")
    cores = usable_cpus()
    if args.threads > cores:
        logger.warning(
            "--threads %d: this machine has %d cores; using %d", args.threads, cores, cores
        )
        args.threads = cores
    choice = PeakChoice(
        experiment=args.experiment,
        labels=parse_labels(args.label),
        auto=args.auto,
        anchor=None if args.anchor is None else parse_assignment(args.anchor, "--anchor"),
    )
    settings = ProcessSettings(
        reference=args.reference,
        window=args.window,
        radius=args.radius,
        unwrap=args.unwrap,
        maps=args.maps,
        maps_grid=args.maps_grid,
        area_m2=args.area,
        threads=args.threads,
        background=args.background,
    )
    options = ProcessOptions(
        choice=choice,
        optics=optics_options(args, args.fps),
        settings=settings,
        frames=args.frames,
        report=args.report_format,
        overwrite=args.overwrite,
        jobs=args.jobs,
        scheduler=args.scheduler,
    )
    recordings = find_recordings(args.input)
    if recordings is not None:
        if waves is not None:
            raise InputError("--waves runs on one recording; run holoview waves on each results.h5")
        return _run_batch(args, recordings, options)
    bar, update = _progress_bar(args.quiet)
    with bar:
        outcome = process_file(args.input, args.out, options, progress=update)
    if outcome.data.interrupted:
        done = len(outcome.data.frames)
        print(
            f"holoview process: interrupted; {outcome.out} holds the results of the "
            f"{done} frames done (marked interrupted)"
            if outcome.files
            else f"holoview process: interrupted after {done} frames; the earlier results in "
            f"{outcome.out} are kept and the partial ones are not written",
            file=sys.stderr,
        )
        return 130
    if not args.quiet:
        fit = outcome.analysis.fit
        used = [p.label for p in outcome.analysis.peaks if p.used_in_fused]
        data = outcome.data
        emit(
            f"{outcome.out}: {len(data.frames)} frames in {data.wall_seconds:.1f} s "
            f"({len(data.frames) / max(data.wall_seconds, 1e-9):.1f} frames/s); "
            f"peaks {', '.join(p.label for p in outcome.analysis.peaks)} "
            f"(from the {outcome.selection.source}); fused "
            f"({', '.join(used) or 'none'}): "
            f"{_rate_text(fit.rate if fit else None, fit.stderr if fit else None)}"
        )
    if waves is not None:
        from holoview.headless.run import RESULTS_H5
        from holoview.headless.waves.outputs import run_waves

        written = [path for path in outcome.files if path.name == RESULTS_H5]
        if not written:  # an interrupted run returned 130 above: this is a bug
            raise RuntimeError(f"process --maps wrote no {RESULTS_H5} in {outcome.out}")
        # the maps step's fused maps, as the run wrote them (results.h5 2.0)
        analysed = run_waves(written[0], outcome.out, waves, overwrite=args.overwrite)
        if not args.quiet:
            emit(summary_line(outcome.out, analysed))
    return 0


def _run_batch(args: argparse.Namespace, recordings: list[Path], options: ProcessOptions) -> int:
    """Process a folder or glob of recordings; one line per failure, and the totals.

    Exit status 3 when an output of any recording could not be written, else 2 when
    one failed, else 0 (130 when stopped).
    """
    from holoview.headless.batch import process_batch

    bar, update = _progress_bar(args.quiet)
    with bar:
        outcome = process_batch(recordings, args.out, options, progress=update)
    for row in outcome.failed:
        print(f"holoview process: {row.input}: {row.message}", file=sys.stderr)
    done = sum(r.status == "ok" for r in outcome.rows)
    if outcome.interrupted:
        print(
            f"holoview process: interrupted after {done} of {len(outcome.rows)} recordings; "
            f"{outcome.index} lists them",
            file=sys.stderr,
        )
        return 130
    if not args.quiet:
        emit(
            f"{outcome.index}: {done} of {len(outcome.rows)} recordings processed"
            + (f", {len(outcome.failed)} failed" if outcome.failed else "")
        )
    if any(row.output_failed for row in outcome.failed):
        return 3  # an output could not be written (a full disk), as for one recording
    return 2 if outcome.failed else 0
