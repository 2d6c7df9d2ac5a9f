"""The ``holoview`` command: argparse subcommands, logging set up here only.

Each subcommand lives in its own module of this package with two functions:
``add_parser(subparsers)`` registers its options (importing nothing heavy) and
``run(args) -> int`` does the work.

Exit statuses: 0 success; 2 a problem the user can fix (bad input, a missing
device, a broken file: a :class:`~holoview.errors.HoloviewError`, one line on
stderr); 3 an output could not be written (a full disk, an I/O error, a closed
standard output: an :class:`~holoview.errors.OutputError`; what was written before
is kept); 130 stopped by Ctrl-C, SIGTERM or SIGHUP (what was done is kept, see each
command); 1 only for a bug (a traceback). Python warnings (numpy's, OpenCV's) go to
the log, shown with ``-v``.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from holoview import __version__
from holoview.cli.options import add_verbosity_options
from holoview.cli.signals import Stopped, stop_on_signals
from holoview.errors import HoloviewError, OutputError

#: Subcommand modules, in the order ``holoview --help`` lists them.
COMMANDS: tuple[str, ...] = ("live", "record", "simulate", "process", "peaks", "export", "info")

#: The subcommand run when none is given.
DEFAULT_COMMAND = "live"


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line, exit status 2."""

    def error(self, message: str) -> NoReturn:
        """Print ``PROG: error: MESSAGE (see PROG --help)`` and exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """Return the top-level parser with every subcommand registered."""
    parser = OneLineParser(
        prog="holoview",
        description="Live view, recording and analysis for multiplexed off-axis "
        "digital holography of fluid surfaces. With no subcommand: the live GUI "
        "on the simulated camera; `holoview FILE`: the GUI on a recording.",
    )
    parser.add_argument("--version", action="version", version=f"holoview {__version__}")
    add_verbosity_options(parser, top=True)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        module = importlib.import_module(f"holoview.cli.{name}")
        sub = module.add_parser(subparsers)
        add_verbosity_options(sub)
        sub.set_defaults(_run=module.run)
    return parser


def configure_logging(verbose: int, quiet: bool) -> None:
    """Send holoview's log records to stderr at the level the flags ask for.

    Python warnings (numpy's overflow and the like) are logged too, under
    ``py.warnings``, shown only with ``-v``.
    """
    level = (
        logging.ERROR if quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    )
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("py.warnings").setLevel(logging.WARNING if verbose else logging.ERROR)
    # Dask (``process --scheduler``) sets its loggers' levels from its configuration when
    # imported, here and in its worker processes, which inherit the environment.
    dask_level = "info" if verbose >= 2 else ("error" if quiet else "warning")
    os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", dask_level)


def _quiet_hdf5_cleanup(unraisable: sys.UnraisableHookArgs) -> None:
    """Log, instead of printing, HDF5's complaints while h5py frees objects of a failed file.

    After a write failed (a full disk), every dataset h5py releases tries to flush and
    fails again; the error that matters has been reported once already.
    """
    if "h5py" in repr(unraisable.object):
        logging.getLogger(__name__).debug(
            "while freeing %r: %s", unraisable.object, unraisable.exc_value
        )
        return
    sys.__unraisablehook__(unraisable)


#: BLAS threads of the commands, unless the environment says otherwise: holoview's matrix
#: products are small and run in blocks on the calling thread (the carrier probe), and
#: OpenBLAS's pool of threads only spun beside them, on cores the reader and the FFT
#: need: ``benchmarks/bench_process.py``, 2000 frames of 1024^2, 615 frames/s with one
#: thread against 476 with OpenBLAS's default (2-core Xeon; the live window unchanged).
BLAS_THREADS = "1"


def _names_a_file(word: str) -> bool:
    """Whether a first word that is no command names a file (``holoview FILE``)."""
    path = Path(word)
    return path.exists() or bool(path.suffix) or "/" in word


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``holoview`` command line; return the process exit status."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", BLAS_THREADS)  # read as numpy loads
    parser = build_parser()
    args_list = list(sys.argv[1:] if argv is None else argv)
    only_options = all(a.startswith("-") for a in args_list)
    if only_options and not {"-h", "--help", "--version"} & set(args_list):
        args_list.append(DEFAULT_COMMAND)
    first = next((a for a in args_list if not a.startswith("-")), None)
    if first is not None and first not in COMMANDS and _names_a_file(first):
        args_list.insert(args_list.index(first), DEFAULT_COMMAND)  # holoview FILE: open it
    try:
        args = parser.parse_args(args_list)
    except SystemExit as exc:  # --help, --version, or a usage error already printed
        return exc.code if isinstance(exc.code, int) else 2
    configure_logging(args.verbose, args.quiet)
    logging.captureWarnings(True)
    previous_hook, sys.unraisablehook = sys.unraisablehook, _quiet_hdf5_cleanup
    try:
        with stop_on_signals():  # the live window, once open, closes itself on them
            return int(args._run(args) or 0)
    except OutputError as exc:
        print(f"holoview {args.command}: error: {exc}", file=sys.stderr)
        return 3
    except HoloviewError as exc:
        print(f"holoview {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except MemoryError as exc:
        print(
            f"holoview {args.command}: error: not enough memory "
            f"({str(exc) or 'an array too large'}); ask for fewer or smaller frames",
            file=sys.stderr,
        )
        return 2
    except KeyboardInterrupt as exc:
        how = f" by {exc.signal_name}" if isinstance(exc, Stopped) else ""
        print(f"holoview {args.command}: interrupted{how}", file=sys.stderr)
        return 130
    finally:
        logging.captureWarnings(False)
        sys.unraisablehook = previous_hook


if __name__ == "__main__":
    sys.exit(main())
