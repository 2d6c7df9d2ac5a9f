"""``holoview waves``: the wave analyses of the maps in a ``results.h5``.

Reads one label's height maps (``holoview process --maps``), writes ``waves.h5``,
``waves.json`` and PNG figures into ``--out`` (:mod:`holoview.headless.waves.outputs`):
the omega-k spectrum with the dispersion relation fitted (sigma, d, U with standard
errors), E(k) and E(f); around a centre the (m, f) spectrum, the partial waves'
incoming and outgoing amplitudes and a ringdown; lock-in maps at a drive frequency; a
band-filtered copy of the maps. ``process --maps --waves`` runs the same on the maps
it has just written. Lengths on the command line are in mm, speeds in mm/s,
frequencies in Hz, wavenumbers in rad/m; angles in degrees.
"""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from holoview.cli.signals import emit
from holoview.errors import InputError

if TYPE_CHECKING:
    from holoview.headless.waves.outputs import WavesOutcome

logger = logging.getLogger(__name__)

#: Millimetres in a metre.
MM = 1e-3


def _pair(text: str, option: str, sep: str = ",") -> tuple[float, float]:
    parts = text.split(sep)
    try:
        if len(parts) != 2:
            raise ValueError
        values = (float(parts[0]), float(parts[1]))
    except ValueError:
        raise InputError(f"{option} {text!r}: give two numbers as A{sep}B") from None
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"{option} {text!r}: the numbers must be finite")
    return values


