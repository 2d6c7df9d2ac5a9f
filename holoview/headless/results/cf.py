"""HDF5 files that netCDF tools and xarray read with their coordinates and units.

The netCDF-4 data model is HDF5 with conventions: a *dimension* is a one-dimensional
dataset made an HDF5 dimension scale (its name is the dimension's name, its values
the coordinate), every other dataset has a scale attached to each of its axes, and
attributes follow the CF conventions (``units`` in UDUNITS spelling, ``long_name``,
``axis``). xarray (``engine="h5netcdf"``), netCDF-C tools and MATLAB's ``ncread``
then name every axis instead of inventing ``phony_dim_0``.

A writer here calls :func:`dimension` once per axis of a group and :func:`variable`
(or :func:`describe` and :func:`attach` on a dataset it made itself) for the data.
Dimensions are per group: xarray opens one group at a time and does not look for
coordinates in the groups above.

Units are CF/UDUNITS spellings: ``m``, ``s``, ``rad``, ``m3``, ``m s-1``, ``count``
(camera counts), and ``1`` for a plain number. Strings carry no unit.

Examples
--------
>>> import tempfile
>>> from pathlib import Path
>>> import h5py, numpy as np, xarray as xr
>>> path = Path(tempfile.mkdtemp()) / "series.h5"
>>> with h5py.File(path, "w") as f:
...     series = f.create_group("series")
...     time = dimension(series, "time", [0.0, 0.5, 1.0], units="s", long_name="time")
...     height = variable(series, "height", [0.0, 1e-9, 2e-9], ("time",), units="m",
...                       long_name="height change")
>>> with xr.open_dataset(path, group="series", engine="h5netcdf") as ds:
...     print(ds.height.dims, ds.height.attrs["units"], ds.time.values)
('time',) m [0.  0.5 1. ]
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import h5py
import numpy as np

#: The conventions the files follow (the ``Conventions`` root attribute).
CONVENTIONS = "CF-1.11"


def describe(dataset: h5py.Dataset, *, units: str | None, long_name: str, **more: Any) -> None:
    """Give ``dataset`` its CF attributes: ``units`` (None for strings), ``long_name``, more.

    Parameters
    ----------
    dataset : h5py.Dataset
        The variable or dimension.
    units : str or None
        A UDUNITS spelling (module docstring); None for a variable of strings.
    long_name : str
        What the values are, in words.
    **more
        Further attributes (``axis``, ``comment``, ...).
    """
    if units is not None:
        dataset.attrs["units"] = units
    dataset.attrs["long_name"] = long_name
    dataset.attrs.update(more)


def dimension(
    group: h5py.Group,
    name: str,
    values: np.ndarray | Sequence[Any],
    *,
    units: str | None,
    long_name: str,
    **more: Any,
) -> h5py.Dataset:
    """Create the dimension ``name`` of ``group``: a 1-D dataset made a dimension scale.

    Strings (a list of str) become a variable-length UTF-8 scale (labels).

    Returns
    -------
    h5py.Dataset
        The scale, to :func:`attach` to the axes it spans.
    """
    array = np.asarray(values)
    if array.dtype.kind in "OUS":
        array = np.array([str(v) for v in array], dtype=h5py.string_dtype())
    scale = group.create_dataset(name, data=array)
    scale.make_scale(name)
    describe(scale, units=units, long_name=long_name, **more)
    return scale


def attach(dataset: h5py.Dataset, scales: Sequence[h5py.Dataset]) -> None:
    """Attach one dimension scale to each axis of ``dataset``, in order.

    Raises
    ------
    ValueError
        The scales' number or lengths do not match the dataset's shape.
    """
    if len(scales) != dataset.ndim:
        raise ValueError(f"{dataset.name}: {dataset.ndim} axes, {len(scales)} scales")
    for axis, scale in enumerate(scales):
        if scale.shape[0] != dataset.shape[axis]:
            raise ValueError(
                f"{dataset.name}: axis {axis} has {dataset.shape[axis]} values, "
                f"{scale.name} has {scale.shape[0]}"
            )
        dataset.dims[axis].attach_scale(scale)


def variable(
    group: h5py.Group,
    name: str,
    values: np.ndarray | Sequence[Any],
    dims: Sequence[str],
    *,
    units: str | None,
    long_name: str,
    **more: Any,
) -> h5py.Dataset:
    """Create the variable ``name`` over the dimensions ``dims`` of ``group``, described.

    ``dims`` name dimensions made by :func:`dimension` in the same group. Strings
    become variable-length UTF-8.
    """
    array = np.asarray(values)
    if array.dtype.kind in "OUS":
        array = np.array([str(v) for v in array.ravel()], dtype=h5py.string_dtype()).reshape(
            array.shape
        )
    dataset = group.create_dataset(name, data=array)
    attach(dataset, [group[d] for d in dims])
    describe(dataset, units=units, long_name=long_name, **more)
    return dataset


def netcdf_attribute(value: Any) -> Any:
    """``value`` as netCDF can store it: booleans as 0/1 (netCDF has no boolean type)."""
    if isinstance(value, bool | np.bool_):
        return int(value)
    if isinstance(value, np.ndarray) and value.dtype == bool:
        return value.astype(np.int8)
    if isinstance(value, list | tuple) and any(isinstance(v, bool | np.bool_) for v in value):
        return [int(v) for v in value]
    return value
