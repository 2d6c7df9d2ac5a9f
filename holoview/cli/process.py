"""``holoview process``: headless processing of a recording into results files and a figure.

The offline replay and test mode of DESIGN.md: the same processing as the GUI, no
display (:mod:`holoview.headless`). Output files and their layout are documented in
:mod:`holoview.headless.outputs` and the README.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from pathlib import Path

from holoview.cli.signals import emit
from holoview.errors import InputError

logger = logging.getLogger(__name__)


def add_optics_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--wavelength``, ``--pixel-pitch``, ``--n1``, ``--n2``, ``--fluid`` (SI units)."""
    from holoview.optics.setup import FLUIDS

    group = parser.add_argument_group(
        "physical parameters (a recording's own are used unless given here)"
    )
    group.add_argument("--wavelength", type=float, metavar="M", help="laser wavelength, m")
    group.add_argument("--pixel-pitch", type=float, metavar="M", help="object-side pixel pitch, m")
    group.add_argument("--n1", type=float, help="refractive index above the surface")
    fluid = group.add_mutually_exclusive_group()
    fluid.add_argument("--n2", type=float, help="refractive index of the fluid")
    fluid.add_argument("--fluid", choices=sorted(FLUIDS), help="sets n2 from a preset")


def add_label_option(parser: argparse.ArgumentParser) -> None:
    """Add the repeatable ``--label LABEL=fx,fy``."""
    parser.add_argument(
        "--label",
        action="append",
        default=[],
        metavar="LABEL=FX,FY",
        help="a labelled peak, carrier in cycles/pixel on the twin whose phase grows with "
        "the height (twice: the model names the rest)",
    )


def add_quiet_option(parser: argparse.ArgumentParser) -> None:
    """Add ``-q`` after the subcommand too (same meaning as before it)."""
    parser.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        default=argparse.SUPPRESS,
        help="errors only, no progress bar",
    )


def optics_options(args: argparse.Namespace, fps: float | None = None):
    """Return the :class:`~holoview.headless.inputs.OpticsOptions` the arguments give."""
    from holoview.headless.inputs import OpticsOptions

    return OpticsOptions(
        wavelength_m=args.wavelength,
        pixel_pitch_m=args.pixel_pitch,
        n1=args.n1,
        n2=args.n2,
        fluid=args.fluid,
        fps_hz=fps,
    )


def parse_labels(texts: list[str]) -> dict[str, tuple[float, float]]:
    """Parse repeated ``--label LABEL=fx,fy`` into a dict (a label given twice is an error)."""
    from holoview.headless.selection import parse_assignment

    labels: dict[str, tuple[float, float]] = {}
    for text in texts:
        label, carrier = parse_assignment(text, "--label")
        if label in labels:
            raise InputError(f"--label {label} is given twice")
        labels[label] = carrier
    return labels


def folder_path(text: str) -> Path:
    """An argparse type: a folder path, not empty (``--out ""`` would be the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("give a folder, not an empty name")
    return Path(text)


def usable_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``process``."""
    parser = subparsers.add_parser(
        "process",
        help="process a recording headless: trends, rates, maps, report",
        description="Demodulate every frame of INPUT (a holoview recording, a multi-page "
        "TIFF, a folder of images or a video) at the chosen peaks and write trends.csv, "
        "summary.json, results.h5 and report.png into DIR.",
    )
    parser.add_argument(
        "input", type=Path, metavar="INPUT", help="recording, TIFF, folder or video"
    )
    parser.add_argument(
        "--out", type=folder_path, required=True, metavar="DIR", help="output folder"
    )
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the results of an earlier run in DIR (only once this run completes)",
    )
    peaks = parser.add_argument_group("peaks (one way)")
    peaks.add_argument("--peaks", type=Path, metavar="FILE.json", help="a peaks file")
    peaks.add_argument(
        "--auto",
        type=int,
        metavar="N",
        help="the N strongest peaks, identified by temporal PCA, the brightest as RB1 "
        "(the default, with N = 4)",
    )
    peaks.add_argument(
        "--anchor",
        metavar="LABEL=FX,FY",
        help="with --auto: the PCA's reference peak and its twin instead of the brightest",
    )
    add_label_option(peaks)
    add_optics_options(parser)
    parser.add_argument(
        "--fps", type=float, metavar="F", help="frame rate, frames/s (replaces the file's times)"
    )
    demod = parser.add_argument_group("demodulation")
    demod.add_argument(
        "--reference",
        choices=("relative", "absolute", "synthetic"),
        default="relative",
        help="reference of the maps (default: relative, against the previous frame)",
    )
    demod.add_argument(
        "--window", choices=("raised-cosine", "top-hat", "tukey"), default="raised-cosine"
    )
    demod.add_argument(
        "--radius", type=float, metavar="R", help="window radius, cycles/pixel (default: automatic)"
    )
    demod.add_argument("--unwrap", choices=("auto", "always", "never"), default="auto")
    demod.add_argument(
        "--threads",
        type=int,
        default=1,
        metavar="N",
        help="FFTW threads per frame (default 1; more only on an otherwise idle machine)",
    )
    parser.add_argument("--maps", action="store_true", help="also write the delta-h maps")
    parser.add_argument("--frames", metavar="START:STOP", help="process these frames only")
    parser.add_argument("--area", type=float, metavar="M2", help="basin area, m^2 (volume rates)")
    add_quiet_option(parser)
    return parser


def _progress_bar(quiet: bool):
    from tqdm import tqdm

    bar = tqdm(unit="frame", disable=quiet or None, file=sys.stderr, dynamic_ncols=True)

    def update(done: int, total: int) -> None:
        if bar.total != total:
            bar.reset(total=total)
        bar.update(done - bar.n)

    return bar, update


def _rate_text(rate: float | None, stderr: float | None) -> str:
    from holoview.processing.trends import format_rate

    return "no rate" if rate is None else format_rate(rate, stderr, ascii=True)


def run(args: argparse.Namespace) -> int:
    """Process, show progress, print one line of what came out."""
    from holoview.headless.pipeline import ProcessSettings
    from holoview.headless.run import PeakChoice, process_file
    from holoview.headless.selection import parse_assignment

    if args.threads < 1:
        raise InputError(f"--threads must be at least 1, got {args.threads}")
    cores = usable_cores()
    if args.threads > cores:
        logger.warning(
            "--threads %d: this machine has %d cores; using %d", args.threads, cores, cores
        )
        args.threads = cores
    if args.auto is None and args.peaks is None and not args.label:
        args.auto = 4
        logger.info("no peaks chosen: --auto 4")
    choice = PeakChoice(
        peaks_file=args.peaks,
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
        area_m2=args.area,
        threads=args.threads,
    )
    bar, update = _progress_bar(args.quiet)
    with bar:
        outcome = process_file(
            args.input,
            args.out,
            choice=choice,
            optics_options=optics_options(args, args.fps),
            settings=settings,
            frames=args.frames,
            progress=update,
            overwrite=args.overwrite,
        )
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
            f"peaks {', '.join(p.label for p in outcome.analysis.peaks)}; fused "
            f"({', '.join(used) or 'none'}): "
            f"{_rate_text(fit.rate if fit else None, fit.stderr if fit else None)}"
        )
    return 0
