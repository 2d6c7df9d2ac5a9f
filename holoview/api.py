"""holoview from Python: the commands as functions, recordings and results as arrays.

Each function mirrors a command and runs the same code: :func:`simulate` is
``holoview simulate`` (its options as keywords), :func:`process` is ``holoview process``
(:func:`holoview.headless.run.process_file`), :func:`waves` is ``holoview waves``,
:func:`export` is ``holoview export``.
:func:`open_recording` gives a recording's frames lazily as a dask array, with their
times and the experiment the recording carries; :func:`open_results` gives a run's
``results.h5`` as xarray Datasets with coordinates in s and m and units.

No Qt is imported here. Mistakes are :class:`~holoview.errors.InputError` (one line
naming the problem), failed writes :class:`~holoview.errors.OutputError`.

Examples
--------
Simulate a recording of evaporating water, process it with maps, and look at the maps:

>>> import tempfile
>>> from pathlib import Path
>>> import holoview.api as hv
>>> folder = Path(tempfile.mkdtemp())
>>> recording = hv.simulate(folder / "evaporation.h5", "evaporation", size=64, frames=8,
...                         fps=20, seed=1, evaporation_um_per_min=60)
>>> with hv.open_recording(recording) as rec:
...     rec.frames.shape, rec.times[1], [p.label for p in rec.experiment.peaks]
((8, 64, 64), np.float64(0.05), ['RB1', 'RF', 'FB1'])
>>> outcome = hv.process(recording, folder / "run", maps=True, jobs=1, report=False)
>>> maps = hv.open_results(outcome.out, "maps")
>>> maps.fused.dims, maps.fused.attrs["units"], maps.x.attrs["units"]
(('time', 'y', 'x'), 'm', 'm')
>>> rate = hv.open_results(outcome.out, "peaks").rate_m_per_s.sel(label="RB1")
>>> round(float(rate) * 6e7, -1)  # um/min, to tens; the water falls at 60 um/min
-60.0
>>> maps.close()
>>> hv.export(outcome.out, "netcdf", folder / "run.nc").path.name
'run.nc'
"""

from __future__ import annotations

import argparse
import importlib
import logging
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, cast

import numpy as np
import xarray as xr

from holoview.api_recordings import Recording, open_recording
from holoview.errors import InputError
from holoview.headless.inputs import OpticsOptions
from holoview.headless.results.exports import Export, Progress, export_results
from holoview.headless.results.results_data import open_results as _open_results
from holoview.headless.run import ProcessOutcome, process_file
from holoview.headless.settings import PeakChoice, ProcessOptions, ProcessSettings

if TYPE_CHECKING:
    from holoview.headless.waves.outputs import WavesOutcome

logger = logging.getLogger(__name__)

__all__ = [
    "Recording",
    "export",
    "open_recording",
    "open_results",
    "process",
    "simulate",
    "waves",
]


class _OptionParser(argparse.ArgumentParser):
    """A command's parser whose mistakes are an InputError, not an exit."""

    def error(self, message: str) -> NoReturn:
        raise InputError(f"{self.prog}: {message}")


def _argv(options: dict[str, Any], joined: frozenset[str] = frozenset()) -> list[str]:
    """Keyword options as command-line arguments: ``wave_rms_nm=40`` -> ``--wave-rms-nm 40``.

    True is a flag, None and False leave the option out, a tuple gives several values
    (one ``X,Y`` value for the options in ``joined``, which take one: ``centre=(3, 2)``
    -> ``--centre 3,2``), a list of tuples repeats the option.
    """
    argv: list[str] = []
    for name, value in options.items():
        option = "--" + name.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            argv.append(option)
        elif isinstance(value, list):
            for item in value:
                argv += [option, *(str(v) for v in np.atleast_1d(item))]
        elif isinstance(value, tuple) and option in joined:
            argv += [option, ",".join(str(v) for v in value)]
        elif isinstance(value, tuple):
            argv += [option, *(str(v) for v in value)]
        else:
            argv += [option, str(value)]
    return argv


def _parse_command(
    command: str, positional: list[str], options: dict[str, Any]
) -> tuple[Any, argparse.Namespace]:
    """The command's module and ``options`` parsed by its own parser (quiet)."""
    parser = _OptionParser(prog="holoview")
    subparsers = parser.add_subparsers(dest="command")
    module = importlib.import_module(f"holoview.cli.{command}")
    module.add_parser(subparsers)
    # options of one value (--centre X,Y): a tuple given for one is joined with commas
    single = frozenset(
        text
        for action in subparsers.choices[command]._actions
        if action.nargs is None
        for text in action.option_strings
    )
    args = parser.parse_args([command, *positional, *_argv(options, single)])
    args.quiet, args.verbose = True, 0
    return module, args


