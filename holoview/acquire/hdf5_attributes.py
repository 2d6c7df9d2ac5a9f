"""Settings and setup values as HDF5 attributes, each with its unit (recordings' layout).

A value is written as an attribute of a group and its unit as the attribute of the
same name on the group's ``units`` subgroup (``""`` for dimensionless). Names ending
in a unit suffix (:data:`UNIT_SUFFIXES`) get that unit unless one is given: a value
may be a ``(value, unit)`` pair. ``None`` is not written.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from holoview.errors import InputError

#: Unit implied by a name's suffix, where no unit is given explicitly.
UNIT_SUFFIXES: dict[str, str] = {
    "_m": "m",
    "_s": "s",
    "_hz": "Hz",
    "_db": "dB",
    "_px": "pixel",
    "_k": "K",
}


def unit_for(name: str) -> str:
    """Return the unit a setting's name implies by its suffix (``""`` when none)."""
    for suffix, unit in UNIT_SUFFIXES.items():
        if name.endswith(suffix):
            return unit
    return ""


def attribute_value(name: str, value: object) -> Any:
    """Return ``value`` in a form HDF5 stores as an attribute, or raise InputError."""
    if isinstance(value, bool | np.bool_):
        return np.bool_(value)
    if isinstance(value, str | int | float | np.integer | np.floating):
        return value
    if isinstance(value, Path):
        return str(value)
    try:
        array = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"setting {name!r}: cannot store {type(value).__name__}") from exc
    if array.dtype.kind not in "biuf":
        if array.dtype.kind == "U":
            return array.astype(h5py.string_dtype())
        raise InputError(f"setting {name!r}: cannot store a value of type {type(value).__name__}")
    return array


def write_attributes(group: h5py.Group, values: Mapping[str, object] | None) -> None:
    """Write ``values`` as attributes of ``group`` and their units on ``group/units``.

    A value may be a plain value or a ``(value, unit)`` pair whose second item is a str.
    """
    units_group = group.create_group("units")
    for name, raw in (values or {}).items():
        unit = unit_for(name)
        value = raw
        if isinstance(raw, tuple) and len(raw) == 2 and isinstance(raw[1], str):
            value, unit = raw
        if value is None:
            continue
        group.attrs[name] = attribute_value(name, value)
        units_group.attrs[name] = unit


def read_attributes(
    group: h5py.Group | None, units_group: h5py.Group | None
) -> tuple[dict[str, Any], dict[str, str]]:
    """Return (values, units) from a group written by :func:`write_attributes`.

    ``units_group`` is its ``units`` subgroup (None where it has none), opened by the
    caller (:func:`holoview.acquire.hdf5_members.open_member`).
    """
    if group is None:
        return {}, {}
    values = {name: plain_value(value) for name, value in group.attrs.items()}
    units = {}
    if units_group is not None:
        units = {name: str(plain_value(unit)) for name, unit in units_group.attrs.items()}
    return values, units


def plain_value(value: Any) -> Any:
    """Return an attribute value as a Python scalar, str, or numpy array."""
    if isinstance(value, bytes):
        return value.decode("utf-8")
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray) and value.dtype.kind == "O":
        return [plain_value(v) for v in value.tolist()]
    return value
