"""Save what is on screen: the current maps (TIFF or NPY) and the window (PNG).

Maps are written as float32 in metres (heights) or radians (phases), one file per
map, named ``STEM_LABEL.tif`` / ``STEM_LABEL.npy`` (the label made a safe name by
:func:`holoview.paths.confined_name`, the whole shortened with a hash where it would be
too long a file name); TIFF files carry the unit in their description. Every file is
written under a temporary name and renamed when complete (:mod:`holoview.atomic`): a
full disk leaves the files that were there.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import tifffile
from PyQt6.QtWidgets import QWidget

from holoview.atomic import atomic_path, fit_name, name_max
from holoview.errors import InputError, OutputError, os_error_text
from holoview.paths import confined_name

logger = logging.getLogger(__name__)

MAP_SUFFIXES = (".tif", ".tiff", ".npy")


def export_maps(maps: Mapping[str, np.ndarray], path: Path, unit: str) -> list[Path]:
    """Write each map to ``PATH-STEM_NAME.SUFFIX``; return the files written.

    Parameters
    ----------
    maps : mapping of str to ndarray
        Maps by name (``RB1``, ..., ``fused``).
    path : Path
        Where to write; its suffix (``.tif``, ``.tiff`` or ``.npy``) picks the format.
    unit : str
        The unit of the values (``m`` or ``rad``), recorded in TIFF descriptions.
    """
    suffix = path.suffix.lower()
    if suffix not in MAP_SUFFIXES:
        raise InputError(f"cannot export maps as {suffix or 'no suffix'}: use .tif or .npy")
    if not maps:
        raise InputError("no maps to export yet: label a peak first")
    if not path.parent.is_dir():
        raise InputError(f"folder {path.parent} does not exist")
    written = []
    for name, data in maps.items():
        stem = f"{path.stem}_{confined_name(name, fallback='map')}"
        target = path.with_name(fit_name(stem, name_max(path.parent) - len(suffix)) + suffix)
        array = np.asarray(data, dtype=np.float32)
        try:
            with atomic_path(target) as partial:
                if suffix == ".npy":
                    np.save(partial, array)
                else:
                    tifffile.imwrite(partial, array, description=f"holoview {name} in {unit}")
        except OSError as exc:
            raise OutputError(f"cannot write {target}: {os_error_text(exc)}") from exc
        written.append(target)
    logger.info("exported %d maps next to %s", len(written), path)
    return written


def export_window_png(widget: QWidget, path: Path) -> Path:
    """Save a picture of ``widget`` to ``path`` (PNG); return the path."""
    if path.suffix.lower() != ".png":
        path = path.with_suffix(".png")
    with atomic_path(path) as partial:
        if not widget.grab().save(str(partial), "PNG"):
            raise OutputError(f"cannot write {path}")
    return path
