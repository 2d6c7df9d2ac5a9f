"""Options every subcommand spells the same way: optics, labels, experiment, verbosity.

One set of names and units across ``live``, ``record``, ``simulate``, ``process`` and
``peaks``: the wavelength in nanometres (``--wavelength-nm``) and the pixel pitch in
micrometres (``--pixel-pitch-um``), as they are written on a laser and a camera, converted
to metres here and nowhere else; ``--n1``, ``--n2`` or ``--fluid``; ``--label
LABEL=FX,FY`` in cycles/pixel; ``--experiment FILE``; and ``-v`` / ``-q``, accepted
before or after the subcommand.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from holoview.errors import InputError

if TYPE_CHECKING:
    from holoview.headless.inputs import OpticsOptions

#: Nanometres and micrometres in a metre.
NM, UM = 1e-9, 1e-6


def positive_number(text: str) -> float:
    """An argparse type: a finite positive number (the message names the value)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite positive number")
    return value


def radius_value(text: str) -> float | str:
    """An argparse type: ``matched``, ``bound`` or a finite positive radius, cycles/pixel."""
    if text in ("matched", "bound"):
        return text
    try:
        return positive_number(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not 'matched', 'bound' or a positive radius in cycles/pixel"
        ) from None


def add_verbosity_options(parser: argparse.ArgumentParser, *, top: bool = False) -> None:
    """Add ``-v`` / ``-q``; on a subcommand they mean the same as before it."""
    default: dict[str, object] = {}
    if not top:
        default = {"default": argparse.SUPPRESS}
    noise = parser.add_mutually_exclusive_group()
    noise.add_argument(
        "-v",
        "--verbose",
        action="count",
        help="more log output (-vv: debug)",
        **({"default": 0} if top else default),
    )
    noise.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="errors only, no progress bars",
        **({"default": False} if top else default),
    )


def add_optics_options(parser: argparse.ArgumentParser, title: str | None = None) -> None:
    """Add ``--wavelength-nm``, ``--pixel-pitch-um``, ``--n1`` and ``--n2`` / ``--fluid``."""
    from holoview.optics.setup import FLUIDS

    group = parser.add_argument_group(
        title
        or "physical parameters (the experiment's and the recording's are used unless given here)"
    )
    group.add_argument(
        "--wavelength-nm", type=positive_number, metavar="NM", help="laser wavelength, nm"
    )
    group.add_argument(
        "--pixel-pitch-um",
        type=positive_number,
        metavar="UM",
        help="object-side pixel pitch, um",
    )
    group.add_argument("--n1", type=positive_number, help="refractive index above the surface")
    fluid = group.add_mutually_exclusive_group()
    fluid.add_argument("--n2", type=positive_number, help="refractive index of the fluid")
    fluid.add_argument("--fluid", choices=sorted(FLUIDS), help="sets n2 from a preset")


def optics_in_metres(args: argparse.Namespace) -> dict[str, float]:
    """The optics the options give in SI units (``wavelength_m``, ``pixel_pitch_m``, n1, n2)."""
    from holoview.optics.setup import FLUIDS

    values = {
        "wavelength_m": None if args.wavelength_nm is None else args.wavelength_nm * NM,
        "pixel_pitch_m": None if args.pixel_pitch_um is None else args.pixel_pitch_um * UM,
        "n1": args.n1,
        "n2": FLUIDS[args.fluid] if getattr(args, "fluid", None) else args.n2,
    }
    return {k: v for k, v in values.items() if v is not None}


def optics_options(args: argparse.Namespace, fps: float | None = None) -> OpticsOptions:
    """Return the :class:`~holoview.headless.inputs.OpticsOptions` the arguments give."""
    from holoview.headless.inputs import OpticsOptions

    return OpticsOptions(
        wavelength_m=None if args.wavelength_nm is None else args.wavelength_nm * NM,
        pixel_pitch_m=None if args.pixel_pitch_um is None else args.pixel_pitch_um * UM,
        n1=args.n1,
        n2=args.n2,
        fluid=args.fluid,
        fps_hz=fps,
    )


def add_experiment_option(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup, help_text: str
) -> None:
    """Add ``--experiment FILE`` (a ``holoview-experiment`` JSON file)."""
    parser.add_argument("--experiment", type=Path, metavar="FILE.json", help=help_text)


def add_label_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """Add the repeatable ``--label LABEL=fx,fy``."""
    parser.add_argument(
        "--label",
        action="append",
        default=[],
        metavar="LABEL=FX,FY",
        help="a labelled peak, carrier in cycles/pixel on the twin whose phase grows with "
        "the height (twice: the model names the rest)",
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
