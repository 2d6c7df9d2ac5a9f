"""MATLAB files of a run's results: MAT v5 through scipy, or v7.3 (HDF5) streamed.

Layout (both versions), one struct per group of ``results.h5``:

``attributes``
    The file's root attributes (format, optics, settings).
``trends``, ``peaks``
    One field per variable (``time``, ``frame``, ``mean_height_m`` (time x label), ...),
    ``units`` (a struct of the variables' units), labels as a char matrix, one row per
    peak padded with spaces (``cellstr(trends.label)`` in MATLAB).
``maps`` (when the results hold maps)
    ``time``, ``frame``, ``y``, ``x`` and one ``(time, y, x)`` array per map; a field is
    named after its label made a MATLAB identifier (``RB1``; ``m_2f`` for ``2f``);
    ``labels`` (char matrix) the labels in the order of ``fields``; ``units``; and
    ``attributes`` (a struct per map of its attributes: alpha, carrier, pixel size...).

Vectors are columns. Booleans are logical, complex values complex.

Version 5 (:func:`write_mat5`) is read by MATLAB, Octave, scipy.io.loadmat and Julia's
MAT.jl; it is built in memory, and a MAT-file of version 5 to 7 holds at most 2 GB per
variable (MATLAB's limit): larger maps are refused with a message naming version 7.3.
Version 7.3 (:func:`write_mat73`) is HDF5 with MATLAB's header and class attributes;
MATLAB reads it (``load``), h5py and HDF5 tools too, scipy does not. Its maps are
written chunk by chunk, so memory stays bounded whatever their size; arrays are stored
with their axes reversed, as MATLAB's column-major order has it.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import xarray as xr

from holoview.errors import InputError
from holoview.headless.results.results_data import map_labels

#: MATLAB's limit for one variable of a MAT-file of version 5 to 7, bytes.
MAT5_LIMIT_BYTES = 2**31

#: Field names of the ``maps`` struct that are not maps.
_MAP_FIELDS = ("time", "frame", "y", "x", "labels", "fields", "units", "attributes")

#: MATLAB class names of numpy dtypes (v7.3's ``MATLAB_class`` attribute).
_CLASSES = {
    "float64": "double",
    "float32": "single",
    "int64": "int64",
    "int32": "int32",
    "int16": "int16",
    "int8": "int8",
    "uint64": "uint64",
    "uint32": "uint32",
    "uint16": "uint16",
    "uint8": "uint8",
    "bool": "logical",
    "complex128": "double",
    "complex64": "single",
}

#: MATLAB's header of a v7.3 file: 116 bytes of text, subsystem offset, version, endian.
_USERBLOCK = 512


def field_name(label: str, taken: set[str]) -> str:
    """A MATLAB identifier for ``label``, unlike any in ``taken`` (which it joins).

    Examples
    --------
    >>> taken = set()
    >>> field_name("RB1", taken), field_name("2f", taken), field_name("RB1.5", taken)
    ('RB1', 'm_2f', 'RB1_5')
    >>> field_name("time", {"time"})
    'time_map'
    """
    name = re.sub(r"\W", "_", label)
    if not name[:1].isalpha():
        name = "m_" + name
    if name in taken:
        name += "_map"
    base, k = name, 2
    while name in taken:
        name, k = f"{base}{k}", k + 1
    taken.add(name)
    return name


def _char_matrix(values: list[str]) -> np.ndarray:
    """Strings as a char matrix, one row each, padded with spaces (at least one column)."""
    width = max([1, *(len(v) for v in values)])
    return np.array([v.ljust(width) for v in values])


def _value(values: np.ndarray) -> np.ndarray:
    """A variable's values for MATLAB: strings as a char matrix."""
    if values.dtype.kind in "OUS":
        return _char_matrix([str(v) for v in values.ravel()])
    return values


def _attributes(attrs: dict[str, Any]) -> dict[str, Any]:
    """Attributes as struct fields (identifiers; lists as arrays)."""
    out: dict[str, Any] = {}
    taken: set[str] = set()
    for key, value in attrs.items():
        if key in ("coordinates", "_FillValue"):
            continue
        name = field_name(key, taken)
        out[name] = np.asarray(value) if isinstance(value, list | tuple) else value
    return out


def _maps_struct(dataset: xr.Dataset) -> dict[str, Any]:
    """The ``maps`` struct: coordinates, one lazy array per map, labels, fields, attributes."""
    struct: dict[str, Any] = {}
    units: dict[str, str] = {}
    for name in ("time", "frame", "y", "x"):
        struct[name] = dataset[name].values
        units[name] = str(dataset[name].attrs.get("units", ""))
    taken = set(_MAP_FIELDS)
    labels = map_labels(dataset)
    fields = [field_name(label, taken) for label in labels]
    per_map: dict[str, Any] = {}
    for label, field in zip(labels, fields, strict=True):
        struct[field] = dataset[label]
        units[field] = str(dataset[label].attrs.get("units", ""))
        per_map[field] = _attributes(dict(dataset[label].attrs))
    struct["labels"] = _char_matrix(labels)
    struct["fields"] = _char_matrix(fields)
    struct["attributes"] = per_map
    struct["units"] = units
    return struct


def _table_struct(dataset: xr.Dataset) -> dict[str, Any]:
    """A ``trends`` or ``peaks`` struct: every variable and coordinate, and their units."""
    struct: dict[str, Any] = {}
    units: dict[str, str] = {}
    taken = {"units"}
    for name, variable in dataset.variables.items():
        field = field_name(str(name), taken)
        struct[field] = _value(variable.values)
        if "units" in variable.attrs:
            units[field] = str(variable.attrs["units"])
    struct["units"] = units
    return struct


