"""A run's results where users live: NetCDF, Zarr, MATLAB and TIFF stacks.

:func:`export_results` reads a ``results.h5`` (format 2.x, or 1.0) through
:func:`~holoview.headless.results.results_data.open_results` and writes:

``netcdf``
    One netCDF-4 file (``.nc``, written by h5netcdf) with the groups ``trends``,
    ``peaks`` and ``maps`` as ``results.h5`` has them (coordinates, ``units``), the
    root attributes as global attributes. netCDF has neither complex numbers nor
    booleans: ``carrier_value`` becomes ``carrier_value_real`` and
    ``carrier_value_imag``, booleans become 0/1 bytes (xarray reads them back as
    booleans), as in ``results.h5`` itself. Read by xarray, netCDF4, ncdump, Panoply,
    MATLAB's ``ncread``.
``zarr``
    A Zarr store (a folder, Zarr format 2: format 3 has no specification for strings
    yet, and MATLAB and most non-Python readers read format 2) with the same groups
    and attributes, maps in chunks of one frame, metadata consolidated.
``mat``
    A MATLAB file (:mod:`holoview.headless.results.export_mat`): version 5 by default (in
    memory, at most 2 GB per variable), or 7.3 (HDF5, streamed).
``tiff``
    A folder of ImageJ hyperstacks, ``<label>.tif`` per map (float32, m; axes TYX),
    with the pixel size in um (ImageJ's resolution and unit, which Fiji reads), the mean
    frame interval, each frame's index and time as its slice label, and the map's
    attributes as ImageJ properties. Files over 4 GB are written as ImageJ writes them
    (one IFD, the frames contiguous). Maps only: TIFF holds no series.

Maps are read and written a chunk of frames at a time (about :data:`CHUNK_BYTES`),
so memory stays bounded whatever their size, except for MAT version 5, which scipy
writes from arrays in memory. Every output is written under a temporary name and
renamed when complete (:mod:`holoview.atomic`): an export that fails or is stopped
leaves no partial output, and an existing output is replaced only with
``overwrite``.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import xarray as xr

from holoview.atomic import atomic_folder, atomic_path
from holoview.errors import InputError, OutputError, os_error_text
from holoview.headless.results.cf import netcdf_attribute, split_complex
from holoview.headless.results.export_mat import mat_tree, write_mat5, write_mat73
from holoview.headless.results.results_data import (
    map_labels,
    open_results,
    results_groups,
    results_path,
)

logger = logging.getLogger(__name__)

#: Export formats.
FORMATS = ("netcdf", "zarr", "mat", "tiff")

#: MAT-file versions written.
MAT_VERSIONS = ("5", "7.3")

#: Bytes of maps read and written at a time.
CHUNK_BYTES = 32 * 2**20

#: The Zarr format written.
ZARR_FORMAT: Literal[2] = 2

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class Export:
    """What an export wrote.

    Attributes
    ----------
    path : Path
        The file (NetCDF, MAT) or folder (Zarr, TIFF).
    format : str
        One of :data:`FORMATS`.
    groups : tuple of str
        The groups of ``results.h5`` exported.
    maps : tuple of str
        The maps exported.
    """

    path: Path
    format: str
    groups: tuple[str, ...]
    maps: tuple[str, ...]


def _check_request(to: str, mat_version: str, target: Path, overwrite: bool) -> None:
    if to not in FORMATS:
        raise InputError(f"unknown export format {to!r}; choose one of {', '.join(FORMATS)}")
    if mat_version not in MAT_VERSIONS:
        raise InputError(f"MAT-file version {mat_version!r}: choose 5 or 7.3")
    if not str(target).strip():
        raise InputError("give an output path, not an empty name")
    if target.exists() and not overwrite:
        raise InputError(f"{target} exists; give --overwrite to replace it")
    if target.is_dir() != (to in ("zarr", "tiff")) and target.exists():
        kind = "a folder" if target.is_dir() else "a file"
        raise InputError(f"{target} is {kind}; a {to} export is not: choose another path")
    if not target.parent.is_dir():
        raise InputError(f"folder {target.parent} does not exist")


def _select_maps(dataset: xr.Dataset, wanted: Sequence[str] | None) -> xr.Dataset:
    labels = map_labels(dataset)
    if not wanted:
        return dataset
    missing = [w for w in wanted if w not in labels]
    if missing:
        raise InputError(
            f"no map {', '.join(missing)} in the results; they hold {', '.join(labels)}"
        )
    return dataset.drop_vars([n for n in labels if n not in wanted])


def chunk_frames(dataset: xr.Dataset) -> int:
    """Frames of a ``maps`` Dataset read at a time: about :data:`CHUNK_BYTES` of one map."""
    frame_bytes = dataset.sizes["y"] * dataset.sizes["x"] * 4
    return max(1, CHUNK_BYTES // max(frame_bytes, 1))


def export_results(
    results: str | Path,
    to: str,
    out: str | Path,
    *,
    maps: Sequence[str] | None = None,
    overwrite: bool = False,
    mat_version: str = "5",
    progress: Progress | None = None,
) -> Export:
    """Export a ``results.h5`` to NetCDF, Zarr, MATLAB or TIFF (module docstring).

    Parameters
    ----------
    results : str or Path
        ``results.h5`` (format 2.x or 1.0), or the output folder holding it.
    to : str
        ``"netcdf"``, ``"zarr"``, ``"mat"`` or ``"tiff"``.
    out : str or Path
        The file (NetCDF, MAT) or folder (Zarr, TIFF) to create.
    maps : sequence of str, optional
        The maps to export (labels, ``fused``); all by default.
    overwrite : bool
        Replace an existing ``out`` (once the new one is complete).
    mat_version : str
        ``"5"`` or ``"7.3"`` (``to="mat"`` only).
    progress : callable, optional
        ``progress(done, total)`` as the maps are written (steps of a chunk).

    Returns
    -------
    Export

    Raises
    ------
    InputError
        No such results file, an unknown format or map, an existing output without
        ``overwrite``, TIFF from results without maps, MAT v5 over its 2 GB limit.
    OutputError
        The output could not be written (nothing is left at ``out``).
    """
    source = results_path(results)
    target = Path(out)
    _check_request(to, mat_version, target, overwrite)
    groups = results_groups(source)
    if to == "tiff":
        if "maps" not in groups:
            raise InputError(f"{source} holds no maps for TIFF: run holoview process with --maps")
        groups = ["maps"]
    if maps and "maps" not in groups:
        raise InputError(f"{source} holds no maps: run holoview process with --maps")
    with contextlib.ExitStack() as stack:
        data: dict[str, xr.Dataset] = {}
        for group in groups:
            dataset = stack.enter_context(open_results(source, group))
            if group == "maps":
                dataset = _select_maps(dataset, maps)
                dataset = dataset.chunk({"time": chunk_frames(dataset), "y": -1, "x": -1})
            data[group] = dataset
        root = dict(data[groups[0]].attrs)
        for dataset in data.values():
            dataset.attrs = {}
        labels = tuple(map_labels(data["maps"])) if "maps" in data else ()
        try:
            _write(
                to,
                target,
                data,
                root,
                overwrite=overwrite,
                mat_version=mat_version,
                progress=progress,
            )
        except (OSError, RuntimeError) as exc:
            raise OutputError(f"cannot write {target}: {os_error_text(exc)}") from exc
    logger.info("exported %s to %s (%s)", source, target, to)
    return Export(target, to, tuple(groups), labels)


def _write(
    to: str,
    target: Path,
    data: dict[str, xr.Dataset],
    root: dict[str, Any],
    *,
    overwrite: bool,
    mat_version: str,
    progress: Progress | None,
) -> None:
    import dask

    with dask.config.set(scheduler="synchronous"):  # one chunk in memory at a time
        if to == "netcdf":
            with atomic_path(target) as partial, _TaskProgress(progress):
                write_netcdf(partial, data, root)
        elif to == "zarr":
            with atomic_folder(target, replace=overwrite) as partial, _TaskProgress(progress):
                write_zarr(partial, data, root)
        elif to == "mat":
            tree = mat_tree(data, root)
            with atomic_path(target) as partial:
                if mat_version == "5":
                    write_mat5(partial, tree)
                else:
                    frames = chunk_frames(data["maps"]) if "maps" in data else 1
                    write_mat73(partial, tree, chunk_frames=frames, progress=progress)
        else:
            with atomic_folder(target, replace=overwrite) as partial:
                write_tiffs(partial, data["maps"], progress)


class _TaskProgress:
    """Report dask's finished tasks as ``progress(done, total)`` while a block computes."""

    def __init__(self, progress: Progress | None) -> None:
        self._progress = progress
        self._callback: Any = None

    def __enter__(self) -> _TaskProgress:
        if self._progress is None:
            return self
        from dask.callbacks import Callback

        report = self._progress
        counts = {"done": 0, "total": 0}

        def start_state(dsk: Any, state: dict[str, Any]) -> None:
            counts["done"] = 0
            counts["total"] = sum(len(state[k]) for k in ("ready", "waiting", "running"))

        def posttask(key: Any, result: Any, dsk: Any, state: Any, worker_id: Any) -> None:
            counts["done"] += 1
            report(counts["done"], max(counts["total"], counts["done"]))

        self._callback = Callback(start_state=start_state, posttask=posttask)
        self._callback.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._callback is not None:
            self._callback.__exit__(*exc)


