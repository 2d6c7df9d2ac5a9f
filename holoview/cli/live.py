"""``holoview live``: the live GUI (the default command)."""

from __future__ import annotations

import argparse
import logging
import os
import sys
from pathlib import Path

from holoview.cli.options import add_experiment_option, add_optics_options, optics_in_metres

NO_DISPLAY_HELP = (
    "no display found (DISPLAY and WAYLAND_DISPLAY are unset). Run the GUI under a "
    "virtual display with `xvfb-run -a holoview live`, or process recordings headless "
    "with `holoview process INPUT --out DIR`."
)


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register ``live``."""
    parser = subparsers.add_parser("live", help="open the live GUI (default: simulated camera)")
    parser.add_argument(
        "file",
        nargs="?",
        type=Path,
        metavar="FILE",
        help="a recording (or TIFF stack, image folder, video, .npy) to open as File > Open "
        "does: paused on its first frame, its whole run measured, the experiment it "
        "carries applied (`holoview FILE` is the same)",
    )
    parser.add_argument(
        "--source",
        default="sim",
        help="camera source: sim (default), aravis[:ID], v4l2[:N] or replay:PATH",
    )
    parser.add_argument(
        "--quit-after",
        type=float,
        default=None,
        metavar="SECONDS",
        help="close the window this many seconds after its source has opened (for scripted runs "
        "and screenshots)",
    )
    add_experiment_option(
        parser,
        "the experiment (optics, labelled peaks, window, reference) to use and keep up to "
        "date; default: $XDG_CONFIG_HOME/holoview/experiment.json",
    )
    add_optics_options(parser, "physical parameters (over the experiment's)")
    return parser


def has_display() -> bool:
    """Return True when Qt can open a window: a display or an explicit platform plugin."""
    return bool(
        os.environ.get("DISPLAY")
        or os.environ.get("WAYLAND_DISPLAY")
        or os.environ.get("QT_QPA_PLATFORM")
    )


def run(args: argparse.Namespace) -> int:
    """Open the main window and run the Qt event loop until it closes."""
    if not has_display():
        print(f"holoview live: {NO_DISPLAY_HELP}", file=sys.stderr)
        return 2
    from holoview.file_kinds import check_regular_file, special_file
    from holoview.ui.app import run_live

    if args.file is not None:
        what = special_file(args.file)
        problem = f"{what}, not a file or folder of frames" if what else "no such file or folder"
        if what or not args.file.exists():
            print(f"holoview live: error: {args.file}: {problem}", file=sys.stderr)
            return 2
    if args.experiment is not None:  # the window reads it, and saves every change to it
        check_regular_file(args.experiment, f"experiment file {args.experiment}")
    status = run_live(
        source=args.source,
        open_path=args.file,
        quit_after=args.quit_after,
        experiment=args.experiment,
        optics=optics_in_metres(args),
    )
    # The window is shut down (its threads and child process ended, its files closed):
    # end here, not in the interpreter's teardown, where Qt's and PyQt's objects go in no
    # set order (exit status -11 after a clean close, seen once in CI, not reproduced in
    # 17 runs under load). Python's own exit handlers are not needed past this point.
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)
