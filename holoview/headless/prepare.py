"""A headless run before its frames: the experiment, the optics, the frame times and the peaks.

:func:`prepare_run` settles, from the input and the options, everything the passes over
the frames need (:class:`~holoview.headless.run_passes.RunFrames`): the experiment the
run starts from (an experiment file, the recording's own, or labels) with the options
over its settings, the optics (:func:`~holoview.headless.inputs.resolve_optics`), the
frame times, the peaks detected on the first usable frame and those chosen
(:mod:`~holoview.headless.selection`), and the maps step's spec. Every user mistake is
an :class:`~holoview.errors.InputError` raised here, before the output folder is touched.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from holoview.engine.experiment import Experiment, LabelledPeak
from holoview.engine.frame_core import matching_positions, mean_positions
from holoview.engine.resolve import on_lattice
from holoview.errors import InputError
from holoview.headless.frame_passes import MapsSpec
from holoview.headless.input_identity import InputIdentity
from holoview.headless.inputs import (
    InputFile,
    Optics,
    check_not_background_subtracted,
    check_run_settings,
    first_good_frame,
    frame_problem,
    resolve_optics,
)
from holoview.headless.parallel.threads import in_order, parent_threads
from holoview.headless.run_passes import RunFrames
from holoview.headless.selection import Selection, select_auto, select_from_experiment
from holoview.headless.settings import PeakChoice, ProcessOptions, ProcessSettings
from holoview.processing.fourier.spectrum import rfft2
from holoview.processing.peaks.detection import Peak, find_peaks
from holoview.processing.peaks.radii import distinct_neighbours, surface_band, window_neighbours
from holoview.processing.peaks.surface_spectrum import (
    SurfaceSpectrum,
    average_change,
    measure_spectrum,
)

logger = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_AUTO",
    "PreparedRun",
    "check_background",
    "choose_peaks",
    "prepare_run",
    "read_background",
    "run_inputs",
]

#: Peaks identified by PCA when nothing names them (no options, no experiment stored).
DEFAULT_AUTO = 4


@dataclass(frozen=True)
class PreparedRun:
    """A run settled before its frames.

    Attributes
    ----------
    frames : RunFrames
        What the passes over the frames take (experiment, optics, settings, peaks).
    first : ndarray
        The first frame peaks could be detected on (counts): the report's spectrum.
    detected : list of Peak
        The peaks detected on it.
    box_shape : tuple of int
        Shape of the maps, ``(by, bx)``.
    """

    frames: RunFrames
    first: np.ndarray
    detected: list[Peak]
    box_shape: tuple[int, int]

    @property
    def selection(self) -> Selection:
        """The peaks chosen."""
        return self.frames.selection

    @property
    def experiment(self) -> Experiment:
        """The run's settled experiment."""
        return self.frames.experiment

    @property
    def optics(self) -> Optics:
        """The run's optics."""
        return self.frames.optics

    @property
    def settings(self) -> ProcessSettings:
        """The run's settings, the experiment's filled in."""
        return self.frames.settings


