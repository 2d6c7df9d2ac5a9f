"""What a headless run is asked: :class:`ProcessOptions`, as the ``holoview process`` options.

:class:`ProcessOptions` holds them all: how the peaks are chosen (:class:`PeakChoice`),
the optics given (:class:`~holoview.headless.inputs.OpticsOptions`), how the frames are
demodulated (:class:`ProcessSettings`), which frames, which report, and where the frames
are measured.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from holoview.engine.experiment import Experiment
from holoview.errors import InputError
from holoview.headless.inputs import OpticsOptions
from holoview.headless.reader import DEFAULT_DEPTH
from holoview.headless.results.figures import figure_format
from holoview.processing.maps.demod_results import MAP_GRIDS

__all__ = ["PeakChoice", "ProcessOptions", "ProcessSettings"]

#: A carrier ``(fx, fy)``, cycles/pixel.
Carrier = tuple[float, float]


@dataclass(frozen=True)
class ProcessSettings:
    """How a run demodulates (names as the ``holoview process`` options).

    Attributes
    ----------
    reference : {"relative", "absolute", "synthetic"} or None
        Reference mode of the maps (the mean-phase series is always relative to the
        first frame). None: the experiment's.
    window : {"raised-cosine", "top-hat", "tukey"} or None
        None: the experiment's.
    radius : float, str or None
        Window radius, cycles/pixel, or ``"matched"`` or ``"bound"``
        (:func:`~holoview.processing.peaks.radii.peak_windows`); None: the experiment's.
    unwrap : {"auto", "always", "never"} or None
        Spatial unwrapping of the maps. None: the experiment's.
    maps : bool
        Write the delta-h maps of every frame, and the fused map.
    maps_grid : {"box", "frame"}
        Where the maps are: ``"box"``, the demodulation box's grid (the smallest that
        holds the widest window, e.g. 48 x 48 for 256 x 256 frames); ``"frame"``, the
        camera frame's pixels (the windowed sideband inverted at the frame's size: a
        plain Fourier filter's maps, for pixel-for-pixel comparisons; more time and
        disk). Only with ``maps``.
    area_m2 : float or None
        Basin area, m^2, for volume rates.
    threads : int
        FFTW threads per frame. One by default: the reader thread needs a core too,
        and on a loaded two-core machine a two-thread FFT waiting for a busy core
        took 450 ms instead of 10 ms per 1024 x 1024 frame.
    read_ahead : int
        Frames the reader thread reads ahead.
    background : str or None
        An object-free hologram for absolute phases: a frame index of the input, or
        a file (its first frame); None: the first processed frame.
    """

    reference: str | None = None
    window: str | None = None
    radius: float | str | None = None
    unwrap: str | None = None
    maps: bool = False
    maps_grid: str = "box"
    area_m2: float | None = None
    threads: int = 1
    read_ahead: int = DEFAULT_DEPTH
    background: str | None = None


@dataclass(frozen=True)
class PeakChoice:
    """How to choose the peaks: at most one of an experiment file, labels, or a count.

    With none, the experiment the recording carries is used, or ``--auto``
    :data:`~holoview.headless.prepare.DEFAULT_AUTO` when it carries none.

    Attributes
    ----------
    experiment : Path or Experiment or None
        An experiment file (:mod:`holoview.engine.experiment`), or an experiment (a
        window's labels and optics, as the file would give them).
    labels : dict of str to (fx, fy)
        Labelled carriers (cycles/pixel); with two or more of the model's families the
        model adds the others.
    auto : int or None
        The number of strongest peaks to identify by PCA.
    anchor : (str, (fx, fy)) or None
        Auto mode: the reference peak's label and carrier (default: the brightest, RB1).
    """

    experiment: Path | Experiment | None = None
    labels: dict[str, Carrier] = field(default_factory=dict)
    auto: int | None = None
    anchor: tuple[str, Carrier] | None = None

    def mode(self) -> str:
        """``"experiment file"``, ``"labels"``, ``"auto"`` or ``"recording"`` (none given)."""
        given = [
            name
            for name, on in (
                ("experiment file", self.experiment is not None),
                ("labels", bool(self.labels)),
                ("auto", self.auto is not None),
            )
            if on
        ]
        if len(given) > 1:
            raise InputError("choose the peaks one way: --experiment FILE, --label or --auto N")
        if self.anchor is not None and given != ["auto"]:
            raise InputError("--anchor goes with --auto")
        return given[0] if given else "recording"


@dataclass(frozen=True)
class ProcessOptions:
    """What ``holoview process`` is asked, beside the input and the output folder.

    Attributes
    ----------
    choice : PeakChoice
        How to choose the peaks.
    optics : OpticsOptions
        Wavelength (m), pixel pitch (m), n1, n2 or fluid, fps; they override the
        experiment's and the recording's own values.
    settings : ProcessSettings
        Reference mode, window, radius, unwrapping (each over the experiment's), maps,
        basin area, threads, background.
    frames : str or None
        ``START:STOP`` of the input's frames (all by default).
    report : str or bool or None
        The report's format: ``"png"``, ``"pdf"`` or ``"svg"`` (``report.png`` ...);
        True is ``"png"``; None or False: no report.
    overwrite : bool
        Replace an earlier run's results in the output folder when the run completes.
    jobs : int or None
        Processes measuring the frames
        (:func:`~holoview.headless.parallel.chunks.plan_jobs`; None: every core but one
        when the run is long enough); with ``scheduler`` ``"local"``, the local
        cluster's workers.
    scheduler : str or None
        A Dask scheduler's address, or ``"local"``
        (:mod:`holoview.headless.parallel.runners`).
    """

    choice: PeakChoice = field(default_factory=PeakChoice)
    optics: OpticsOptions = field(default_factory=OpticsOptions)
    settings: ProcessSettings = field(default_factory=ProcessSettings)
    frames: str | None = None
    report: str | bool | None = "png"
    overwrite: bool = False
    jobs: int | None = 1
    scheduler: str | None = None

    def checked(self) -> ProcessOptions:
        """These options with the report's format settled and a background's reference.

        Raises
        ------
        InputError
            For an unknown report format, ``--background`` with a reference other
            than absolute, or an unknown ``--maps-grid`` or one without ``--maps``.
        """
        report = "png" if self.report is True else self.report or None
        if report:
            figure_format(f"report.{report}", "--report-format")
        settings = self.settings
        if settings.maps_grid not in MAP_GRIDS:
            raise InputError(
                f"unknown --maps-grid {settings.maps_grid!r}; choose one of {', '.join(MAP_GRIDS)}"
            )
        if settings.maps_grid != "box" and not settings.maps:
            raise InputError(f"--maps-grid {settings.maps_grid} places the maps: give --maps too")
        if settings.background is not None:
            if settings.reference not in (None, "absolute"):
                raise InputError(
                    f"--background is the reference of absolute phases: it goes with "
                    f"--reference absolute, not {settings.reference}"
                )
            settings = replace(settings, reference="absolute")
        return replace(self, report=report, settings=settings)
