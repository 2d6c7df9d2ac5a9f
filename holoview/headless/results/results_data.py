"""``results.h5`` as xarray Datasets: one per group, with coordinates and units.

:func:`open_results` opens a group of a ``results.h5`` (or of the output folder that
holds one) lazily: ``maps`` gives ``h(time, y, x)`` per peak and ``fused``, in m with
``time`` in s and ``y``, ``x`` in m on the object side; ``trends`` the series by
``(time, label)``; ``peaks`` the per-peak table by ``label``. Every numeric variable
carries ``units`` (CF spelling) and ``long_name``; the Dataset's attributes are the
file's root attributes (format, optics, settings).

Format 2.x files (:mod:`holoview.headless.results.results_layout`) are netCDF-4 and open
through xarray's ``h5netcdf`` engine. Whatever their version, the Datasets hold the
same types: booleans as booleans (format 2.1 stores them as int8 0/1, which xarray
reads back as booleans by their ``dtype`` marker; the attributes
:data:`~holoview.headless.results.results_layout.BOOLEAN_ATTRIBUTES` are made booleans
here) and ``carrier_value`` complex (2.1 stores its parts, joined here by
:func:`~holoview.headless.results.cf.join_complex`). Format 1.0 files (written before
dimension scales) are read here into the same Datasets: coordinates rebuilt from the
maps' ``pixel_step_px`` and ``pixel_size_m`` and the trends' ``time_s``, ``unit``
attributes turned into ``units`` in CF spelling; their maps stay on disk (dask).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import xarray as xr

from holoview.acquire.durability import open_hdf5_for_reading
from holoview.errors import InputError
from holoview.headless.results.cf import join_complex
from holoview.headless.results.results_layout import (
    BOOLEAN_ATTRIBUTES,
    LABEL_NAME,
    RESULTS_FORMAT,
    RESULTS_VERSION,
    TIME_NAME,
    map_axis,
)

logger = logging.getLogger(__name__)

#: The groups of a results file.
GROUPS = ("maps", "trends", "peaks")

#: Major format versions read here.
READABLE_MAJORS = (1, 2)

#: Format 1.0's ``unit`` values in CF spelling (the empty unit: a plain number).
_CF_UNITS = {"": "1", "m^3": "m3", "counts": "count"}

#: Frames of maps per dask chunk of a format 1.0 file by default.
V1_CHUNK_FRAMES = 16


def results_path(path: str | Path) -> Path:
    """The ``results.h5`` that ``path`` names: the file, or the one in an output folder.

    Raises
    ------
    InputError
        No such file, or a folder without ``results.h5``.
    """
    p = Path(path)
    if p.is_dir():
        p = p / "results.h5"
    if not p.is_file():
        raise InputError(f"{p}: no such results file")
    return p


def results_version(path: str | Path) -> str:
    """The ``format_version`` of a holoview results file (``"1.0"``, ``"2.0"``, ``"2.1"``).

    Raises
    ------
    InputError
        The file is not HDF5, not a holoview results file, or of a version not read.
    """
    p = results_path(path)
    with open_hdf5_for_reading(p) as f:  # a truncated copy said as such
        kind = _text(f.attrs.get("format", ""))
        version = _text(f.attrs.get("format_version", ""))
    if kind != RESULTS_FORMAT:
        raise InputError(f"{p}: not a holoview results file (format {kind or 'unknown'!r})")
    try:
        major = int(version.split(".", 1)[0])
    except ValueError:
        major = -1
    if major not in READABLE_MAJORS:
        raise InputError(
            f"{p}: results format version {version!r} is not read by this holoview "
            f"(it reads up to {RESULTS_VERSION})"
        )
    return version


def results_groups(path: str | Path) -> list[str]:
    """The groups of :data:`GROUPS` that the results file holds (``maps`` only with maps)."""
    p = results_path(path)
    results_version(p)
    with h5py.File(p, "r") as f:
        return [g for g in GROUPS if g in f and (g != "maps" or _map_names(f["maps"]))]


def open_results(
    path: str | Path, group: str = "maps", *, chunks: dict[str, int] | None = None
) -> xr.Dataset:
    """Open one group of a results file as an xarray Dataset (lazily).

    Parameters
    ----------
    path : str or Path
        ``results.h5``, or the output folder of ``holoview process`` holding it.
    group : str
        ``"maps"``, ``"trends"`` or ``"peaks"``.
    chunks : dict, optional
        Dask chunks (``{"time": 16}``): the variables are then dask arrays, read chunk
        by chunk when computed. Format 1.0 maps are dask arrays in any case.

    Returns
    -------
    xarray.Dataset
        Its ``attrs`` are the file's root attributes. Close it (or use it in a
        ``with`` block) to release the file.

    Raises
    ------
    InputError
        No such file, not a results file, an unknown group, or no maps in a file
        written without ``--maps``.
    """
    p = results_path(path)
    if group not in GROUPS:
        raise InputError(f"unknown results group {group!r}; choose one of {', '.join(GROUPS)}")
    version = results_version(p)
    with h5py.File(p, "r") as f:
        root = _booleans({k: _plain(v) for k, v in f.attrs.items()})
        if group not in f or (group == "maps" and not _map_names(f["maps"])):
            hint = ": run holoview process with --maps" if group == "maps" else ""
            raise InputError(f"{p} holds no {group}{hint}")
    if version.startswith("1."):
        dataset = _open_v1(p, group, chunks)
    else:
        dataset = join_complex(xr.open_dataset(p, group=group, engine="h5netcdf", chunks=chunks))
        for variable in dataset.variables.values():
            variable.attrs = _booleans(variable.attrs)
    dataset.attrs.update(root)
    return dataset


def map_labels(dataset: xr.Dataset) -> list[str]:
    """The map variables of a ``maps`` Dataset (peaks in file order, then ``fused``)."""
    names = [str(n) for n in dataset.data_vars if dataset[n].dims == ("time", "y", "x")]
    return sorted(names, key=lambda n: n == "fused")


def _map_names(group: h5py.Group) -> list[str]:
    return [n for n, item in group.items() if isinstance(item, h5py.Dataset) and item.ndim == 3]


def _text(value: Any) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _plain(value: Any) -> Any:
    """An attribute as Python holds it: str for bytes, lists for small arrays."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray) and value.dtype.kind in "OS":
        return [_text(v) for v in value]
    return value