def prepare_run(
    source: InputFile,
    selected: range,
    options: ProcessOptions,
    identity: InputIdentity | None = None,
) -> PreparedRun:
    """Settle a run of ``selected`` frames of ``source`` (module documentation).

    ``identity`` (the input's when the run started) goes with the run's frames to its
    workers, which refuse an input replaced since.

    Raises
    ------
    InputError
        Missing or wrong parameters, a bad experiment file or labels (a label on no
        detected peak, an unknown label without alpha), no usable first frame.
    """
    base, mode, notes = _base_experiment(options.choice, source, selected[0])
    from_file = base if mode == "experiment file" else None
    optics = resolve_optics(source.setup, options.optics, from_file)
    optics.require("wavelength_m")
    experiment, settings = _settle(base, options.settings, optics)
    frame_times = source.times(selected, options.optics.fps_hz)
    check_run_settings(
        area_m2=settings.area_m2, radius=settings.radius, frame_shape=source.frame_shape
    )
    first_index, first = first_good_frame(source, selected)
    background = read_background(settings.background, source)
    detected = find_peaks(first, radius=experiment.fixed_radius, threads=settings.threads)
    selection = choose_peaks(
        options.choice,
        mode=mode,
        experiment=experiment,
        detected=detected,
        shape=source.frame_shape,
        optics=optics,
    )
    for note in (*notes, *source.notes):
        logger.warning("%s", note)
    level = logging.WARNING if frame_times.warning else logging.INFO
    logger.log(level, "%s: %s", source.path, frame_times.note)
    notes += [*source.notes, frame_times.note]
    selection = replace(selection, notes=(*notes, *selection.notes))
    spec = MapsSpec(
        experiment=experiment,
        peaks=tuple(selection.peaks),
        neighbours=tuple(window_neighbours(detected, on_lattice(selection.labelling, detected))),
        threads=settings.threads,
        background=background,
        grid=settings.maps_grid,
    )
    threads = parent_threads(options.jobs, settings.threads)
    if experiment.radius_rule == "matched":
        spectrum = _matching_spectrum(
            source,
            selected,
            first_index=first_index,
            first=first,
            reference=experiment.reference,
            background=background,
            band=surface_band(detected),
            carriers=[p.carrier for p in selection.peaks],
            neighbours=spec.neighbours,
            threads=threads,
        )
        spec = spec.matched(source.frame_shape, source.saturation, spectrum)
    core = spec.core(source.frame_shape, source.saturation)
    demodulator = core.demodulator
    assert demodulator is not None
    selection = replace(selection, notes=(*selection.notes, *core.notes))
    logger.info(
        "%s: %d frames, peaks %s (from the %s), window radius %.4f cycles/pixel, maps %s",
        source.path,
        len(selected),
        ", ".join(p.label or "?" for p in selection.peaks),
        selection.source,
        demodulator.radius,
        demodulator.box_shape,
    )
    run = RunFrames(
        source,
        selected,
        frame_times,
        selection,
        spec,
        experiment,
        optics,
        settings,
        identity,
        threads,
    )
    return PreparedRun(run, first, detected, demodulator.box_shape)


def _matching_spectrum(
    source: InputFile,
    frames: range,
    *,
    first_index: int,
    first: np.ndarray,
    reference: str,
    background: np.ndarray | None,
    band: float,
    carriers: list[tuple[float, float]],
    neighbours: tuple[tuple[float, float], ...],
    threads: int = 1,
) -> SurfaceSpectrum:
    """What a run's windows are matched to: the changes its maps show, the waves detected.

    The frames :func:`~holoview.engine.frame_core.matching_positions` names after the
    first good one, against it; against the background, the first good one and those
    (a background taken from the run's first frame leaves the others to show the
    changes). Frames that cannot be used are left out (the first alone when none
    is left, as for synthetic phases). The change around the ``carriers`` (their windows
    bounded by the ``neighbours`` too) averaged
    over the frames :func:`~holoview.engine.frame_core.mean_positions` names
    (:class:`~holoview.processing.peaks.surface_spectrum.ChangeAverage`), against the
    same reference (relative maps: each against the frame before it). The frames are
    read in turn, transformed ``threads`` at a time, and their changes added in order.
    """
    start = frames.index(first_index)
    later = []
    for position in matching_positions(reference, len(frames) - start):
        frame = source.read(frames[start + position])
        if frame_problem(frame) is None:
            later.append(frame)
    positions = mean_positions(reference, len(frames) - start)
    fixed = first if background is None else background

    def read(position: int) -> tuple[np.ndarray, np.ndarray]:  # here, one after another
        frame = source.read(frames[start + position])
        against = source.read(frames[start + position - 1]) if reference == "relative" else fixed
        return frame, against

    def transformed(pair: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray] | None:
        """The frame's half spectrum and its reference's (a fixed one as it is), or None."""
        frame, against = pair
        if frame_problem(frame) is not None or frame_problem(against) is not None:
            return None
        return rfft2(frame), against if against is fixed else rfft2(against)

    mean = None
    if positions and carriers:
        others = distinct_neighbours(first.shape, np.array(carriers), neighbours)
        # read here, transformed ``threads`` at a time, added in order: the same sums
        done = in_order(transformed, (read(p) for p in positions), threads)
        pairs = (p for p in done if p is not None)
        mean = average_change(first.shape, carriers, pairs, neighbours=[tuple(o) for o in others])
    if reference != "synthetic" and background is not None:
        return measure_spectrum([first, *later], background, band=band, mean=mean)
    if not later:
        return measure_spectrum(first, band=band)
    return measure_spectrum(later, first, band=band, mean=mean)


