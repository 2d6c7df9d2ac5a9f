"""``holoview peaks``: the carrier peaks of one frame, and their labels.

Detection is :func:`holoview.processing.peaks.detection.find_peaks`. The labels come from
``--label``, an ``--experiment`` file or the experiment the recording carries, snapped
to the detected peaks by the engine's rule (:func:`holoview.engine.resolve.resolve_peaks`);
with two of the model's families the model names the others and says which twin each
is stored on. ``--json`` prints an experiment (``holoview process --experiment`` and
``holoview live --experiment`` read it back) with every detected peak under ``detected``.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path
from typing import Any

from holoview.cli.options import (
    add_experiment_option,
    add_label_option,
    add_optics_options,
    optics_options,
    parse_labels,
)
from holoview.cli.signals import emit
from holoview.errors import InputError

logger = logging.getLogger(__name__)


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register ``peaks``."""
    parser = subparsers.add_parser(
        "peaks",
        help="list the carrier peaks of a frame (and their labels)",
        description="Detect the carrier peaks of one frame of INPUT (a holoview recording, "
        "a multi-page TIFF, a folder of images or a video): carrier (cycles/pixel), "
        "amplitude, significance, flags; with two --label, the model's labels and twins.",
    )
    parser.add_argument(
        "input", type=Path, metavar="INPUT", help="recording, TIFF, folder or video"
    )
    parser.add_argument("--frame", type=int, default=0, metavar="K", help="frame index (default 0)")
    parser.add_argument(
        "--json", action="store_true", help="print an experiment file (JSON) to stdout"
    )
    add_label_option(parser)
    add_experiment_option(parser, "take the labels (and optics) from this experiment file")
    add_optics_options(parser)
    return parser


def _names(peak: dict[str, Any]) -> str:
    """A row's names: the model's labels landing on it, else the lattice's name (a ghost's
    ``RB1~g0``: no model label lands on a ghost)."""
    return "/".join(peak["labels"]) or peak["label"] or ""


def _table(document: dict[str, Any]) -> str:
    rows, cols = document["frame_shape"]
    detected = document["detected"]
    width = max([7] + [len(_names(p)) for p in detected]) + 1
    lines = [
        f"{document['input']} frame {document['frame']} ({rows} x {cols}): "
        f"{len(detected)} peaks; carriers in cycles/pixel (fx along columns); lattice "
        "(fb1, rf): the carrier is fb1 f_FB1 + rf f_RF, residual in FFT bins",
        f"{'#':>3}  {'label':<{width}}{'fx':>9}{'fy':>9}{'amplitude':>11}{'snr':>9}  "
        f"{'twin':<5}{'lattice':>9}{'resid':>7}  flags",
    ]
    for peak in detected:
        twin = {True: "yes", False: "no", None: "-"}[peak["twin"]]
        names = _names(peak) or "-"
        fx, fy = peak["carrier"]
        point = "-" if peak["lattice"] is None else "{},{}".format(*peak["lattice"])
        resid = "-" if peak["residual_bins"] is None else f"{peak['residual_bins']:.2f}"
        lines.append(
            f"{peak['index']:>3}  {names:<{width}}{fx:>+9.4f}{fy:>+9.4f}"
            f"{peak['amplitude']:>11.4g}{peak['snr']:>9.1f}  {twin:<5}{point:>9}{resid:>7}  "
            f"{','.join(peak['flags'])}"
            + (f"  {peak['sideband']['text']}" if peak.get("sideband") else "")
        )
    for key, text in (("missing", "predicted, not detected"), ("notes", "note")):
        for line in document.get(key) or []:
            lines.append(f"{text}: {line}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Detect, label, print a table or an experiment (JSON)."""
    from dataclasses import replace

    from holoview.engine.experiment import Experiment, LabelledPeak
    from holoview.engine.resolve import resolve_peaks
    from holoview.headless.inputs import (
        InputFile,
        check_not_background_subtracted,
        frame_problem,
        resolve_optics,
    )
    from holoview.headless.selection import describe_peaks
    from holoview.processing.naming.lattice import identify_lattice
    from holoview.processing.peaks.detection import find_peaks

    labels = parse_labels(args.label)
    if labels and args.experiment is not None:
        raise InputError("give --label or --experiment, not both")
    given = Experiment.load(args.experiment) if args.experiment is not None else None
    with InputFile(args.input) as source:
        if not 0 <= args.frame < len(source):
            raise InputError(f"--frame must be in 0..{len(source) - 1}, got {args.frame}")
        stored, notes = source.experiment_at(args.frame)
        if not labels and given is None:
            for note in notes:
                logger.warning("%s", note)
        optics = resolve_optics(source.setup, optics_options(args), given)
        frame = source.read(args.frame)
        shape = source.frame_shape
    experiment = given or stored or Experiment()
    if labels:
        experiment = replace(experiment, peaks=tuple(LabelledPeak(k, c) for k, c in labels.items()))
    experiment = replace(
        experiment,
        wavelength_m=optics.wavelength_m,
        pixel_pitch_m=optics.pixel_pitch_m,
        n1=optics.n1,
        n2=optics.n2,
    )
    problem = frame_problem(frame)
    if problem is not None:
        raise InputError(f"{args.input} frame {args.frame} {problem}; choose another with --frame")
    check_not_background_subtracted(frame, f"{args.input} frame {args.frame}")
    detected = find_peaks(frame, radius=experiment.fixed_radius)
    if experiment.peaks and not detected:
        raise InputError(f"no significant peak in frame {args.frame}: nothing to label")
    resolution = resolve_peaks(experiment, detected, shape)
    try:
        resolution.strict(unmatched=bool(labels) or given is not None)
    except InputError as exc:
        if labels or given is not None:
            raise
        raise InputError(
            f"the experiment the recording carries: {exc}; name the peaks with --label or "
            "--experiment"
        ) from exc
    named = tuple(LabelledPeak(p.label, p.carrier) for p in resolution.peaks if p.label)
    document = replace(experiment, peaks=named).to_dict()
    labelling = resolution.labelling
    notes = list(resolution.notes)
    lattice = labelling.lattice if labelling is not None else None
    if lattice is None and len(detected) >= 2 and optics.n2 is not None:
        try:  # no labels: the lattice names the peaks by itself
            lattice = identify_lattice([p.carrier for p in detected], shape, optics.n1, optics.n2)
        except InputError as exc:
            notes.append(f"no automatic naming: {exc}")
    if lattice is not None:
        notes += list(lattice.notes)
        if lattice.sign_from == "convention":
            notes.append(
                "the twins are a convention (RB1 as detected): every height may come out "
                "negated; label a peak on its stored twin (--label) to settle it"
            )
    document.update(
        input=str(args.input),
        frame=args.frame,
        frame_shape=list(shape),
        detected=describe_peaks(detected, lattice, labelling),
        basis=None if lattice is None else lattice.source,
        precision_bins=None if lattice is None else lattice.precision_bins,
        margin=None if lattice is None else lattice.margin,
        sign_from=None if lattice is None else lattice.sign_from,
        missing=list(lattice.missing) if lattice else [],
        notes=notes,
    )
    emit(json.dumps(document, indent=2) if args.json else _table(document))
    return 0
