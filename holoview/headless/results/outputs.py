"""The files a headless run writes: ``trends.csv``, ``summary.json`` and ``results.h5``.

``trends.csv``
    Long format, one row per frame and peak, header
    ``frame,time_s,label,alpha,mean_phase_rad,mean_height_m``; then the fused estimate
    under the label ``fused`` (its ``alpha`` and ``mean_phase_rad`` empty). ``frame`` is
    the input's frame index, ``time_s`` from 0 at the first processed frame, phases
    (rad) and heights (m) relative to the first frame. An empty field is a value not
    known (a frame that could not be demodulated, a peak without alpha).
``summary.json``
    See :func:`summary_document`.
``results.h5``
    Format ``holoview-results`` 2.0, netCDF-4 in the CF manner: its layout is
    documented in :mod:`holoview.headless.results.results_layout`, which writes its series and
    peaks tables and the maps' dimensions; :class:`ResultsFile` writes the maps as they
    come and the rest at the end.

Each writer writes the path it is given: a run gives them temporary names and
renames the files when it completes (:mod:`holoview.headless.results.output_folder`). A
failed write is an :class:`~holoview.errors.OutputError` naming the file.
"""

from __future__ import annotations

import contextlib
import csv
import datetime as _dt
import json
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
from holoview.engine.map_step import frame_shift, pixel_step
from holoview.errors import OutputError, os_error_text
from holoview.headless.analysis import Analysis, PeakOutcome
from holoview.headless.inputs import Optics
from holoview.headless.results import cf
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

#: The header of ``trends.csv``, exactly.
TRENDS_HEADER = ("frame", "time_s", "label", "alpha", "mean_phase_rad", "mean_height_m")

#: Format name and version of ``summary.json`` (``results.h5``'s: results_layout).
SUMMARY_FORMAT = "holoview-process-summary"
FORMAT_VERSION = "1.0"

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


@contextlib.contextmanager
def _writing(name: str) -> Iterator[None]:
    """Turn a failed write (h5py raises RuntimeError for some) into an OutputError."""
    try:
        yield
    except (OSError, RuntimeError) as exc:
        raise OutputError(f"cannot write {name}: {os_error_text(exc)}") from exc


def _number(value: float | None, fmt: str = ".10g") -> str:
    if value is None or not math.isfinite(value):
        return ""
    return format(value, fmt)


def write_trends_csv(path: Path, data: RunData, analysis: Analysis) -> None:
    """Write ``trends.csv`` (module docstring), one frame at a time (OutputError on failure)."""
    with _writing("trends.csv"), open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(TRENDS_HEADER)
        for i, (frame, t) in enumerate(zip(data.frames, data.times, strict=True)):
            time_text = _number(float(t))
            for j, peak in enumerate(analysis.peaks):
                writer.writerow(
                    (
                        int(frame),
                        time_text,
                        peak.label,
                        _number(peak.alpha),
                        _number(float(analysis.phases[i, j])),
                        _number(float(analysis.heights[i, j]), ".9e"),
                    )
                )
            if analysis.fused is not None:
                fused = float(analysis.fused[i])
                writer.writerow((int(frame), time_text, "fused", "", "", _number(fused, ".9e")))


def _clean(value: Any) -> Any:
    """JSON-ready: NaN and infinities to None, numpy scalars to Python, tuples to lists."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def radius_setting(radius: float | str | None) -> float | str:
    """The radius a run was asked for: ``"matched"`` (None), ``"bound"`` or the number."""
    return "matched" if radius is None else radius


def _peak_entry(peak: PeakOutcome) -> dict[str, Any]:
    return {
        "carrier": list(peak.carrier),
        "alpha": peak.alpha,
        "amplitude": peak.amplitude,
        "snr": peak.snr,
        "rate_m_per_s": peak.rate,
        "rate_stderr_m_per_s": peak.rate_stderr,
        "noise_m": peak.noise_m,
        "map_noise_rad": peak.map_noise_rad,
        "map_noise_m": peak.map_noise_m,
        "used_in_fused": peak.used_in_fused,
        "flags": list(peak.flags),
        **_lattice_entry(peak),
    }


def _lattice_entry(peak: PeakOutcome) -> dict[str, Any]:
    """``lattice`` ([fb1, rf] or null), ``residual_bins``, ``kind``, ``coupling``."""
    p = peak.lattice
    return {
        "lattice": None if p is None or p.lattice is None else list(p.lattice),
        "residual_bins": None if p is None else p.residual_bins,
        "kind": None if p is None else str(p.kind),
        "coupling": None if p is None else p.coupling,
    }


def _displacement_entry(
    data: RunData, j: int, frame_shape: tuple[int, int], pixel_pitch_m: float | None
) -> dict[str, Any] | None:
    """A peak's measured shift against the first peak, in map and frame pixels (and m)."""
    if not data.displacements:
        return None
    shift = data.displacements[j]
    frame_px = list(frame_shift(shift, frame_shape, data.box_shape))
    return {
        "measured": shift.measured,
        "shift_map_px": list(shift.shift),
        "stderr_map_px": list(shift.stderr),
        "shift_frame_px": frame_px,
        "shift_m": None if pixel_pitch_m is None else [v * pixel_pitch_m for v in frame_px],
    }