def _range(text: str | None, option: str) -> tuple[float | None, float | None]:
    """``A:B``, ``A:`` or ``:B`` into (A or None, B or None)."""
    if text is None:
        return None, None
    parts = text.split(":")
    if len(parts) != 2:
        raise InputError(f"{option} {text!r}: give START:STOP (either may be left out)")
    try:
        values = tuple(float(p) if p.strip() else None for p in parts)
    except ValueError:
        raise InputError(f"{option} {text!r}: START and STOP must be numbers") from None
    low, high = values
    if low is not None and high is not None and not low < high:
        raise InputError(f"{option} {text!r}: START must be below STOP")
    return low, high


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register ``waves``."""
    from holoview.optics.surfaces import FLUID_MECHANICS

    parser = subparsers.add_parser(
        "waves",
        help="wave analyses of the maps in a results.h5: omega-k, dispersion fit, partial "
        "waves, ringdown, lock-in",
        description="Analyse the height maps of one label of INPUT (a results.h5 written "
        "by holoview process --maps) as a wave field h(t, y, x) and write waves.h5, "
        "waves.json and PNG figures into DIR.",
    )
    parser.add_argument(
        "input", type=Path, metavar="INPUT", help="a results.h5 with maps, or the run's folder"
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    parser.add_argument("--overwrite", action="store_true", help="replace earlier waves outputs")
    parser.add_argument(
        "--fluid", choices=sorted(FLUID_MECHANICS), help="the liquid (default water)"
    )
    parser.add_argument("--threads", type=int, default=1, metavar="N", help="FFT threads")
    add_wave_options(parser)
    source = parser.add_argument_group("the maps")
    source.add_argument("--label", default="fused", help="fused (default) or a peak's label")
    source.add_argument("--time", metavar="T0:T1", help="analyse the frames in [T0, T1) s")
    source.add_argument(
        "--pixel-size-um", type=float, metavar="UM", help="pixel size of maps that carry none"
    )
    source.add_argument("--fps", type=float, metavar="F", help="frame rate of maps without times")
    return parser


def add_wave_options(parser: argparse.ArgumentParser) -> None:
    """The analysis options (shared with ``process --waves``)."""
    from holoview.optics.surfaces import FLUID_MECHANICS

    fluid = parser.add_argument_group(
        "fluid and dispersion fit (--fluid: its density and starting surface tension, "
        f"one of {', '.join(sorted(FLUID_MECHANICS))}; default water)"
    )
    fluid.add_argument("--sigma", type=float, metavar="N_PER_M", help="starting surface tension")
    fluid.add_argument("--density", type=float, metavar="KG_PER_M3", help="fluid density")
    fluid.add_argument(
        "--depth-mm", type=float, metavar="MM", help="starting (or held) depth (default 5)"
    )
    fluid.add_argument("--flow-mm-per-s", metavar="UX,UY", help="starting (or held) mean flow")
    fluid.add_argument(
        "--hold", metavar="NAMES", default="", help="held in the fit: sigma,depth,flow"
    )
    fluid.add_argument("--no-fit", action="store_true", help="no dispersion fit")
    fluid.add_argument("--k-range", metavar="K1:K2", help="wavenumbers fitted, rad/m")
    fluid.add_argument(
        "--segment",
        type=int,
        default=128,
        metavar="N",
        help="frames per spectral segment (the (m, f) spectrum's: at least N, an eighth of "
        "the record up to 2048)",
    )
    around = parser.add_argument_group("around a centre (partial waves, ringdown)")
    around.add_argument(
        "--centre",
        metavar="X,Y|auto",
        help="centre in mm on the maps (x along columns, y along rows, from the first pixel)",
    )
    around.add_argument("--m-max", type=int, default=8, metavar="M", help="largest |m|")
    around.add_argument("--r-range-mm", metavar="R1:R2", help="ring radii, mm")
    around.add_argument(
        "--modes", metavar="M:F,...", help="partial waves to fit (default: the strongest)"
    )
    around.add_argument(
        "--n-modes", type=int, default=4, metavar="N", help="strongest (m, f) peaks fitted"
    )
    around.add_argument("--ringdown", metavar="M,F1:F2", help="fit a damped mode in this band")
    around.add_argument("--ringdown-start", type=float, metavar="T", help="fit from T s")
    drive = parser.add_argument_group("lock-in and band filter")
    drive.add_argument("--drive-hz", type=float, metavar="F", help="lock-in maps at F")
    drive.add_argument("--harmonics", type=int, default=3, metavar="N", help="of the drive")
    drive.add_argument("--band-k", metavar="K1:K2", help="band filter: wavenumbers, rad/m")
    drive.add_argument("--band-f", metavar="F1:F2", help="band filter: frequencies, Hz")
    drive.add_argument(
        "--band-direction",
        metavar="DEG[,HALF]",
        help="band filter: waves travelling within HALF (default 30) degrees of DEG",
    )


def _modes(text: str | None) -> tuple[tuple[int, float], ...]:
    if not text:
        return ()
    out = []
    for item in text.split(","):
        try:
            m, f = item.split(":")
            out.append((int(m), float(f)))
        except ValueError:
            raise InputError(f"--modes {text!r}: give M:F pairs, such as 0:14,2:22") from None
    return tuple(out)


def _band(args: argparse.Namespace) -> Any:
    from holoview.processing.waves.filters import Band

    if args.band_k is None and args.band_f is None and args.band_direction is None:
        return None
    k_min, k_max = _range(args.band_k, "--band-k")
    f_min, f_max = _range(args.band_f, "--band-f")
    direction, half = None, 30.0
    if args.band_direction is not None:
        parts = args.band_direction.split(",")
        try:
            direction = float(parts[0])
            half = float(parts[1]) if len(parts) > 1 else half
        except (ValueError, IndexError):
            raise InputError(f"--band-direction {args.band_direction!r}: give DEG[,HALF]") from None
    return Band(
        k_min,
        k_max,
        f_min,
        f_max,
        None if direction is None else math.radians(direction),
        math.radians(half),
    )


def wave_options(args: argparse.Namespace) -> Any:
    """Return the :class:`~holoview.headless.waves.analysis.WaveOptions` the arguments give."""
    from holoview.headless.waves.analysis import WaveOptions
    from holoview.optics.surfaces import FLUID_MECHANICS
    from holoview.processing.waves.dispersion import Fluid, check_fit_settings

    name = getattr(args, "fluid", None) or "water"
    if name not in FLUID_MECHANICS:
        raise InputError(
            f"--fluid {name}: no density and surface tension known for it; the wave "
            f"analyses know {', '.join(sorted(FLUID_MECHANICS))}"
        )
    fluid = Fluid.named(name)
    if args.sigma is not None or args.density is not None:
        fluid = Fluid(
            args.density if args.density is not None else fluid.density,
            args.sigma if args.sigma is not None else fluid.surface_tension,
            fluid.gravity,
            fluid.name,
        )
    hold = tuple(h for h in args.hold.split(",") if h.strip())
    if "depth" in hold and args.depth_mm is None:
        raise InputError("--hold depth needs --depth-mm")
    centre: Any = None
    if args.centre is not None:
        if args.centre.strip().lower() == "auto":
            centre = "auto"
        else:
            x0, y0 = _pair(args.centre, "--centre")
            centre = (x0 * MM, y0 * MM)
    ringdown = None
    if args.ringdown is not None:
        try:
            m_text, band = args.ringdown.split(",")
            f1, f2 = _range(band, "--ringdown")
            if f1 is None or f2 is None:
                raise ValueError
            ringdown = (int(m_text), f1, f2)
        except ValueError:
            raise InputError(f"--ringdown {args.ringdown!r}: give M,F1:F2 such as 2,9:15") from None
    ux, uy = (0.0, 0.0) if args.flow_mm_per_s is None else _pair(args.flow_mm_per_s, "--flow")
    flow = (ux * MM, uy * MM)
    r_low, r_high = _range(args.r_range_mm, "--r-range-mm")
    k_low, k_high = _range(args.k_range, "--k-range")
    for option, value in (("--segment", args.segment), ("--threads", args.threads)):
        if value < 1:
            raise InputError(f"{option} must be at least 1, got {value}")
    if args.drive_hz is not None and not (math.isfinite(args.drive_hz) and args.drive_hz > 0):
        raise InputError(f"--drive-hz must be positive, got {args.drive_hz}")
    depth = (args.depth_mm if args.depth_mm is not None else 5.0) * MM
    if not args.no_fit:  # before process makes its maps, not after
        check_fit_settings(hold, depth, fluid)
    return WaveOptions(
        fluid=fluid,
        depth=depth,
        flow=(0.0, 0.0) if args.flow_mm_per_s is None else flow,
        hold=hold,
        fit=not args.no_fit,
        segment=args.segment,
        k_range=(k_low, k_high),
        centre=centre,
        m_max=args.m_max,
        r_range=(None if r_low is None else r_low * MM, None if r_high is None else r_high * MM),
        modes=_modes(args.modes),
        n_modes=args.n_modes,
        drive=args.drive_hz,
        harmonics=args.harmonics,
        ringdown=ringdown,
        ringdown_start=args.ringdown_start,
        band=_band(args),
        workers=args.threads,
    )


def summary_line(out: Path, outcome: WavesOutcome) -> str:
    """One line of what came out (value ± error, units)."""
    from holoview.processing.waves.fit_text import fit_values, with_error

    summary = outcome.summary
    parts = [f"{out}: {summary['input']['frames']} frames of {summary['input']['label']}"]
    fit = outcome.results.dispersion
    if fit is not None:
        sigma, depth, flow = fit_values(fit)
        parts.append(f"sigma {sigma}, depth {depth}, flow {flow}")
    elif summary.get("dispersion_problem"):
        parts.append("no dispersion fit (waves.json's notes say why)")
    if summary.get("partial_waves"):
        parts.append(f"{len(summary['partial_waves'])} partial waves")
    ring = summary.get("ringdown")
    if ring:
        parts.append(
            f"ringdown {with_error(ring['frequency_hz'], ring['frequency_stderr_hz'])} Hz, "
            f"decay {with_error(ring['decay_per_s'], ring['decay_stderr_per_s'])} 1/s"
        )
    return "; ".join(parts)


def analyse(args: argparse.Namespace) -> Any:
    """Analyse and write as the arguments say; return the :class:`WavesOutcome`."""
    from holoview.headless.waves.outputs import run_waves

    options = wave_options(args)
    for name, value in (("--pixel-size-um", args.pixel_size_um), ("--fps", args.fps)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be positive, got {value}")
    return run_waves(
        args.input,
        args.out,
        options,
        label=args.label,
        time_range=None if args.time is None else _range(args.time, "--time"),
        pixel_size=None if args.pixel_size_um is None else args.pixel_size_um * 1e-6,
        fps=args.fps,
        overwrite=args.overwrite,
    )


def run(args: argparse.Namespace) -> int:
    """Analyse, write, print one line."""
    outcome = analyse(args)
    if not args.quiet:
        emit(summary_line(args.out, outcome))
    return 0
