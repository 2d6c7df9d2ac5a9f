"""``holoview export``: a run's ``results.h5`` as NetCDF, Zarr, MATLAB or TIFF stacks.

The formats, their layouts and limits are documented in
:mod:`holoview.headless.results.exports`; the output is written under a temporary name and
renamed when complete, and replaces an existing one only with ``--overwrite``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from holoview.cli.signals import emit


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register ``export``."""
    parser = subparsers.add_parser(
        "export",
        help="export results.h5 to NetCDF, Zarr, MATLAB or TIFF stacks",
        description="Write the series, peaks and maps of RESULTS (a results.h5 or the output "
        "folder of holoview process) as a NetCDF file, a Zarr store (a folder), a MATLAB "
        "file, or a folder of ImageJ TIFF stacks (one per map, pixel size in um). Maps are "
        "written a chunk of frames at a time (MAT version 5 excepted: in memory, at most "
        "2 GB per variable).",
    )
    parser.add_argument(
        "results", type=Path, metavar="RESULTS", help="results.h5, or the folder holding it"
    )
    parser.add_argument(
        "--to",
        required=True,
        choices=("netcdf", "zarr", "mat", "tiff"),
        help="the format",
    )
    parser.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="PATH",
        help="file to create (netcdf, mat) or folder (zarr, tiff)",
    )
    parser.add_argument(
        "--map",
        action="append",
        default=[],
        metavar="LABEL",
        help="export this map only (a peak's label or fused; repeat for several)",
    )
    parser.add_argument(
        "--mat-version",
        choices=("5", "7.3"),
        default="5",
        help="MAT-file version: 5 (MATLAB, Octave, scipy; up to 2 GB per variable) or 7.3 "
        "(HDF5; MATLAB and h5py; any size, streamed). Default 5",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace PATH if it exists (once complete)"
    )
    return parser


def run(args: argparse.Namespace) -> int:
    """Export, with a progress bar; print one line naming what was written."""
    from tqdm import tqdm

    from holoview.headless.results.exports import export_results

    bar = tqdm(unit="chunk", disable=args.quiet or None, file=sys.stderr, dynamic_ncols=True)

    def update(done: int, total: int) -> None:
        if bar.total != total:
            bar.reset(total=total)
        bar.update(done - bar.n)

    with bar:
        done = export_results(
            args.results,
            args.to,
            args.out,
            maps=args.map,
            overwrite=args.overwrite,
            mat_version=args.mat_version,
            progress=update,
        )
    if not args.quiet:
        maps = f"; maps {', '.join(done.maps)}" if done.maps else ""
        emit(f"{done.path}: {done.format} of {', '.join(done.groups)}{maps}")
    return 0