def _run_command(command: str, positional: list[str], options: dict[str, Any]) -> int:
    """Parse ``options`` with the command's own parser and run it quietly."""
    module, args = _parse_command(command, positional, options)
    return int(module.run(args) or 0)


def simulate(path: str | Path, scenario: str = "waves", **options: Any) -> Path:
    """Write a simulated recording with its truth: ``holoview simulate PATH``.

    Parameters
    ----------
    path : str or Path
        The recording to create (an existing file is not overwritten).
    scenario : str
        ``"waves"``, ``"evaporation"``, ``"injection"`` and the others of
        ``holoview simulate --help``.
    **options
        The command's options with underscores: ``size`` (pixels), ``frames``,
        ``fps`` (frames/s), ``seed``, ``noise``, ``wavelength_nm``, ``pixel_pitch_um``,
        ``n2`` or ``fluid``, ``m_r_mrad=(mx, my)``, ``evaporation_um_per_min``,
        ``wave_rms_nm``, ``ghost=[(arm, tx, ty, amplitude), ...]``, ...; units as the
        names say.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        An unknown option, a value the command refuses, an existing file.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> folder = Path(tempfile.mkdtemp())
    >>> simulate(folder / "waves.h5", "waves", size=64, frames=4, seed=2).name
    'waves.h5'
    >>> simulate(folder / "other.h5", size=64, colour="blue")
    Traceback (most recent call last):
    ...
    holoview.errors.InputError: holoview: unrecognized arguments: --colour blue
    """
    _run_command("simulate", [str(path)], {"scenario": scenario, **options})
    return Path(path)


def _frame_range(frames: str | slice | range | None) -> str | None:
    """``frames`` as ``--frames START:STOP`` takes it."""
    if frames is None or isinstance(frames, str):
        return frames
    if isinstance(frames, range | slice) and frames.step in (None, 1):
        start = "" if frames.start is None else str(frames.start)
        stop = "" if frames.stop is None else str(frames.stop)
        return f"{start}:{stop}"
    raise InputError(f"frames takes 'START:STOP', a slice or a range without step, got {frames}")


