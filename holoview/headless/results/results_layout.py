"""The layout of ``results.h5``: a netCDF-4 file that xarray and netCDF tools read whole.

Format ``holoview-results`` 2.1 is HDF5 laid out in the netCDF-4/CF manner
(:mod:`holoview.headless.results.cf`): the axes of each group are HDF5 dimension scales, so
``xarray.open_dataset(path, group="maps", engine="h5netcdf")`` gives ``h(time, y, x)``
with its coordinates, and every numeric variable has ``units`` (UDUNITS spelling: ``m``,
``s``, ``rad``, ``m3``, ``m s-1``, ``count``, ``1``) and a ``long_name``; strings carry no
unit. Its types are those every netCDF-C 4.x reads (no HDF5 enum or compound):
booleans are int8 0/1 (variables with ``flag_values`` 0, 1, ``flag_meanings`` ``false
true`` and xarray's ``dtype`` ``bool``, which xarray reads as booleans; the attributes
:data:`BOOLEAN_ATTRIBUTES` plain int8), the complex carrier value is two float32
variables, ``carrier_value_real`` and ``carrier_value_imag``.

Earlier formats are still read by :mod:`holoview.headless.results.results_data`, into
the same Datasets: 2.0 (booleans as h5py's enum, ``carrier_value`` complex64, which
netCDF-C before 4.10 drops without a word) and 1.0 (no dimension scales,
``/trends/time_s`` instead of ``time``, a ``unit`` attribute instead of ``units``).

Root attributes
    ``format``, ``format_version``, ``Conventions`` (``CF-1.11``), ``uuid``,
    ``holoview_version``, ``created_utc``, ``input``, ``interrupted`` (0 or 1: the run
    was stopped, the frames done only), and the parameters (``wavelength_m``, ``n1``,
    ``n2``, ``pixel_pitch_m``, ``reference``, ``window``, ``radius``: ``"matched"``,
    ``"bound"`` or the radius given in cycles/pixel, ``unwrap``).
``/trends``
    Dimensions ``time`` (N,: s from the first processed frame) and ``label`` (M,: the
    peaks). ``frame`` (time: the input's frame index, a coordinate); ``alpha``
    (label); ``mean_phase_rad``, ``mean_height_m``, ``carrier_value_real`` and
    ``carrier_value_imag`` (the complex carrier value's parts, camera counts),
    ``phase_noise_rad`` (the maps' per-pixel noise where a frame was demodulated), each
    (time, label); ``fused_height_m``, ``fused_spread_m``, with ``--area``
    ``fused_volume_m3``, and with the joint estimate ``vibration_rad`` (the
    reference-arm phase), ``ambiguity_margin`` (noise standard deviations) and
    ``ambiguity_flagged`` (a boolean), each (time).
``/peaks``
    Dimensions ``label`` and ``component`` (``fx``, ``fy``). ``carrier_cpp`` (label,
    component; cycles/pixel on the twin whose phase grows with h), and per label
    ``alpha``, ``amplitude``, ``snr``, ``rate_m_per_s``, ``rate_stderr_m_per_s``,
    ``used_in_fused`` (a boolean), ``flags`` (comma-separated), and the window each peak was
    demodulated with: ``radius_cpp`` (its cut-off, cycles/pixel), ``window_taper``,
    ``window_rule`` (``matched``, ``bound`` or ``given``) and ``window_reason``.
``/maps`` (with ``process --maps``; none in a run interrupted before any frame's maps)
    Dimensions ``time`` (s), ``y`` and ``x``: positions of the map pixels' centres in
    m on the object side (map pixel ``(p, q)`` is centred on frame position
    ``(p * pixel_step_px[0], q * pixel_step_px[1])`` in pixel pitches, frame pixel
    ``(0, 0)``'s centre at the origin, y down the rows, x along the columns); without a
    pixel pitch, in frame pixels (``units`` ``1``). ``frame`` (time) is a coordinate.
    ``<label>`` per peak and ``fused`` (time, y, x): float32, m, at the demodulation
    box's resolution, or on the frame's pixels with ``--maps-grid frame``
    (``pixel_step_px`` 1), NaN where not trusted; attributes ``units``, ``long_name``,
    ``quantity`` (``delta_h``), ``reference`` and ``reference_description``, ``label``,
    ``alpha``, ``carrier_cpp``, ``frame_shape_px``, ``grid`` (``box`` or ``frame``),
    ``pixel_step_px``, ``pixel_size_m``
    (when the pixel pitch is known), ``window``, per peak the window it was demodulated
    with (``radius_cpp``, its cut-off in cycles/pixel; ``window_taper``,
    ``window_rule``, ``window_bound_cpp``, ``window_content_cpp`` where matched,
    ``window_reason``) and its measured shift against the first peak
    (``displacement_px``, ``displacement_stderr_px``, ``displacement_measured`` 0 or 1; the
    maps are not moved, their coordinates are the camera's), and for ``fused`` its
    ``labels``, their radii ``radius_cpp`` (one per label) and ``grid_of`` (the maps
    are moved onto that peak's grid before fusing). The maps, the fused one included,
    are the maps step's (:class:`holoview.engine.map_step.MapStep`), frame by frame, as
    the live view shows them: the fused map takes the peaks of the fused depth known
    before the frames (the joint estimate's, else every peak with alpha), weighed by
    each map's expected error (its noise and what its window cuts), leaving out at each
    frame a peak whose mean phase stepped past 0.8 pi since the frame before. A peak
    without alpha keeps its phase map (``units`` ``rad``, ``quantity`` ``phase``).

Written by :class:`holoview.headless.results.results_file.ResultsFile` (the maps as they
come, then :func:`write_trends`, :func:`write_peaks` and, for the maps,
:func:`map_dimensions`);
read as xarray Datasets by :mod:`holoview.headless.results.results_data`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import h5py
import numpy as np

from holoview.headless.analysis import Analysis
from holoview.headless.results import cf
from holoview.headless.run_data import RunData
from holoview.headless.settings import ProcessSettings
from holoview.processing.peaks.matched import Window

#: Format name and version of ``results.h5``.
RESULTS_FORMAT = "holoview-results"
RESULTS_VERSION = "2.1"

#: Attributes holding a boolean as int8 0/1: the root's and each peak map's.
BOOLEAN_ATTRIBUTES = ("interrupted", "displacement_measured")

#: The ``long_name`` of the time and label dimensions.
TIME_NAME = "time since the first processed frame"
LABEL_NAME = "peak label"


def map_axis(count: int, step_px: float, pixel_pitch_m: float | None) -> np.ndarray:
    """Positions of a map axis's pixel centres: m with a pixel pitch, else frame pixels.

    Map pixel ``p`` is centred on frame position ``p * step_px`` (frame pixel ``i`` is
    centred on ``i``; the origin is frame pixel (0, 0)'s centre).

    Examples
    --------
    >>> map_axis(4, 2.0, 5e-6)
    array([0.e+00, 1.e-05, 2.e-05, 3.e-05])
    """
    positions = np.arange(count, dtype=np.float64) * step_px
    return positions if pixel_pitch_m is None else positions * pixel_pitch_m


def map_dimensions(
    group: h5py.Group,
    *,
    frames: np.ndarray,
    times: np.ndarray,
    box_shape: tuple[int, int],
    step_px: tuple[float, float],
    pixel_pitch_m: float | None,
) -> list[h5py.Dataset]:
    """Create ``time``, ``y`` and ``x`` (and ``frame`` on time) in ``group``; return the scales.

    ``y`` and ``x`` are in m on the object side, or in frame pixels (``units`` ``1``)
    without a pixel pitch (:func:`map_axis`).
    """
    # no axis "T": CF takes a T axis for a calendar time, "seconds since" a date (4.4)
    time = cf.dimension(group, "time", times, units="s", long_name=TIME_NAME)
    cf.variable(group, "frame", frames, ("time",), units="1", long_name="frame index in the input")
    scales = [time]
    for name, count, step in zip(("y", "x"), box_shape, step_px, strict=True):
        direction = "rows, down" if name == "y" else "columns, right"
        where = "object side, m" if pixel_pitch_m is not None else "frame pixels"
        scales.append(
            cf.dimension(
                group,
                name,
                map_axis(count, step, pixel_pitch_m),
                units="m" if pixel_pitch_m is not None else "1",
                long_name=f"{name} position of the map pixel's centre ({direction}; {where})",
                axis=name.upper(),
            )
        )
    return scales


def write_trends(
    group: h5py.Group, data: RunData, analysis: Analysis, settings: ProcessSettings
) -> None:
    """Write ``/trends`` (module docstring) into ``group``."""
    peaks = analysis.peaks
    cf.dimension(group, "time", data.times, units="s", long_name=TIME_NAME)
    cf.dimension(group, "label", [p.label for p in peaks], units=None, long_name=LABEL_NAME)
    by_frame, by_peak = ("time",), ("time", "label")
    series: dict[str, tuple[Any, tuple[str, ...], str, str]] = {
        "frame": (data.frames, by_frame, "1", "frame index in the input"),
        "alpha": (
            np.array([p.alpha or math.nan for p in peaks]),
            ("label",),
            "1",
            "height prefactor alpha of the peak (phase = 4 pi alpha h / wavelength)",
        ),
        "mean_phase_rad": (analysis.phases, by_peak, "rad", "mean phase change"),
        "mean_height_m": (analysis.heights, by_peak, "m", "mean height change"),
        "phase_noise_rad": (data.noise_rad, by_peak, "rad", "per-pixel phase noise of maps"),
    }
    if analysis.fused is not None:
        series["fused_height_m"] = (analysis.fused, by_frame, "m", "fused height change")
        if analysis.fused_spread is not None:
            series["fused_spread_m"] = (
                analysis.fused_spread,
                by_frame,
                "m",
                "spread of the peaks' heights about the fused height",
            )
        if settings.area_m2 is not None:
            series["fused_volume_m3"] = (
                analysis.fused * settings.area_m2,
                by_frame,
                "m3",
                "volume change over the basin area",
            )
    if analysis.margins is not None:
        series["ambiguity_margin"] = (
            analysis.margins,
            by_frame,
            "1",
            "joint estimate's ambiguity margin, noise standard deviations",
        )
    if analysis.vibration is not None:
        series["vibration_rad"] = (
            analysis.vibration,
            by_frame,
            "rad",
            "reference-arm phase (vibration)",
        )
    for name, (values, dims, units, long_name) in series.items():
        more = {"coordinates": "frame"} if dims[0] == "time" and name != "frame" else {}
        cf.variable(group, name, values, dims, units=units, long_name=long_name, **more)
    cf.complex_parts(
        group,
        "carrier_value",
        data.values.astype(np.complex64),
        by_peak,
        units="count",
        long_name="complex carrier value (demodulated amplitude and phase), camera counts",
        coordinates="frame",
    )
    if analysis.flagged is not None:
        cf.flags(
            group,
            "ambiguity_flagged",
            analysis.flagged,
            by_frame,
            long_name="frame whose joint estimate is ambiguous",
            coordinates="frame",
        )


def write_peaks(group: h5py.Group, analysis: Analysis, windows: Sequence[Window] = ()) -> None:
    """Write ``/peaks`` (module docstring) into ``group``; ``windows``: each peak's."""
    peaks = analysis.peaks
    cf.dimension(group, "label", [p.label for p in peaks], units=None, long_name=LABEL_NAME)
    cf.dimension(
        group,
        "component",
        ["fx", "fy"],
        units=None,
        long_name="carrier component: fx along the columns, fy along the rows",
    )
    cf.variable(
        group,
        "carrier_cpp",
        np.array([p.carrier for p in peaks], dtype=np.float64).reshape(-1, 2),
        ("label", "component"),
        units="1",
        long_name="carrier frequency on the twin whose phase grows with h, cycles/pixel",
    )
    for name, values, units, long_name in (
        ("alpha", [p.alpha for p in peaks], "1", "height prefactor alpha"),
        ("amplitude", [p.amplitude for p in peaks], "1", "peak amplitude |S(f)| / S(0)"),
        ("snr", [p.snr for p in peaks], "1", "peak signal-to-noise ratio"),
        ("rate_m_per_s", [p.rate for p in peaks], "m s-1", "fitted depth rate"),
        (
            "rate_stderr_m_per_s",
            [p.rate_stderr for p in peaks],
            "m s-1",
            "standard error of the rate",
        ),
    ):
        array = np.array([math.nan if v is None else v for v in values], dtype=np.float64)
        cf.variable(group, name, array, ("label",), units=units, long_name=long_name)
    cf.flags(
        group,
        "used_in_fused",
        [p.used_in_fused for p in peaks],
        ("label",),
        long_name="peak used in the fused height",
    )
    cf.variable(
        group,
        "flags",
        [",".join(p.flags) for p in peaks],
        ("label",),
        units=None,
        long_name="the peak's flags, comma-separated",
    )
    if not windows:
        return
    for name, numbers, long_name in (
        ("radius_cpp", [w.radius for w in windows], "window radius (cut-off), cycles/pixel"),
        ("window_taper", [w.taper for w in windows], "window's edge, fraction of the radius"),
    ):
        cf.variable(
            group,
            name,
            np.array(numbers, dtype=np.float64),
            ("label",),
            units="1",
            long_name=long_name,
        )
    for name, texts, long_name in (
        ("window_rule", [w.rule for w in windows], "how the radius was chosen"),
        ("window_reason", [w.reason for w in windows], "why this radius"),
    ):
        cf.variable(group, name, texts, ("label",), units=None, long_name=long_name)
