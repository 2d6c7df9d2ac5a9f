"""The text files a headless run writes: ``trends.csv`` and ``summary.json``.

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
    Written by :class:`~holoview.headless.results.results_file.ResultsFile`.

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
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from holoview import __version__
from holoview.engine.map_step import frame_shift
from holoview.errors import OutputError, os_error_text
from holoview.headless.analysis import Analysis, PeakOutcome
from holoview.headless.inputs import Optics
from holoview.headless.run_data import RunData
from holoview.headless.settings import ProcessSettings
from holoview.processing.series.frame_gaps import lost_between

logger = logging.getLogger(__name__)

#: The header of ``trends.csv``, exactly.
TRENDS_HEADER = ("frame", "time_s", "label", "alpha", "mean_phase_rad", "mean_height_m")

#: Format name and version of ``summary.json`` (``results.h5``'s: results_layout).
SUMMARY_FORMAT = "holoview-process-summary"
FORMAT_VERSION = "1.0"


@contextlib.contextmanager
def writing(name: str) -> Iterator[None]:
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
    with writing("trends.csv"), open(path, "w", newline="", encoding="utf-8") as f:
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
    ``frames`` as ``[start, stop]``, ``interrupted``, ``frames_lost`` (in gaps between
    them, by the frame intervals), and a recording's uuid, source, creation time);
    ``parameters`` (``wavelength_m``, ``pixel_pitch_m``, ``n1``, ``n2`` and where each
    came from, ``fps_hz`` (the camera's: the frame intervals, lost frames counted, over
    the duration), ``reference``, ``window``, ``radius`` (``"matched"``,
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
    intervals = int(np.sum(data.series.intervals[1:]))  # between the first and last frames
    lost = lost_between(data.series.intervals)[0]
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
            "frames_lost": lost,
        },
        "parameters": {
            "wavelength_m": optics.wavelength_m,
            "pixel_pitch_m": optics.pixel_pitch_m,
            "n1": optics.n1,
            "n2": optics.n2,
            "optics_from": dict(optics.sources),
            "fps_hz": intervals / duration if duration > 0 else None,
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


def write_summary_json(path: Path, document: dict[str, Any]) -> None:
    """Write ``summary.json`` (strict JSON: no NaN; OutputError on failure)."""
    with writing("summary.json"):
        path.write_text(json.dumps(document, indent=2, allow_nan=False) + "\n", encoding="utf-8")
