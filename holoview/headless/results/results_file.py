"""``results.h5`` while a run writes it: :class:`ResultsFile`.

Format ``holoview-results`` 2.1, netCDF-4 in the CF manner: its layout is documented in
:mod:`holoview.headless.results.results_layout`, which writes its series and peaks
tables and the maps' dimensions; :class:`ResultsFile` writes the maps as they come
(checking the room on the disk a batch at a time) and the rest at the end. A failed
write is an :class:`~holoview.errors.OutputError` naming the file.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import logging
import math
import os
import uuid
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from holoview import __version__
from holoview.acquire.durability import CLOSE_MARGIN_BYTES, DiskReserve, free_bytes
from holoview.engine.map_step import pixel_step
from holoview.errors import OutputError
from holoview.headless.analysis import Analysis
from holoview.headless.inputs import Optics
from holoview.headless.results import cf
from holoview.headless.results.outputs import radius_setting, writing
from holoview.headless.results.results_layout import (
    RESULTS_FORMAT,
    RESULTS_VERSION,
    map_dimensions,
    write_peaks,
    write_trends,
)
from holoview.headless.run_data import RunData
from holoview.headless.settings import ProcessSettings
from holoview.processing.peaks.matched import Window

logger = logging.getLogger(__name__)

#: Bytes kept free beside ``results.h5`` while it is written: the room to close it cleanly
#: when the disk fills (its index, a few kilobytes).
CLOSE_RESERVE_BYTES = 1 << 20

#: Frames of maps whose room on the disk is checked at once ...
MAP_BATCH = 16

#: ... while they stay under this many bytes (maps on the frame's grid, 1024 x 1024 with
#: six peaks, are checked frame by frame).
MAP_BATCH_BYTES = 32 << 20

#: What each reference mode means, for the map attributes.
REFERENCE_DESCRIPTIONS = {
    "relative": "each frame against the previous one (the first frame is zero)",
    "absolute": "each frame against the first processed frame",
    "synthetic": "against a plane wave at the carrier (up to a global 2 pi)",
}


def _window_attributes(window: Window) -> dict[str, Any]:
    """A map's attributes saying the window it was demodulated with (its cut-off)."""
    return {
        "radius_cpp": window.radius,
        "window_taper": window.taper,
        "window_rule": window.rule,
        "window_bound_cpp": window.bound,
        "window_content_cpp": math.nan if window.content is None else window.content,
        "window_reason": window.reason,
    }