def process(
    recording: str | Path,
    out: str | Path,
    *,
    labels: dict[str, tuple[float, float]] | None = None,
    auto: int | None = None,
    anchor: tuple[str, tuple[float, float]] | None = None,
    experiment: str | Path | None = None,
    wavelength_m: float | None = None,
    pixel_pitch_m: float | None = None,
    n1: float | None = None,
    n2: float | None = None,
    fluid: str | None = None,
    fps: float | None = None,
    reference: str | None = None,
    window: str | None = None,
    radius: float | str | None = None,
    unwrap: str | None = None,
    background: str | int | None = None,
    maps: bool = False,
    maps_grid: str = "box",
    area_m2: float | None = None,
    frames: str | slice | range | None = None,
    threads: int = 1,
    jobs: int | None = None,
    scheduler: str | None = None,
    report: str | bool | None = "png",
    overwrite: bool = False,
) -> ProcessOutcome:
    """Process a recording into an output folder: ``holoview process RECORDING --out OUT``.

    The same code as the command (:func:`holoview.headless.run.process_file`), the same
    outputs (``trends.csv``, ``summary.json``, ``results.h5``, ``report.png``), the
    options in SI units.

    Parameters
    ----------
    recording : str or Path
        A holoview recording, a TIFF stack, a folder of images, a video or a ``.npy``.
    out : str or Path
        The output folder (``overwrite`` to replace an earlier run's results).
    labels : dict of str to (fx, fy), optional
        Labelled peaks, carriers in cycles/pixel (``--label``).
    auto : int, optional
        The N strongest peaks, identified by PCA (``--auto``).
    anchor : (str, (fx, fy)), optional
        With ``auto``: the reference peak (``--anchor``).
    experiment : str or Path, optional
        An experiment file (``--experiment``). With none of ``labels``, ``auto`` and
        ``experiment``: the recording's own experiment, else ``auto=4``.
    wavelength_m, pixel_pitch_m : float, optional
        Laser wavelength and object-side pixel pitch, m (over the recording's).
    n1, n2 : float, optional
        Refractive indices above the surface and of the fluid; or ``fluid`` by name.
    fps : float, optional
        Frame rate, frames/s, replacing the file's times.
    reference, window, radius, unwrap : optional
        Demodulation settings as the command's options (radius in cycles/pixel, or
        ``"matched"`` or ``"bound"``).
    background : str or int, optional
        The object-free hologram: a frame index of the recording, or a file.
    maps : bool
        Write the height maps (``--maps``).
    maps_grid : {"box", "frame"}
        With ``maps``: the maps on the demodulation box's grid (the default) or on the
        camera frame's pixels (``--maps-grid frame``: the windowed sideband inverted at
        the frame's size, as a plain Fourier filter gives it).
    area_m2 : float, optional
        Basin area, m^2 (volume rates).
    frames : str, slice or range, optional
        The frames to process (``"100:500"``, ``slice(100, 500)``).
    threads, jobs, scheduler : optional
        FFTW threads per frame; processes (None: automatic); a Dask scheduler.
    report : str or None
        The report's format, ``"png"``, ``"pdf"`` or ``"svg"`` (``report.png``, ...:
        ``--report-format``); None (or False): no report.
    overwrite : bool
        Replace the results of an earlier run in ``out``.

    Returns
    -------
    ProcessOutcome
        ``out``, the peaks, the series, the analysis and ``summary`` (the content of
        ``summary.json``); open the results with :func:`open_results` (``out``).

    Raises
    ------
    InputError
        For anything ``holoview process`` refuses (one line naming it).
    OutputError
        An output could not be written.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> folder = Path(tempfile.mkdtemp())
    >>> path = simulate(folder / "rec.h5", "evaporation", size=64, frames=8, fps=20, seed=1)
    >>> outcome = process(path, folder / "out", jobs=1, report=False)
    >>> sorted(p.name for p in outcome.files)
    ['results.h5', 'summary.json', 'trends.csv']
    >>> outcome.summary["fused"]["labels"]
    ['RB1', 'RF', 'RB2', 'FB1', 'RB3']
    """
    choice = PeakChoice(
        experiment=None if experiment is None else Path(experiment),
        labels=dict(labels or {}),
        auto=auto,
        anchor=anchor,
    )
    optics = OpticsOptions(
        wavelength_m=wavelength_m,
        pixel_pitch_m=pixel_pitch_m,
        n1=n1,
        n2=n2,
        fluid=fluid,
        fps_hz=fps,
    )
    settings = ProcessSettings(
        reference=reference,
        window=window,
        radius=radius,
        unwrap=unwrap,
        maps=maps,
        maps_grid=maps_grid,
        area_m2=area_m2,
        threads=threads,
        background=None if background is None else str(background),
    )
    options = ProcessOptions(
        choice=choice,
        optics=optics,
        settings=settings,
        frames=_frame_range(frames),
        report=report,
        overwrite=overwrite,
        jobs=jobs,
        scheduler=scheduler,
    )
    return process_file(recording, out, options)


def waves(results: str | Path, out: str | Path, **options: Any) -> WavesOutcome:
    """Analyse a run's maps as a wave field: ``holoview waves RESULTS --out OUT``.

    The same code as the command (:func:`holoview.headless.waves.outputs.run_waves`),
    the same outputs (``waves.h5``, ``waves.json``, PNG figures): the omega-k spectrum
    with the capillary-gravity dispersion relation fitted (surface tension, depth and
    mean flow with standard errors), E(k) and E(f); with ``centre``, the (m, f)
    spectrum, partial waves and a ringdown; lock-in maps at ``drive_hz``.

    Parameters
    ----------
    results : str or Path
        A ``results.h5`` with maps (``process(..., maps=True)``), or its folder.
    out : str or Path
        The output folder.
    **options
        The command's options with underscores, units as the command's (mm, mm/s, Hz,
        rad/m): ``label`` (``"fused"``), ``time="0.02:"``, ``segment`` (frames),
        ``fluid``, ``sigma`` (N/m), ``depth_mm``, ``flow_mm_per_s="20,10"``,
        ``hold="depth"``, ``no_fit``, ``k_range="300:1800"``, ``centre="auto"`` or
        ``"X,Y"``, ``r_range_mm``, ``m_max``, ``modes="0:14,2:22"``, ``ringdown="2,9:15"``,
        ``drive_hz``, ``harmonics``, ``band_f="10:40"``, ``threads``, ``overwrite``
        (``holoview waves --help``).

    Returns
    -------
    WavesOutcome
        ``out``, ``results`` (arrays, SI units), ``summary`` (the content of
        ``waves.json``: values with their standard errors and units) and ``files``.

    Raises
    ------
    InputError
        For anything ``holoview waves`` refuses (one line naming it).
    OutputError
        An output could not be written.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> folder = Path(tempfile.mkdtemp())
    >>> waves(folder / "missing.h5", folder / "waves")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    holoview.errors.InputError: ...missing.h5: no such file
    """
    module, args = _parse_command("waves", [str(results)], {"out": out, **options})
    return cast("WavesOutcome", module.analyse(args))