def _for_netcdf(dataset: xr.Dataset) -> xr.Dataset:
    """Complex variables split into real and imaginary parts, booleans in attributes as 0/1."""
    out = split_complex(dataset)
    for variable in out.variables.values():
        variable.attrs = {k: netcdf_attribute(v) for k, v in variable.attrs.items()}
    return out


def _map_encoding(dataset: xr.Dataset, key: str, chunks: tuple[int, ...]) -> dict[str, Any]:
    return {name: {key: chunks} for name in map_labels(dataset)}


def write_netcdf(path: Path, data: dict[str, xr.Dataset], root: dict[str, Any]) -> None:
    """Write the groups into one netCDF-4 file at ``path`` (module docstring)."""
    attrs = {k: netcdf_attribute(v) for k, v in root.items()}
    xr.Dataset(attrs=attrs).to_netcdf(path, mode="w", engine="h5netcdf")
    for group, dataset in data.items():
        encoding = {}
        if group == "maps":
            by, bx = dataset.sizes["y"], dataset.sizes["x"]
            encoding = _map_encoding(dataset, "chunksizes", (1, by, bx))
        _for_netcdf(dataset).to_netcdf(
            path, mode="a", group=group, engine="h5netcdf", encoding=encoding
        )


def write_zarr(path: Path, data: dict[str, xr.Dataset], root: dict[str, Any]) -> None:
    """Write the groups into a Zarr store (folder) at ``path`` (module docstring)."""
    import zarr

    attrs = {k: netcdf_attribute(v) for k, v in root.items()}
    xr.Dataset(attrs=attrs).to_zarr(path, mode="w", zarr_format=ZARR_FORMAT, consolidated=False)
    for group, dataset in data.items():
        encoding = {}
        if group == "maps":
            by, bx = dataset.sizes["y"], dataset.sizes["x"]
            encoding = _map_encoding(dataset, "chunks", (1, by, bx))
        clean = dataset.copy()
        for variable in clean.variables.values():
            variable.attrs = {k: netcdf_attribute(v) for k, v in variable.attrs.items()}
        clean.to_zarr(
            path,
            group=group,
            mode="w",
            zarr_format=ZARR_FORMAT,
            consolidated=False,
            encoding=encoding,
        )
    zarr.consolidate_metadata(str(path), zarr_format=ZARR_FORMAT)