def summary_document(
    *,
    input_info: dict[str, Any],
    optics: Optics,
    settings: ProcessSettings,
    selection_mode: str,
    data: RunData,
    analysis: Analysis,
    frame_shape: tuple[int, int],
) -> dict[str, Any]:
    """Return ``summary.json``'s content.

    Keys: ``format``, ``format_version``, ``holoview_version``, ``created_utc``;
    ``input`` (path, kind, frames in the file, frame shape, dtype, the processed
    ``frames`` as ``[start, stop]``, ``interrupted``, and a recording's uuid, source,
    creation time);
    ``parameters`` (``wavelength_m``, ``pixel_pitch_m``, ``n1``, ``n2`` and where each
    came from, ``fps_hz`` (mean), ``reference``, ``window``, ``radius`` (``"matched"``,
    ``"bound"`` or the number given, cycles/pixel), ``unwrap``, ``maps``, ``maps_grid``,
    ``area_m2``,
    ``peaks_from``); ``peaks`` (per label: ``window``, the one it was demodulated
    with: ``radius_cpp``, ``kind``, ``taper``, ``rule``, ``bound_cpp``,
    ``content_cpp`` and ``reason``;
    ``carrier`` [fx, fy] cycles/pixel, ``alpha``, ``amplitude``, ``snr``,
    ``rate_m_per_s``, ``rate_stderr_m_per_s``, ``noise_m`` (of the depth series),
    ``map_noise_rad`` and ``map_noise_m`` (per map pixel, median), ``used_in_fused``,
    ``flags``, ``displacement``: its measured shift ``(dy, dx)`` against the first
    peak, ``shift_map_px`` and ``stderr_map_px`` in map pixels, ``shift_frame_px``,
    ``shift_m`` with a pixel pitch, ``measured`` (False: too uncertain, not applied;
    null with one peak)); ``fused`` (``rate_m_per_s``, ``rate_stderr_m_per_s``, ``labels``, with
    an area ``volume_rate_m3_per_s`` and its ``volume_rate_stderr_m3_per_s``; None
    when nothing was fused); ``pca`` (``confidence``, ``reference``, ``prefactors``,
    ``explained``, ``n_samples``; None when not computed); ``frames`` (``processed``,
    counts of ``nonfinite``, ``no_signal``, ``saturated`` frames); ``timing``
    (seconds in all, reading, demodulating and of it the maps, frames per second,
    ``workers``, and for a parallel run ``worker_seconds`` and ``parent_seconds``);
    ``notes``.
    Values not known are null.
    """
    n = len(data.frames)
    duration = float(data.times[-1] - data.times[0]) if n > 1 else 0.0
    fused = None
    if analysis.fused is not None:
        fused = {
            "rate_m_per_s": analysis.fit.rate if analysis.fit else None,
            "rate_stderr_m_per_s": analysis.fit.stderr if analysis.fit else None,
            "labels": [p.label for p in analysis.peaks if p.used_in_fused],
        }
        if settings.area_m2 is not None and analysis.fit is not None:
            fused["volume_rate_m3_per_s"] = analysis.fit.rate * settings.area_m2
            fused["volume_rate_stderr_m3_per_s"] = analysis.fit.stderr * settings.area_m2
        fused["joint"] = analysis.margins is not None
        if analysis.margins is not None and analysis.flagged is not None:
            finite = analysis.margins[np.isfinite(analysis.margins)]
            fused["frames_flagged"] = int(analysis.flagged.sum())
            fused["smallest_margin"] = float(finite.min()) if finite.size else None
        if analysis.vibration is not None and np.isfinite(analysis.vibration).any():
            fused["vibration_rms_rad"] = float(np.nanstd(analysis.vibration))
    document = {
        "format": SUMMARY_FORMAT,
        "format_version": FORMAT_VERSION,
        "holoview_version": __version__,
        "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "input": {
            **input_info,
            "frames": [int(data.frames[0]), int(data.frames[-1]) + 1],
            "interrupted": data.interrupted,
        },
        "parameters": {
            "wavelength_m": optics.wavelength_m,
            "pixel_pitch_m": optics.pixel_pitch_m,
            "n1": optics.n1,
            "n2": optics.n2,
            "optics_from": dict(optics.sources),
            "fps_hz": (n - 1) / duration if duration > 0 else None,
            "reference": settings.reference,
            "background": settings.background,
            "window": settings.window,
            "radius": radius_setting(settings.radius),
            "unwrap": settings.unwrap,
            "maps": settings.maps,
            "maps_grid": settings.maps_grid,
            "area_m2": settings.area_m2,
            "peaks_from": selection_mode,
        },
        "peaks": {
            p.label: {
                **_peak_entry(p),
                "window": data.windows[j].to_dict() if data.windows else None,
                "displacement": _displacement_entry(data, j, frame_shape, optics.pixel_pitch_m),
            }
            for j, p in enumerate(analysis.peaks)
        },
        "fused": fused,
        "pca": analysis.pca,
        "frames": {"processed": n, **data.frame_flags},
        "timing": {
            "seconds": data.wall_seconds,
            "read_seconds": data.read_seconds,
            "demodulate_seconds": data.demod_seconds,
            "frames_per_second": n / data.wall_seconds if data.wall_seconds > 0 else None,
            "maps_seconds": data.maps_seconds,
            "workers": data.workers,
            "worker_seconds": data.worker_seconds,
            "parent_seconds": data.parent_seconds,
        },
        "notes": list(analysis.notes),
    }
    cleaned: dict[str, Any] = _clean(document)  # a dict stays a dict
    return cleaned


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


def write_summary_json(path: Path, document: dict[str, Any]) -> None:
    """Write ``summary.json`` (strict JSON: no NaN; OutputError on failure)."""
    with _writing("summary.json"):
        path.write_text(json.dumps(document, indent=2, allow_nan=False) + "\n", encoding="utf-8")


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
            with _writing("results.h5"):
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
                "interrupted": data.interrupted,
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
                        "displacement_measured": shift.measured,
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
            with _writing("results.h5"):
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
                with _writing("results.h5"):
                    self._file.close()
            except OutputError as exc:
                if not broken:
                    raise
                logger.debug("closing a failed results.h5: %s", exc)  # the first error counts
            finally:
                self._reserve.release()