def _base_experiment(
    choice: PeakChoice, source: InputFile, first_frame: int
) -> tuple[Experiment, str, list[str]]:
    """The experiment a run starts from, where it came from, and notes.

    An experiment file, else the recording's own (labels, settings) when it carries one;
    ``--label`` replaces the peaks; with none, a recording without an experiment falls
    back to ``--auto``.
    """
    mode = choice.mode()
    if mode == "experiment file":
        given = choice.experiment
        assert given is not None
        return given if isinstance(given, Experiment) else Experiment.load(given), mode, []
    stored, notes = source.experiment_at(first_frame)
    base = stored or Experiment(wavelength_m=None, pixel_pitch_m=None, n1=None, n2=None)
    if mode == "labels":
        peaks = tuple(LabelledPeak(k, c) for k, c in choice.labels.items())
        return replace(base, peaks=peaks), mode, notes
    if mode == "recording":
        if stored is not None and stored.peaks:
            return stored, "recording", notes
        why = "carries no usable experiment" if stored is None else "names no peak"
        notes.append(f"the recording {why}: peaks identified by --auto {DEFAULT_AUTO}")
        return base, "auto", notes
    return base, "auto", notes


def _settle(
    experiment: Experiment, settings: ProcessSettings, optics: Optics
) -> tuple[Experiment, ProcessSettings]:
    """Options over the experiment's demodulation settings; the resolved optics into it."""
    experiment = experiment.updated(
        window=settings.window,
        reference=settings.reference,
        unwrap=settings.unwrap,
        radius=settings.radius,
    )
    experiment = replace(
        experiment,
        wavelength_m=optics.wavelength_m,
        pixel_pitch_m=optics.pixel_pitch_m,
        n1=optics.n1,
        n2=optics.n2,
    )
    settings = replace(
        settings,
        window=experiment.window,
        reference=experiment.reference,
        unwrap=experiment.unwrap,
        radius=experiment.radius,
    )
    return experiment, settings


def choose_peaks(
    choice: PeakChoice,
    *,
    mode: str,
    experiment: Experiment,
    detected: list[Peak],
    shape: tuple[int, int],
    optics: Optics,
) -> Selection:
    """The peaks of a run: the experiment's (``mode`` names where it came from) or auto."""
    if mode == "auto":
        optics.require("n2")
        count = DEFAULT_AUTO if choice.auto is None else choice.auto  # --auto 0 is refused
        return select_auto(count, detected, shape, choice.anchor)
    return select_from_experiment(experiment, detected, shape, mode)


def read_background(spec: str | None, source: InputFile) -> np.ndarray | None:
    """The background hologram ``--background`` names: a frame index of ``source``, or a file.

    Raises
    ------
    InputError
        For an index outside the input, a file that cannot be read, a frame of another
        shape than the input's, or one that is no hologram: constant (all zero),
        non-finite, damaged, or negative (:func:`check_background`).
    """
    if spec is None:
        return None
    if spec.lstrip("-").isdigit():
        index = int(spec)
        if not 0 <= index < len(source):
            raise InputError(
                f"--background {spec}: {source.path} has frames 0 to {len(source) - 1}"
            )
        frame = source.read(index)
    else:
        with InputFile(spec) as other:
            frame = other.read(0)
        if frame.shape != source.frame_shape:
            raise InputError(
                f"--background {spec}: frames of {frame.shape[0]} x {frame.shape[1]} pixels, "
                f"the input's are {source.frame_shape[0]} x {source.frame_shape[1]}"
            )
    check_background(frame, f"--background {spec}")
    return frame


def run_inputs(input_path: str | Path, choice: PeakChoice, settings: ProcessSettings) -> list[Path]:
    """Every file or folder a run reads: the input, an experiment file, a background file."""
    inputs = [Path(input_path)]
    if choice.experiment is not None and not isinstance(choice.experiment, Experiment):
        inputs.append(Path(choice.experiment))
    spec = settings.background
    if spec is not None and not spec.lstrip("-").isdigit():
        inputs.append(Path(spec))
    return inputs


def check_background(frame: np.ndarray, where: str) -> None:
    """Refuse a background that is no hologram: absolute phases against it would be noise.

    A background is an object-free hologram: an intensity with fringes. A constant
    frame (all zero), one with NaN, one damaged in transfer, and one of negative or
    zero mean intensity (a negated or background-subtracted frame) are refused.
    """
    problem = frame_problem(frame)
    if problem is not None:
        raise InputError(f"{where}: the frame {problem}; give an object-free hologram")
    mean = float(np.mean(frame, dtype=np.float64))
    if mean <= 0:
        raise InputError(
            f"{where}: the frame's mean intensity is {mean:.3g} (values {frame.min():.3g} to "
            f"{frame.max():.3g}): a hologram is an intensity; give an object-free hologram"
        )
    check_not_background_subtracted(frame, where)