def _frames(array: xr.DataArray, step: int, progress: Callable[[], None]) -> Iterator[np.ndarray]:
    """The frames of a ``(time, y, x)`` map, read ``step`` at a time, as float32."""
    for start in range(0, array.sizes["time"], step):
        block = np.asarray(array[start : start + step].values, dtype=np.float32)
        yield from block
        progress()


def _imagej_metadata(array: xr.DataArray, dataset: xr.Dataset) -> dict[str, Any]:
    """ImageJ's metadata of one map: axes, unit, frame interval, labels, properties."""
    times = dataset["time"].values
    frames = dataset["frame"].values
    metadata: dict[str, Any] = {
        "axes": "TYX",
        "unit": "um" if "pixel_size_m" in array.attrs else "pixel",
        "Labels": [f"frame {int(f)}, t = {t:.6f} s" for f, t in zip(frames, times, strict=True)],
        "Properties": {
            str(k): str(v) for k, v in array.attrs.items() if not str(k).startswith("_")
        },
        "Info": f"holoview map {array.name}: values in {array.attrs.get('units', 'm')}, "
        "NaN where not trusted; slice labels give each frame's index and time",
    }
    if times.size > 1:
        metadata["finterval"] = float(np.mean(np.diff(times)))
    return metadata


def write_tiffs(folder: Path, dataset: xr.Dataset, progress: Progress | None = None) -> None:
    """Write ``<label>.tif`` per map of ``dataset`` into ``folder`` (module docstring)."""
    import tifffile

    labels = map_labels(dataset)
    step = chunk_frames(dataset)
    n = dataset.sizes["time"]
    total = len(labels) * (-(-n // step))
    done = [0]

    def advance() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], total)

    for label in labels:
        array = dataset[label]
        options: dict[str, Any] = {}
        size = array.attrs.get("pixel_size_m")
        if size is not None:
            options["resolution"] = (1 / (float(size[1]) * 1e6), 1 / (float(size[0]) * 1e6))
        tifffile.imwrite(
            folder / f"{label}.tif",
            data=_frames(array, step, advance),
            shape=(n, dataset.sizes["y"], dataset.sizes["x"]),
            dtype=np.float32,
            imagej=True,
            metadata=_imagej_metadata(array, dataset),
            **options,
        )
