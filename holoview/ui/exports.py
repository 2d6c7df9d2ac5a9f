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
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np
import tifffile
from PyQt6.QtWidgets import QFileDialog, QWidget

from holoview.atomic import atomic_path, fit_name, name_max
from holoview.errors import HoloviewError, InputError, OutputError, os_error_text
from holoview.paths import confined_name
from holoview.ui.legends import FUSED

if TYPE_CHECKING:
    from holoview.live.maps_pipeline import LiveResult
    from holoview.ui.status_bar import LiveStatusBar
    from holoview.ui.surface_view import SurfaceView

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


class WindowExports:
    """The main window's exports: its maps (TIFF or NPY), itself (PNG), a snapshot of both."""

    _maps_result: LiveResult | None
    surface: SurfaceView
    status: LiveStatusBar
    show_message: Callable[[str], None]

    def _window(self) -> QWidget:
        return cast(QWidget, self)

    def current_maps(self) -> tuple[dict[str, np.ndarray], str]:
        """Return the maps shown (metres or radians) and their unit: those of the newest
        result drawn (a restart's reference frame, zeros, is not)."""
        result = self._maps_result
        if result is None:
            return {}, "m"
        if self.surface.mode == "phase":
            return dict(result.phases_rad), "rad"
        maps = dict(result.heights_m)
        if result.fused_m is not None:
            maps[FUSED] = result.fused_m
        return maps, "m"

    def export_maps_to(self, path: Path) -> list[Path]:
        """Write the current maps next to ``path`` (``.tif`` or ``.npy``)."""
        maps, unit = self.current_maps()
        return export_maps(maps, path, unit)

    def export_maps_dialog(self) -> None:
        """Ask for a file name and export the current maps."""
        path, _ = QFileDialog.getSaveFileName(
            self._window(),
            "Export maps",
            "maps.tif",
            "TIFF (*.tif);;NumPy (*.npy)",
        )
        if path:
            try:
                written = self.export_maps_to(Path(path))
            except HoloviewError as exc:
                self.show_message(str(exc))
                return
            self.status.showMessage(f"wrote {len(written)} maps", 4000)

    def save_png_dialog(self) -> None:
        """Ask for a file name and save the window as PNG."""
        path, _ = QFileDialog.getSaveFileName(
            self._window(),
            "Save window",
            "holoview.png",
            "PNG (*.png)",
        )
        if path:
            try:
                export_window_png(self._window(), Path(path))
            except HoloviewError as exc:
                self.show_message(str(exc))

    def snapshot(self, folder: Path | None = None) -> list[Path]:
        """Save the window (PNG) and the current maps (NPY) with a time stamp in the name."""
        folder = folder or Path.cwd()
        stem = folder / time.strftime("holoview-%Y%m%d-%H%M%S")
        try:
            written = [export_window_png(self._window(), stem.with_suffix(".png"))]
            maps, unit = self.current_maps()
            if maps:
                written += export_maps(maps, stem.with_suffix(".npy"), unit)
        except HoloviewError as exc:
            self.show_message(str(exc))
            return []
        self.status.showMessage(f"snapshot: {len(written)} files in {folder}", 4000)
        return written
