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

Only the netCDF-4 types that every netCDF-C release reads are written: h5py's booleans
(an HDF5 enum) and complex numbers (an HDF5 compound) are dropped without a word by
netCDF-C before 4.10 (Debian 12's ncdump, 4.9.0, shows neither). So a boolean variable
is int8 0/1 with CF's ``flag_values`` and ``flag_meanings`` and xarray's marker
``dtype = "bool"`` (:func:`flags`; xarray reads it back as booleans), a boolean
attribute an int8 0/1 (:func:`flag_attribute`), and a complex variable two float
variables ``<name>_real`` and ``<name>_imag`` (:func:`complex_parts`;
:func:`split_complex` and :func:`join_complex` do the same to xarray Datasets).

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
import xarray as xr

#: The conventions the files follow (the ``Conventions`` root attribute).
CONVENTIONS = "CF-1.11"

#: The parts a complex variable is stored as, ``<name>_real`` and ``<name>_imag``.
COMPLEX_PARTS = ("real", "imag")

#: The CF flag attributes of a boolean variable stored as int8 0/1.
FLAG_ATTRIBUTES = {"flag_values": np.array([0, 1], dtype=np.int8), "flag_meanings": "false true"}


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


def flags(
    group: h5py.Group,
    name: str,
    values: np.ndarray | Sequence[bool],
    dims: Sequence[str],
    *,
    long_name: str,
    **more: Any,
) -> h5py.Dataset:
    """Create the boolean variable ``name``: int8 0/1, flagged as booleans (module docstring).

    Its attributes are ``units`` ``1``, ``long_name``, :data:`FLAG_ATTRIBUTES` and
    ``dtype = "bool"``, the marker with which xarray writes booleans and reads them back.
    """
    array = np.asarray(values, dtype=bool).astype(np.int8)
    return variable(
        group,
        name,
        array,
        dims,
        units="1",
        long_name=long_name,
        **FLAG_ATTRIBUTES,
        dtype="bool",
        **more,
    )


def flag_attribute(value: bool) -> np.int8:
    """A boolean attribute as netCDF-C reads it: int8 0/1."""
    return np.int8(value)


def complex_parts(
    group: h5py.Group,
    name: str,
    values: np.ndarray,
    dims: Sequence[str],
    *,
    units: str,
    long_name: str,
    **more: Any,
) -> tuple[h5py.Dataset, h5py.Dataset]:
    """Create the complex variable ``name`` as ``<name>_real`` and ``<name>_imag``.

    Each part has the real type of ``values`` (float32 for complex64), the ``units``
    and the ``long_name`` followed by `` (real part)`` or `` (imag part)``:
    :func:`join_complex` joins them again.
    """
    array = np.asarray(values)
    real, imag = (
        variable(
            group,
            f"{name}_{part}",
            getattr(array, part),
            dims,
            units=units,
            long_name=_part_name(long_name, part),
            **more,
        )
        for part in COMPLEX_PARTS
    )
    return real, imag


def _part_name(long_name: str, part: str) -> str:
    return f"{long_name} ({part} part)"


def split_complex(dataset: xr.Dataset) -> xr.Dataset:
    """``dataset`` with each complex variable split into ``<name>_real`` and ``<name>_imag``."""
    out = dataset.copy()
    for name in list(out.data_vars):
        array = out[name]
        if np.issubdtype(array.dtype, np.complexfloating):
            for part in COMPLEX_PARTS:
                attrs = dict(array.attrs)
                attrs["long_name"] = _part_name(attrs.get("long_name", str(name)), part)
                out[f"{name}_{part}"] = getattr(array, part).assign_attrs(attrs)
            out = out.drop_vars([name])
    return out


def join_complex(dataset: xr.Dataset) -> xr.Dataset:
    """``dataset`` with each pair ``<name>_real``, ``<name>_imag`` joined into complex ``<name>``.

    The inverse of :func:`split_complex` and :func:`complex_parts`: the attributes are
    the real part's, its ``long_name`` without `` (real part)``; the variables keep
    their order, and the file stays open until the returned Dataset is closed.
    """
    real, imag = (f"_{part}" for part in COMPLEX_PARTS)
    names = [str(name) for name in dataset.data_vars]
    stems = [
        n.removesuffix(real)
        for n in names
        if n.endswith(real) and n.removesuffix(real) + imag in names
    ]
    if not stems:
        return dataset
    parts = {stem + suffix: stem for stem in stems for suffix in (real, imag)}
    for stem in stems:
        real_part = dataset[stem + real]
        long_name = str(real_part.attrs.get("long_name", stem)).removesuffix(_part_name("", "real"))
        joined = (real_part + 1j * dataset[stem + imag]).assign_attrs(
            {**real_part.attrs, "long_name": long_name}
        )
        dataset = dataset.drop_vars([stem + real, stem + imag]).assign({stem: joined})
    order = dict.fromkeys(parts.get(n, n) for n in names)  # each stem where its real part was
    return dataset[list(order)]


def netcdf_attribute(value: Any) -> Any:
    """``value`` as netCDF can store it: booleans as 0/1 (netCDF has no boolean type), int8
    as in ``results.h5`` (:func:`flag_attribute`)."""
    if isinstance(value, bool | np.bool_):
        return flag_attribute(bool(value))
    if isinstance(value, np.ndarray) and value.dtype == bool:
        return value.astype(np.int8)
    if isinstance(value, list | tuple) and any(isinstance(v, bool | np.bool_) for v in value):
        return [int(v) for v in value]
    return value