def _booleans(attrs: dict[Any, Any]) -> dict[Any, Any]:
    """``attrs`` with :data:`BOOLEAN_ATTRIBUTES` as booleans (format 2.1 stores int8 0/1)."""
    return {k: bool(v) if k in BOOLEAN_ATTRIBUTES else v for k, v in attrs.items()}


def _units(dataset: h5py.Dataset) -> dict[str, str]:
    """A format 1.0 dataset's ``unit`` as CF ``units`` (none for strings).

    Format 1.0 wrote no unit in ``/peaks``: its rates are in m/s, the rest plain numbers.
    """
    if dataset.dtype.kind in "OS":
        return {}
    unit = _text(dataset.attrs.get("unit", ""))
    if dataset.name.endswith("_m_per_s"):
        unit = "m s-1"
    return {"units": _CF_UNITS.get(unit, unit)}


def _strings(dataset: h5py.Dataset) -> np.ndarray:
    return np.array([_text(v) for v in dataset[()]])


def _open_v1(path: Path, group: str, chunks: dict[str, int] | None) -> xr.Dataset:
    """A format 1.0 group as the Dataset format 2.0 gives (module docstring)."""
    if group == "maps":
        return _open_v1_maps(path, chunks)
    with h5py.File(path, "r") as f:
        g = f[group]
        labels = _strings(g["label"])
        coords: dict[str, Any] = {"label": ("label", labels, {"long_name": LABEL_NAME})}
        variables: dict[str, Any] = {}
        if group == "trends":
            times = g["time_s"][()]
            coords["time"] = ("time", times, {"units": "s", "long_name": TIME_NAME})
            coords["frame"] = ("time", g["frame"][()], {"units": "1"})
        else:
            coords["component"] = ("component", np.array(["fx", "fy"]))
        for name, item in g.items():
            if name in ("label", "time_s", "frame"):
                continue
            values = _strings(item) if item.dtype.kind in "OS" else item[()]
            variables[name] = (_v1_dims(name, values.ndim, group), values, _units(item))
    dataset = xr.Dataset(variables, coords=coords)
    return dataset if chunks is None else dataset.chunk(chunks)


def _v1_dims(name: str, ndim: int, group: str) -> tuple[str, ...]:
    """A format 1.0 variable's dimensions, by its group, name and rank."""
    if group == "peaks":
        return ("label", "component")[:ndim]
    if ndim == 2:
        return ("time", "label")
    return ("label",) if name == "alpha" else ("time",)


def _open_v1_maps(path: Path, chunks: dict[str, int] | None) -> xr.Dataset:
    import dask.array as da

    f = h5py.File(path, "r")
    try:
        names = _map_names(f["maps"])
        first = f["maps"][names[0]]
        n, by, bx = first.shape
        step = [float(v) for v in first.attrs["pixel_step_px"]]
        size = first.attrs.get("pixel_size_m")
        pitch = None if size is None else float(size[0]) / step[0]
        axis_units = "1" if pitch is None else "m"
        k = (chunks or {}).get("time", V1_CHUNK_FRAMES)
        variables = {}
        for name in names:
            source = f["maps"][name]
            attrs = {k: _plain(v) for k, v in source.attrs.items() if k != "unit"}
            attrs.update(_units(source))
            lazy = da.from_array(source, chunks=(max(1, k), by, bx), lock=True)
            variables[name] = (("time", "y", "x"), lazy, attrs)
        times = f["trends"]["time_s"][:n]
        coords = {
            "time": ("time", times, {"units": "s", "long_name": TIME_NAME}),
            "frame": ("time", f["trends"]["frame"][:n], {"units": "1"}),
            "y": ("y", map_axis(by, step[0], pitch), {"units": axis_units}),
            "x": ("x", map_axis(bx, step[1], pitch), {"units": axis_units}),
        }
        dataset = xr.Dataset(variables, coords=coords)
    except BaseException:
        f.close()
        raise
    dataset.set_close(f.close)
    return dataset