def open_results(
    path: str | Path, group: str = "maps", *, chunks: dict[str, int] | None = None
) -> xr.Dataset:
    """Open a group of a run's ``results.h5`` as an xarray Dataset (lazily).

    ``maps`` gives ``h(time, y, x)`` per peak and ``fused`` (m; ``time`` in s, ``y``
    and ``x`` in m on the object side, at the map pixels' centres); ``trends`` the
    series by ``(time, label)``; ``peaks`` the table by ``label``. Booleans are
    booleans and ``carrier_value`` complex, as the file stores them (int8 0/1 and two
    float parts, which every netCDF reader reads); files of the earlier formats 2.0
    and 1.0 open the same way (:mod:`holoview.headless.results.results_data`).

    Parameters
    ----------
    path : str or Path
        ``results.h5``, or the output folder holding it.
    group : str
        ``"maps"``, ``"trends"`` or ``"peaks"``.
    chunks : dict, optional
        Dask chunks, e.g. ``{"time": 64}``, for maps larger than memory.

    Returns
    -------
    xarray.Dataset
        Close it (or use ``with``) to release the file.

    Raises
    ------
    InputError
        No such file, not a results file, an unknown group, or no maps.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> folder = Path(tempfile.mkdtemp())
    >>> path = simulate(folder / "rec.h5", "evaporation", size=64, frames=8, fps=20, seed=1)
    >>> out = process(path, folder / "out", jobs=1, report=False).out
    >>> with open_results(out, "trends") as trends:
    ...     print(trends.mean_height_m.dims, trends.time.attrs["units"], trends.sizes["time"])
    ('time', 'label') s 8
    >>> open_results(out, "maps")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    holoview.errors.InputError: ... holds no maps: run holoview process with --maps
    """
    return _open_results(path, group, chunks=chunks)


def export(
    results: str | Path,
    to: str,
    out: str | Path,
    *,
    maps: Sequence[str] | None = None,
    overwrite: bool = False,
    mat_version: str = "5",
    progress: Progress | None = None,
) -> Export:
    """Export a run's results: ``holoview export RESULTS --to TO --out OUT``.

    Parameters
    ----------
    results : str or Path
        ``results.h5``, or the output folder holding it.
    to : str
        ``"netcdf"`` (a ``.nc`` file), ``"zarr"`` (a folder), ``"mat"`` (a ``.mat``
        file) or ``"tiff"`` (a folder of ImageJ stacks, one per map).
    out : str or Path
        The file or folder to create.
    maps : sequence of str, optional
        The maps to export (all by default).
    overwrite : bool
        Replace an existing ``out``.
    mat_version : str
        ``"5"`` (scipy, Octave, MATLAB; 2 GB per variable) or ``"7.3"`` (HDF5).
    progress : callable, optional
        ``progress(done, total)`` while the maps are written.

    Returns
    -------
    Export
        The path written, the format, the groups and maps.

    Raises
    ------
    InputError
        See :func:`holoview.headless.results.exports.export_results`.
    OutputError
        The output could not be written (nothing is left at ``out``).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from scipy.io import loadmat
    >>> folder = Path(tempfile.mkdtemp())
    >>> path = simulate(folder / "rec.h5", "evaporation", size=64, frames=8, fps=20, seed=1)
    >>> out = process(path, folder / "out", maps=True, jobs=1, report=False).out
    >>> done = export(out, "mat", folder / "run.mat", maps=["fused"])
    >>> done.maps
    ('fused',)
    >>> mat = loadmat(done.path, simplify_cells=True)
    >>> mat["maps"]["fused"].shape, mat["maps"]["units"]["fused"], mat["trends"]["time"][1]
    ((8, 16, 16), 'm', np.float64(0.05))
    """
    return export_results(
        results,
        to,
        out,
        maps=maps,
        overwrite=overwrite,
        mat_version=mat_version,
        progress=progress,
    )