class ResultsFile:
    """``results.h5`` while a run writes it: maps frame by frame, the rest at the end.

    Every failed write (a full disk) is an :class:`~holoview.errors.OutputError`.

    Parameters
    ----------
    path : Path
        The file to create (replaced if it exists; a run gives a temporary name).
    labels : sequence of str
        The selected peaks' labels during the run (auto mode renames them at the end).
    n_frames : int
        Frames to be processed.
    box_shape : tuple of int
        Shape of the maps.
    maps : bool
        Create the map datasets.
    """

    def __init__(
        self,
        path: Path,
        *,
        labels: Sequence[str],
        n_frames: int,
        box_shape: tuple[int, int],
        maps: bool,
    ) -> None:
        self.path = path
        self._broken = False  # a write failed: the file is dropped, its data need not reach it
        self._reserve = DiskReserve(path, CLOSE_RESERVE_BYTES, name="results.h5")
        try:
            with writing("results.h5"):
                self._file = h5py.File(path, "w", libver=("v110", "latest"))
        except OutputError:
            self._reserve.release()
            raise
        self._labels = list(labels)
        self._maps: list[h5py.Dataset] = []
        if maps:
            with self._guard():
                group = self._file.create_group("maps")
                self._maps = [
                    self._map_dataset(group, f"_peak{j}", n_frames, box_shape)
                    for j in range(len(self._labels))
                ]
        # each frame's map is one HDF5 chunk, written as it is (write_direct_chunk: no
        # datatype conversion or selection, half the CPU time of a dataset write); the
        # disk's room is checked once a batch of frames
        frame_bytes = 4 * box_shape[0] * box_shape[1] * (len(self._labels) + 1)
        self._batch = max(1, min(MAP_BATCH, MAP_BATCH_BYTES // frame_bytes))
        self._block = -1
        self._n_frames, self._box_shape = n_frames, box_shape
        self._map_bytes = int(np.prod(box_shape)) * np.dtype(np.float32).itemsize
        self._fused_made = False  # /maps/fused is made with the first fused map

    def _write_chunk(self, dataset: h5py.Dataset, position: int, values: np.ndarray) -> None:
        array = np.ascontiguousarray(values, dtype=np.float32)
        if array.shape != self._box_shape:
            raise ValueError(f"a map of shape {array.shape}, the file holds {self._box_shape}")
        dataset.id.write_direct_chunk((position, 0, 0), array)

    @staticmethod
    def _map_dataset(
        group: h5py.Group, name: str, n_frames: int, box_shape: tuple[int, int]
    ) -> h5py.Dataset:
        return group.create_dataset(
            name,
            shape=(n_frames, *box_shape),
            maxshape=(None, *box_shape),
            dtype=np.float32,
            chunks=(1, *box_shape),
            fillvalue=np.float32(np.nan),
        )

    def write_maps(
        self, position: int, maps: Sequence[np.ndarray], fused: np.ndarray | None
    ) -> None:
        """Store the ``position``-th processed frame's maps (one per peak) and fused map.

        The first fused map creates ``/maps/fused``; a frame given none keeps NaN there.
        """
        if not self._maps:
            return
        if fused is not None and not self._fused_made:
            self._fused_made = True
            with self._guard():
                self._maps.append(
                    self._map_dataset(self._file["maps"], "fused", self._n_frames, self._box_shape)
                )
        block = position // self._batch
        if block != self._block:
            self._block = block
            self._ensure_room(self._batch * len(self._maps) * self._map_bytes)
        with self._guard():
            for dataset, values in zip(self._maps, maps, strict=False):
                self._write_chunk(dataset, position, values)
            if fused is not None:
                self._write_chunk(self._maps[-1], position, fused)

    def finish(
        self,
        *,
        data: RunData,
        analysis: Analysis,
        optics: Optics,
        settings: ProcessSettings,
        input_path: str,
        frame_shape: tuple[int, int],
    ) -> None:
        """Write the series, the peaks table and the attributes; name the maps."""
        n, m = len(data.frames), len(analysis.peaks)
        self._ensure_room(n * (48 * m + 48))
        with self._guard():
            self._finish(
                data=data,
                analysis=analysis,
                optics=optics,
                settings=settings,
                input_path=input_path,
                frame_shape=frame_shape,
            )

    def _finish(
        self,
        *,
        data: RunData,
        analysis: Analysis,
        optics: Optics,
        settings: ProcessSettings,
        input_path: str,
        frame_shape: tuple[int, int],
    ) -> None:
        f = self._file
        if data.maps_dropped and self._maps:  # interrupted before any frame's maps
            del f["maps"]
            self._maps, self._block = [], -1
        for dataset in self._maps:
            dataset.resize(len(data.frames), axis=0)  # fewer after an interruption
        f.attrs.update(
            {
                "format": RESULTS_FORMAT,
                "format_version": RESULTS_VERSION,
                "Conventions": cf.CONVENTIONS,
                "uuid": str(uuid.uuid4()),
                "holoview_version": __version__,
                "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
                "input": input_path,
                "interrupted": cf.flag_attribute(data.interrupted),
                "wavelength_m": optics.wavelength_m or math.nan,
                "pixel_pitch_m": optics.pixel_pitch_m or math.nan,
                "n1": optics.n1,
                "n2": optics.n2 or math.nan,
                "reference": settings.reference,
                "window": settings.window,
                "radius": radius_setting(settings.radius),
                "unwrap": settings.unwrap,
            }
        )
        self._write_trends(data, analysis, settings)
        self._write_peaks(analysis, data)
        if self._maps:
            self._name_maps(
                data=data,
                analysis=analysis,
                optics=optics,
                settings=settings,
                frame_shape=frame_shape,
            )

    def _write_trends(self, data: RunData, analysis: Analysis, settings: ProcessSettings) -> None:
        write_trends(self._file.create_group("trends"), data, analysis, settings)

    def _write_peaks(self, analysis: Analysis, data: RunData) -> None:
        write_peaks(self._file.create_group("peaks"), analysis, data.windows)

    def _name_maps(
        self,
        *,
        data: RunData,
        analysis: Analysis,
        optics: Optics,
        settings: ProcessSettings,
        frame_shape: tuple[int, int],
    ) -> None:
        group = self._file["maps"]
        step = pixel_step(frame_shape, data.box_shape)
        # None is "the experiment's": prepare_run settles it before any frame is read
        assert settings.reference is not None, "the run's settings were not settled"
        common: dict[str, Any] = {
            "reference": settings.reference,
            "reference_description": (
                REFERENCE_DESCRIPTIONS[settings.reference]
                if settings.background is None
                else f"each frame against the background hologram {settings.background}"
            ),
            "frame_shape_px": list(frame_shape),
            "grid": settings.maps_grid,
            "pixel_step_px": list(step),
            "window": settings.window,
            "untrusted": "NaN",
        }
        if optics.pixel_pitch_m is not None:
            common["pixel_size_m"] = [
                step[0] * optics.pixel_pitch_m,
                step[1] * optics.pixel_pitch_m,
            ]
        for j, peak in enumerate(analysis.peaks):
            group.move(f"_peak{j}", peak.label)
            attrs = group[peak.label].attrs
            attrs.update(common)
            height = data.map_units[j] == "m"
            attrs.update(
                {
                    "label": peak.label,
                    "units": "m" if height else "rad",
                    "long_name": f"{'height' if height else 'phase'} change from {peak.label}",
                    "quantity": "delta_h" if height else "phase",
                    "alpha": peak.alpha or math.nan,
                    "carrier_cpp": list(peak.carrier),
                    **(_window_attributes(data.windows[j]) if data.windows else {}),
                }
            )
            if data.displacements:
                shift = data.displacements[j]
                attrs.update(
                    {
                        "displacement_px": list(shift.shift),
                        "displacement_stderr_px": list(shift.stderr),
                        "displacement_measured": cf.flag_attribute(shift.measured),
                    }
                )
        if "fused" in group:
            group["fused"].attrs.update(common)
            group["fused"].attrs.update(
                {
                    "label": "fused",
                    "units": "m",
                    "long_name": "height change fused from " + ", ".join(data.fused_labels),
                    "quantity": "delta_h",
                    "labels": ",".join(data.fused_labels),
                    "radius_cpp": [
                        data.windows[j].radius if data.windows else data.radius
                        for j, p in enumerate(analysis.peaks)
                        if p.label in data.fused_labels
                    ],
                    "grid_of": analysis.peaks[0].label,
                }
            )
        pitch = optics.pixel_pitch_m
        scales = map_dimensions(
            group,
            frames=data.frames,
            times=data.times,
            box_shape=data.box_shape,
            step_px=step,
            pixel_pitch_m=pitch,
        )
        for name in [p.label for p in analysis.peaks] + (["fused"] if "fused" in group else []):
            cf.attach(group[name], scales)
            group[name].attrs["coordinates"] = "frame"

    def _ensure_room(self, nbytes: int) -> None:
        """Raise OutputError, before HDF5 tries, when ``nbytes`` more would not fit.

        HDF5 meeting a full disk in the middle of a write can leave its objects unable
        to close (and h5py crashing at exit); a run's own results filling the disk are
        stopped here instead, cleanly.
        """
        free = free_bytes(self.path.parent)
        if free is not None and free < nbytes + CLOSE_MARGIN_BYTES:
            self._broken = True
            raise OutputError(
                f"cannot write results.h5: the disk is full ({free / 1e6:.1f} MB free, "
                f"{(nbytes + CLOSE_MARGIN_BYTES) / 1e6:.1f} MB needed)"
            )

    @contextlib.contextmanager
    def _guard(self) -> Iterator[None]:
        """:func:`_writing` for this file, remembering that a write failed."""
        try:
            with writing("results.h5"):
                yield
        except OutputError:
            self._broken = True
            raise

    def _drop_data(self) -> None:
        """Make room to close a file that failed: its data go, it is dropped anyway.

        Closing an HDF5 file whose cached chunks or index cannot be written fails, and
        h5py then crashes freeing its objects (a segmentation fault at exit). So every
        chunked dataset is emptied (its cached chunks are discarded, not written), the
        file's blocks are freed (it is truncated to nothing) and the reserve kept
        beside it is given back: the few kilobytes of index written at close then fit.
        """
        chunked: list[h5py.Dataset] = []
        self._file.visititems(
            lambda _, item: (
                chunked.append(item)
                if isinstance(item, h5py.Dataset) and item.chunks and item.maxshape[0] is None
                else None
            )
        )
        for dataset in chunked:
            try:
                dataset.resize(0, axis=0)
            except (OSError, RuntimeError):
                continue
        with contextlib.suppress(OSError):
            os.truncate(self.path, 0)
        self._reserve.release()

    def close(self) -> None:
        """Write the maps still buffered, flush and close the file (closed also on failure).

        When a write failed, nothing more is written: the data are dropped
        (:meth:`_drop_data`) and the file is closed, for the caller to remove.

        Raises
        ------
        OutputError
            The file could not be written completely.
        """
        if not self._file.id.valid:
            return
        try:
            if not self._broken:
                with self._guard():
                    self._file.flush()  # fails here, not inside close, when the disk is full
        finally:
            broken = self._broken
            if broken:
                self._drop_data()
            try:
                with writing("results.h5"):
                    self._file.close()
            except OutputError as exc:
                if not broken:
                    raise
                logger.debug("closing a failed results.h5: %s", exc)  # the first error counts
            finally:
                self._reserve.release()
