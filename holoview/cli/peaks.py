"""``holoview peaks``: the carrier peaks of one frame, and their model labels.

Detection is :func:`holoview.processing.peaks.find_peaks`; with two ``--label`` the
model (:func:`holoview.processing.labelling.label_peaks`) names the others and says
which twin each is stored on. ``--json`` prints a document whose ``peaks`` list
``holoview process --peaks`` reads back (entries without a label are skipped there).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from holoview.cli.process import (
    add_label_option,
    add_optics_options,
    add_quiet_option,
    optics_options,
    parse_labels,
)
from holoview.cli.signals import emit
from holoview.errors import InputError


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
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
    parser.add_argument("--json", action="store_true", help="print JSON (a peaks file)")
    add_label_option(parser)
    add_optics_options(parser)
    add_quiet_option(parser)
    return parser


def _table(document: dict[str, Any]) -> str:
    rows, cols = document["frame_shape"]
    width = max([7] + [len("/".join(p["labels"])) for p in document["peaks"]]) + 1
    lines = [
        f"{document['input']} frame {document['frame']} ({rows} x {cols}): "
        f"{len(document['peaks'])} peaks; carriers in cycles/pixel (fx along columns)",
        f"{'#':>3}  {'label':<{width}}{'fx':>9}{'fy':>9}{'amplitude':>11}{'snr':>9}  "
        f"{'twin':<5} flags",
    ]
    for peak in document["peaks"]:
        twin = {True: "yes", False: "no", None: "-"}[peak["twin"]]
        names = "/".join(peak["labels"]) or "-"
        fx, fy = peak["carrier"]
        lines.append(
            f"{peak['index']:>3}  {names:<{width}}{fx:>+9.4f}{fy:>+9.4f}"
            f"{peak['amplitude']:>11.4g}{peak['snr']:>9.1f}  {twin:<5} {','.join(peak['flags'])}"
        )
    for key, text in (("missing", "predicted, not detected"), ("flip_hint", "wrong twin?")):
        if document.get(key):
            lines.append(f"{text}: {', '.join(document[key])}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Detect, label when asked, print a table or JSON."""
    from holoview.headless.inputs import (
        InputFile,
        check_not_background_subtracted,
        frame_problem,
        resolve_optics,
    )
    from holoview.headless.selection import describe_peaks
    from holoview.processing.labelling import label_peaks
    from holoview.processing.peaks import find_peaks

    labels = parse_labels(args.label)
    if len(labels) == 1:
        raise InputError(
            "--label needs at least two peaks (e.g. --label RB1=fx,fy --label FB1=fx,fy)"
        )
    with InputFile(args.input) as source:
        if not 0 <= args.frame < len(source):
            raise InputError(f"--frame must be in 0..{len(source) - 1}, got {args.frame}")
        optics = resolve_optics(source.setup, optics_options(args))
        frame = source.read(args.frame)
        shape = source.frame_shape
    problem = frame_problem(frame)
    if problem is not None:
        raise InputError(f"{args.input} frame {args.frame} {problem}; choose another with --frame")
    check_not_background_subtracted(frame, f"{args.input} frame {args.frame}")
    detected = find_peaks(frame)
    labelling = None
    if labels:
        optics.require("n2")
        assert optics.n2 is not None
        if not detected:
            raise InputError(f"no significant peak in frame {args.frame}: nothing to label")
        labelling = label_peaks(
            [p.carrier for p in detected], labels, optics.n1, optics.n2, shape, max_order=3
        )
    document = {
        "input": str(args.input),
        "frame": args.frame,
        "frame_shape": list(shape),
        "n1": optics.n1,
        "n2": optics.n2,
        "peaks": describe_peaks(detected, labelling, optics),
        "missing": list(labelling.missing) if labelling else [],
        "flip_hint": list(labelling.flip_hint) if labelling else [],
    }
    emit(json.dumps(document, indent=2) if args.json else _table(document))
    return 0