def mat_tree(groups: dict[str, xr.Dataset], root: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The MAT-file's structs (module docstring); maps stay lazy (xarray DataArrays)."""
    tree: dict[str, dict[str, Any]] = {"attributes": _attributes(root)}
    for group, dataset in groups.items():
        tree[group] = _maps_struct(dataset) if group == "maps" else _table_struct(dataset)
    return tree


def _nbytes(value: Any) -> int:
    if isinstance(value, dict):
        return sum(_nbytes(v) for v in value.values())
    if isinstance(value, xr.DataArray | np.ndarray):
        return int(value.nbytes)
    return 64


def write_mat5(path: Path, tree: dict[str, dict[str, Any]]) -> None:
    """Write ``tree`` as a MAT v5 file (maps loaded into memory).

    Raises
    ------
    InputError
        A variable (a struct: ``maps`` with every map) would exceed 2 GB.
    """
    from scipy.io import savemat

    for name, struct in tree.items():
        size = _nbytes(struct)
        if size >= MAT5_LIMIT_BYTES:
            raise InputError(
                f"the {name} ({size / 1e9:.1f} GB) exceed the 2 GB a MAT-file of version 5 "
                "holds per variable: give --mat-version 7.3 (HDF5, read by MATLAB and h5py), "
                "fewer maps (--map), or export to netcdf or zarr"
            )
    savemat(path, _loaded(tree), format="5", long_field_names=True, oned_as="column")


def _loaded(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _loaded(v) for k, v in value.items()}
    if isinstance(value, xr.DataArray):
        return value.values
    if value is None:
        return np.array([])
    return value


def _header() -> bytes:
    """MATLAB's 128-byte v7.3 header, padded to the 512-byte HDF5 user block."""
    text = (
        "MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: "
        f"{time.strftime('%a %b %d %H:%M:%S %Y')} HDF5 schema 1.00 ."
    )
    head = text.encode("ascii").ljust(116, b" ") + b" " * 8 + b"\x00\x02" + b"IM"
    return head.ljust(_USERBLOCK, b"\x00")


def _matlab_layout(values: np.ndarray) -> np.ndarray:
    """An array as MATLAB stores it in HDF5: at least 2-D (vectors as columns), axes reversed."""
    if values.ndim == 0:
        values = values.reshape(1, 1)
    elif values.ndim == 1:
        values = values.reshape(-1, 1)
    return np.ascontiguousarray(values.T)


def _write73(group: h5py.Group, name: str, value: Any) -> None:
    """One field of a v7.3 struct: a sub-struct, a string, or an array (not a lazy map)."""
    if isinstance(value, dict):
        sub = group.create_group(name)
        sub.attrs["MATLAB_class"] = np.bytes_("struct")
        for key, item in value.items():
            _write73(sub, key, item)
        return
    array = np.asarray(value)
    if array.dtype.kind in "OUS":
        text = array if array.ndim >= 1 else _char_matrix([str(array)])
        rows = [str(v) for v in np.atleast_1d(text)]
        codes = np.array([[ord(c) for c in row] for row in _char_matrix(rows)], np.uint16)
        dataset = group.create_dataset(name, data=np.ascontiguousarray(codes.T))
        dataset.attrs["MATLAB_class"] = np.bytes_("char")
        dataset.attrs["MATLAB_int_decode"] = np.int32(2)
        return
    kind = _CLASSES.get(array.dtype.name)
    if kind is None:
        array, kind = array.astype(np.float64), "double"
    if array.dtype == bool:
        array = array.astype(np.uint8)
    if array.dtype.kind == "c":
        part = np.float32 if array.dtype == np.complex64 else np.float64
        compound = np.dtype([("real", part), ("imag", part)])
        stored = np.empty(array.shape, compound)
        stored["real"], stored["imag"] = array.real, array.imag
        array = stored
    dataset = group.create_dataset(name, data=_matlab_layout(array))
    dataset.attrs["MATLAB_class"] = np.bytes_(kind)


def write_mat73(
    path: Path,
    tree: dict[str, dict[str, Any]],
    *,
    chunk_frames: int,
    progress: Callable[[int, int], None] | None = None,
) -> None:
    """Write ``tree`` as a MAT v7.3 (HDF5) file, maps ``chunk_frames`` frames at a time.

    ``progress(done, total)`` is called after each chunk of frames of each map.
    """
    maps = {
        name: value
        for name, value in tree.get("maps", {}).items()
        if isinstance(value, xr.DataArray)
    }
    total = sum(-(-m.shape[0] // chunk_frames) for m in maps.values())
    done = 0
    with h5py.File(path, "w", userblock_size=_USERBLOCK) as f:
        for name, struct in tree.items():
            group = f.create_group(name)
            group.attrs["MATLAB_class"] = np.bytes_("struct")
            for key, value in struct.items():
                if not isinstance(value, xr.DataArray):
                    _write73(group, key, value)
        for field, array in maps.items():
            n, rows, cols = array.shape
            dataset = f["maps"].create_dataset(
                field, shape=(cols, rows, n), dtype=array.dtype, chunks=(cols, rows, 1)
            )
            dataset.attrs["MATLAB_class"] = np.bytes_(_CLASSES[array.dtype.name])
            for start in range(0, n, chunk_frames):
                stop = min(start + chunk_frames, n)
                block = np.asarray(array[start:stop].values)
                dataset[:, :, start:stop] = block.transpose(2, 1, 0)
                done += 1
                if progress is not None:
                    progress(done, total)
    with open(path, "r+b") as f:
        f.write(_header())
