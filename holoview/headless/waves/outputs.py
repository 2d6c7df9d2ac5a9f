"""``holoview waves``' files: ``waves.h5``, ``waves.json`` and the figures, written atomically.

``waves.h5`` (format ``holoview-waves`` 1.0), every dataset with a ``unit`` attribute,
coordinates attached as HDF5 dimension scales (xarray reads each group with
``engine="h5netcdf"``):

- root attributes: ``format``, ``format_version``, ``uuid``, ``holoview_version``,
  ``created_utc``, ``input``, ``label``, ``sign_convention``, ``frames``, ``gaps``,
  ``lost_frames``, ``frame_interval_s``, ``time_origin_s`` (the input's time of the first
  frame analysed; every time here is from it), ``pixel_size_m``, ``k_cut_rad_per_m``.
- ``/omega_k``: ``power`` (f, ky, kx) float32 m^2 Hz^-1 (rad/m)^-2 with ``frequency``
  (Hz), ``ky`` and ``kx`` (rad/m); attributes ``segments``, ``relative_stderr``.
- ``/energy``: ``E_k`` (m^2 per rad/m) on ``k`` (rad/m), ``E_omega`` (m^2 s/rad) on
  ``omega`` (rad/s).
- ``/dispersion`` (with a fit): attributes of :meth:`DispersionFit.as_dict`; the ridge
  ``ridge_kx``, ``ridge_ky`` (rad/m), ``ridge_omega`` (rad/s) on ``cell``.
- ``/azimuthal`` (with a centre): ``power`` (m, f) m^2/Hz on ``m`` and ``frequency``;
  ``radius`` (m); attributes ``centre_m``, ``centre_method``; ``tone_frequency`` (Hz),
  ``tone_m`` and ``profile_real``, ``profile_imag`` (tone, radius; m): the measured
  ``A_m(r)``.
- ``/partial_waves``: one row per fit: ``m``, ``frequency_hz`` (and stderr),
  ``wavenumber_rad_per_m`` (and stderr), ``incoming_real_m``, ``incoming_imag_m``,
  ``outgoing_real_m``, ``outgoing_imag_m``, the standard errors of their moduli
  (``incoming_stderr_m``, ``outgoing_stderr_m``) and of their phases
  (``*_phase_stderr_rad``: with k and the frequency fitted, a phase is known less well
  than a modulus), ``incoming_over_outgoing`` and its stderr.
- ``/ringdown``: attributes of :meth:`Ringdown.as_dict`; ``time`` (s), ``series_real``,
  ``series_imag``, ``model_real``, ``model_imag`` (the combined rings, arbitrary scale).
- ``/lockin``: ``amplitude``, ``amplitude_stderr`` (harmonic, y, x; m), ``phase``,
  ``phase_stderr`` (rad) on ``harmonic``, ``y``, ``x`` (m); attribute ``frequency_hz``.
- ``/filtered`` (with a band): ``height`` (time, y, x) float32 m on ``time`` (s), ``y``,
  ``x``; the band in the attributes, and in time the width of its edges
  (``transition_hz``).

``waves.json`` (format ``holoview-waves-summary`` 1.0): the input, the clock, every value
with its standard error and unit (:func:`_summary_values`),
``dispersion_problem`` (why a dispersion fit asked for was not made, else null), the
notes, the figures and the timing.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import math
import time
import uuid
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from holoview import __version__
from holoview.errors import InputError, OutputError, os_error_text
from holoview.headless.results.output_folder import OutputFolder
from holoview.headless.waves.analysis import WaveOptions, WaveResults, analyse_waves
from holoview.headless.waves.figures import FIGURES, draw_figures
from holoview.headless.waves.maps import WaveMaps, open_wave_maps, results_path
from holoview.processing.waves.filters import band_filter, block_for, transition_width
from holoview.processing.waves.omega_k import SIGN_CONVENTION

logger = logging.getLogger(__name__)

__all__ = ["WAVES_H5", "WAVES_JSON", "WavesOutcome", "run_waves"]

WAVES_H5 = "waves.h5"
WAVES_JSON = "waves.json"
FORMAT = "holoview-waves"
SUMMARY_FORMAT = "holoview-waves-summary"
FORMAT_VERSION = "1.0"


def _scale(group: h5py.Group, name: str, values: np.ndarray, unit: str) -> h5py.Dataset:
    dataset = group.create_dataset(name, data=values)
    dataset.attrs["unit"] = unit
    dataset.make_scale(name)
    return dataset


def _data(
    group: h5py.Group,
    name: str,
    values: np.ndarray,
    unit: str,
    scales: tuple[h5py.Dataset, ...] = (),
) -> h5py.Dataset:
    dataset = group.create_dataset(name, data=values)
    dataset.attrs["unit"] = unit
    for axis, scale in enumerate(scales):
        dataset.dims[axis].attach_scale(scale)
    return dataset


def _attrs(target: h5py.Group, values: dict[str, Any]) -> None:
    for key, value in values.items():
        if value is None:
            continue
        if isinstance(value, list) and all(isinstance(v, str) for v in value):
            target.attrs[key] = ",".join(value)  # lists of names: comma-separated
        elif isinstance(value, list):
            target.attrs[key] = np.asarray(value, dtype=np.float64)
        else:
            target.attrs[key] = value


def _write_h5(path: Path, results: WaveResults, maps: WaveMaps, options: WaveOptions) -> None:
    spectrum = results.spectrum
    with h5py.File(path, "w", libver=("v110", "latest")) as f:
        _attrs(
            f,
            {
                "format": FORMAT,
                "format_version": FORMAT_VERSION,
                "uuid": str(uuid.uuid4()),
                "holoview_version": __version__,
                "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
                "input": str(maps.path),
                "label": maps.label,
                "sign_convention": SIGN_CONVENTION,
                "frames": maps.frames,
                "gaps": maps.clock.gaps,
                "lost_frames": maps.clock.lost,
                "frame_interval_s": maps.clock.interval,
                "time_origin_s": maps.time_origin,
                "pixel_size_m": list(maps.pixel_size),
                "k_cut_rad_per_m": maps.k_cut,
            },
        )
        group = f.create_group("omega_k")
        scales = (
            _scale(group, "frequency", spectrum.frequency, "Hz"),
            _scale(group, "ky", spectrum.ky, "rad/m"),
            _scale(group, "kx", spectrum.kx, "rad/m"),
        )
        _data(group, "power", spectrum.power, "m^2 Hz^-1 (rad/m)^-2", scales)
        _attrs(
            group,
            {"segments": spectrum.segments, "relative_stderr": spectrum.relative_stderr},
        )
        group = f.create_group("energy")
        k, e_k = spectrum.energy_k()
        omega, e_omega = spectrum.energy_omega()
        _data(group, "E_k", e_k, "m^2 / (rad/m)", (_scale(group, "k", k, "rad/m"),))
        _data(group, "E_omega", e_omega, "m^2 s / rad", (_scale(group, "omega", omega, "rad/s"),))
        if results.dispersion is not None:
            fit = results.dispersion
            group = f.create_group("dispersion")
            _attrs(group, {k: v for k, v in fit.as_dict().items() if k != "correlation"})
            group.attrs["correlation"] = fit.correlation
            cell = _scale(group, "cell", np.arange(fit.ridge.omega.size), "1")
            _data(group, "ridge_kx", fit.ridge.kx, "rad/m", (cell,))
            _data(group, "ridge_ky", fit.ridge.ky, "rad/m", (cell,))
            _data(group, "ridge_omega", fit.ridge.omega, "rad/s", (cell,))
        if results.mf is not None and results.grid is not None:
            _write_azimuthal(f.create_group("azimuthal"), results)
        if results.partial_waves:
            _write_partial_waves(f.create_group("partial_waves"), results)
        if results.ringdown is not None:
            fit_r = results.ringdown
            group = f.create_group("ringdown")
            _attrs(group, fit_r.as_dict())
            time_scale = _scale(group, "time", fit_r.times, "s")
            for name, values in (("series", fit_r.series), ("model", fit_r.model)):
                _data(group, f"{name}_real", values.real, "1", (time_scale,))
                _data(group, f"{name}_imag", values.imag, "1", (time_scale,))
        if results.lockin is not None:
            _write_lockin(f.create_group("lockin"), results, maps)
        if options.band is not None:
            _write_filtered(f.create_group("filtered"), maps, options)


def _write_azimuthal(group: h5py.Group, results: WaveResults) -> None:
    mf, grid = results.mf, results.grid
    assert mf is not None and grid is not None
    scales = (_scale(group, "m", mf.m, "1"), _scale(group, "frequency", mf.frequency, "Hz"))
    _data(group, "power", mf.power, "m^2/Hz", scales)
    _scale(group, "radius", grid.radii, "m")
    _attrs(
        group,
        {
            "centre_m": list(results.centre or ()),
            "centre_stderr_m": list(results.centre_stderr),
            "centre_method": results.centre_method,
        },
    )
    if results.tones:
        tone = _scale(group, "tone", np.arange(len(results.tones)), "1")
        radius = group["radius"]
        _data(group, "tone_m", np.array([m for m, _, _ in results.tones]), "1", (tone,))
        _data(group, "tone_frequency", np.array([f for _, f, _ in results.tones]), "Hz", (tone,))
        profiles = np.array([p for _, _, p in results.tones])
        _data(group, "profile_real", profiles.real, "m", (tone, radius))
        _data(group, "profile_imag", profiles.imag, "m", (tone, radius))


def _write_partial_waves(group: h5py.Group, results: WaveResults) -> None:
    fits = results.partial_waves
    rows = _scale(group, "wave", np.arange(len(fits)), "1")
    columns: list[tuple[str, Any, str]] = [
        ("m", [p.m for p in fits], "1"),
        ("frequency_hz", [p.frequency for p in fits], "Hz"),
        ("frequency_stderr_hz", [p.frequency_stderr for p in fits], "Hz"),
        ("wavenumber_rad_per_m", [p.wavenumber for p in fits], "rad/m"),
        ("wavenumber_stderr_rad_per_m", [p.wavenumber_stderr for p in fits], "rad/m"),
        ("incoming_real_m", [p.incoming.real for p in fits], "m"),
        ("incoming_imag_m", [p.incoming.imag for p in fits], "m"),
        ("incoming_stderr_m", [p.incoming_stderr for p in fits], "m"),
        ("incoming_phase_stderr_rad", [p.incoming_phase_stderr for p in fits], "rad"),
        ("outgoing_real_m", [p.outgoing.real for p in fits], "m"),
        ("outgoing_imag_m", [p.outgoing.imag for p in fits], "m"),
        ("outgoing_stderr_m", [p.outgoing_stderr for p in fits], "m"),
        ("outgoing_phase_stderr_rad", [p.outgoing_phase_stderr for p in fits], "rad"),
        ("incoming_over_outgoing", [p.ratio for p in fits], "1"),
        ("incoming_over_outgoing_stderr", [p.ratio_stderr for p in fits], "1"),
    ]
    for name, values, unit in columns:
        _data(group, name, np.asarray(values), unit, (rows,))
    group.attrs["convention"] = (
        "A_m(r) = outgoing H_m^(1)(k r) + incoming H_m^(2)(k r), "
        "h = Re(A_m(r) exp(i (m theta - omega t)))"
    )


def _write_lockin(group: h5py.Group, results: WaveResults, maps: WaveMaps) -> None:
    lockin = results.lockin
    assert lockin is not None
    dy, dx = maps.pixel_size
    rows, cols = maps.shape
    scales = (
        _scale(group, "harmonic", np.array(lockin.harmonics), "1"),
        _scale(group, "y", np.arange(rows) * dy, "m"),
        _scale(group, "x", np.arange(cols) * dx, "m"),
    )
    _data(group, "amplitude", lockin.magnitude.astype(np.float32), "m", scales)
    _data(group, "amplitude_stderr", lockin.stderr.astype(np.float32), "m", scales)
    _data(group, "phase", lockin.phase.astype(np.float32), "rad", scales)
    _data(group, "phase_stderr", lockin.phase_stderr.astype(np.float32), "rad", scales)
    group.attrs["frequency_hz"] = lockin.frequency
    group.attrs["convention"] = "h = mean + sum_n amplitude_n cos(n omega t - phase_n)"


def _write_filtered(group: h5py.Group, maps: WaveMaps, options: WaveOptions) -> None:
    band = options.band
    assert band is not None
    dy, dx = maps.pixel_size
    rows, cols = maps.shape
    scales = (
        _scale(group, "time", maps.clock.times, "s"),
        _scale(group, "y", np.arange(rows) * dy, "m"),
        _scale(group, "x", np.arange(cols) * dx, "m"),
    )
    height = group.create_dataset(
        "height", shape=(maps.frames, rows, cols), dtype=np.float32, chunks=(1, rows, cols)
    )
    height.attrs["unit"] = "m"
    for axis, scale in enumerate(scales):
        height.dims[axis].attach_scale(scale)
    for name in ("k_min", "k_max", "f_min", "f_max", "direction", "half_width"):
        value = getattr(band, name)
        if value is not None:
            group.attrs[name] = value
    group.attrs["units"] = (
        "k in rad/m, f in Hz, direction and half_width in rad, transition_hz in Hz"
    )

    class Stack:
        """The maps analysed, by frame slices (relative maps summed)."""

        shape = (maps.frames, rows, cols)

        def __getitem__(self, key: slice) -> np.ndarray:
            start, stop, _ = key.indices(maps.frames)
            return maps.read(start, stop)

    longest = max(stop - start for start, stop in maps.clock.runs)
    block = block_for(band, maps.clock.rate, (rows, cols), longest)
    if band.temporal:
        group.attrs["transition_hz"] = transition_width(maps.clock.rate, block)
    band_filter(
        Stack(),
        maps.clock.times,
        maps.pixel_size,
        band,
        height,
        block=block,
        workers=options.workers,
    )


class WavesOutcome:
    """What :func:`run_waves` produced.

    Attributes
    ----------
    out : Path
        The output folder.
    results : WaveResults
        The analyses' results (arrays in SI units).
    summary : dict
        The content of ``waves.json`` (values with standard errors and units).
    files : list of Path
        The files written.
    """

    def __init__(
        self, out: Path, results: WaveResults, summary: dict[str, Any], files: list[Path]
    ) -> None:
        self.out = out
        self.results = results
        self.summary = summary
        self.files = files


def run_waves(
    input_path: str | Path,
    out: str | Path,
    options: WaveOptions,
    *,
    label: str = "fused",
    time_range: tuple[float | None, float | None] | None = None,
    pixel_size: float | None = None,
    fps: float | None = None,
    overwrite: bool = False,
) -> WavesOutcome:
    """Analyse one label's maps of a ``results.h5`` and write the outputs into ``out``.

    The output folder follows :mod:`holoview.headless.results.output_folder`: earlier outputs
    of this command are replaced only with ``overwrite``, and only when every file is
    complete.

    A dispersion fit that cannot be made does not hold back the spectra, figures and
    other analyses: they are written, the reason is a note, and it is raised after the
    writing when the fit was the one analysis asked for (:attr:`WaveOptions.fit_alone`),
    else logged as a warning.

    Raises
    ------
    InputError
        Bad input or a fit that does not converge (nothing is written), or the dispersion
        fit alone asked for could not be made (the rest is written).
    OutputError
        A file could not be written (nothing is replaced).
    """
    started = time.perf_counter()
    folder = Path(out)
    input_path = results_path(input_path)
    names = (WAVES_H5, WAVES_JSON, *FIGURES)
    with OutputFolder(folder, names, overwrite=overwrite, inputs=[input_path]) as outputs:
        with open_wave_maps(
            input_path, label, time_range=time_range, pixel_size=pixel_size, fps=fps
        ) as maps:
            results = analyse_waves(maps, options)
            try:
                written = time.perf_counter()
                _write_h5(outputs.path(WAVES_H5), results, maps, options)
                drawn = draw_figures(
                    results,
                    {name: outputs.path(name) for name in FIGURES},
                    processes=options.workers,
                )
                results.timing["writing_s"] = time.perf_counter() - written
            except OSError as exc:
                raise OutputError(f"cannot write into {folder}: {os_error_text(exc)}") from exc
            results.timing["total_s"] = time.perf_counter() - started
            summary = _summary(results, maps, drawn)
            try:
                outputs.path(WAVES_JSON).write_text(
                    json.dumps(_clean(summary), indent=2, allow_nan=False) + "\n",
                    encoding="utf-8",
                )
            except OSError as exc:
                raise OutputError(f"cannot write {WAVES_JSON}: {os_error_text(exc)}") from exc
        files = outputs.finish(interrupted=False)
    logger.info("wrote %s", ", ".join(p.name for p in files))
    if results.fit_problem is not None:
        if options.fit_alone:
            raise InputError(
                f"{results.fit_problem} (the spectra and figures are in {folder}; "
                "--no-fit leaves the fit out)"
            )
        logger.warning("no dispersion fit: %s", results.fit_problem)
    return WavesOutcome(folder, results, summary, files)


def _summary_values(results: WaveResults) -> dict[str, Any]:
    """The analyses' values with their errors, for ``waves.json``."""
    spectrum = results.spectrum
    out: dict[str, Any] = {
        "omega_k": {
            "segments": spectrum.segments,
            "frames": spectrum.frames,
            "frequency_resolution_hz": spectrum.df,
            "k_resolution_rad_per_m": list(spectrum.dk),
            "k_cut_rad_per_m": spectrum.k_cut,
            "relative_stderr": spectrum.relative_stderr,
        },
        "dispersion": None if results.dispersion is None else results.dispersion.as_dict(),
        "dispersion_problem": results.fit_problem,
        "centre_m": None if results.centre is None else list(results.centre),
        "centre_stderr_m": None if results.centre is None else list(results.centre_stderr),
        "centre_method": results.centre_method or None,
        "partial_waves": [fit.as_dict() for fit in results.partial_waves],
        "ringdown": None if results.ringdown is None else results.ringdown.as_dict(),
    }
    if results.mf is not None:
        out["mf_spectrum"] = {
            "segments": results.mf.segments,
            "strongest": [{"m": m, "frequency_hz": f} for m, f in results.mf.strongest(8)],
        }
    if results.lockin is not None:
        lockin = results.lockin
        out["lockin"] = {
            "frequency_hz": lockin.frequency,
            "harmonics": list(lockin.harmonics),
            "median_amplitude_m": [float(np.nanmedian(a)) for a in lockin.magnitude],
            "median_amplitude_stderr_m": [float(np.nanmedian(e)) for e in lockin.stderr],
        }
    return out


def _summary(results: WaveResults, maps: WaveMaps, drawn: list[str]) -> dict[str, Any]:
    return {
        "format": SUMMARY_FORMAT,
        "format_version": FORMAT_VERSION,
        "holoview_version": __version__,
        "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "input": {
            "path": str(maps.path),
            "label": maps.label,
            "reference": maps.reference,
            "frames": maps.frames,
            "first_frame": maps.first,
            "time_origin_s": maps.time_origin,
            "frame_interval_s": maps.clock.interval,
            "gaps": maps.clock.gaps,
            "lost_frames": maps.clock.lost,
            "pixel_size_m": list(maps.pixel_size),
            "k_cut_rad_per_m": maps.k_cut,
            "k_cut_from": maps.k_cut_source,
        },
        "sign_convention": SIGN_CONVENTION,
        **_summary_values(results),
        "notes": results.notes,
        "figures": drawn,
        "timing": results.timing,
    }


def _clean(value: Any) -> Any:
    """JSON-ready: NaN and infinities to None, numpy scalars to Python."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
