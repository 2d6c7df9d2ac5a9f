"""The input of a headless run: the frame file, its optics and its frame times.

Physical parameters come from a holoview recording's ``/setup`` attributes when it
has them, else from the user's options. An option given explicitly overrides the
recording (with a warning naming both values): a recording made with a wrong setting
can still be processed right. Frame times come from the file's own timestamps by the
one clock rule (:mod:`holoview.acquire.frame_times`: the camera clock where it is
finite, forward and free of jumps, else host arrival times; a video's frame rate);
``fps_hz`` replaces them with ``index / fps_hz``, and files without usable times (TIFF
stacks, image folders, a recording whose clocks are both damaged) need it. The rule
used, and what a recording's frames lack (a recording still being written, time
stamps missing for frames stored), are notes for the results.

The frames are checked where a user's mistake would otherwise pass unseen: values
beyond the recording's pixel format (a "Mono12" file holding 16-bit data) stop the
run naming the file and frame; :func:`first_good_frame` finds the frame the peaks are
detected on, skipping (with a warning) frames damaged in transfer, non-finite or
blank, and refuses background-subtracted frames, which cannot be demodulated.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, Self

import numpy as np

from holoview.acquire.frame_file import FrameFile
from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.replay_files import open_frame_file
from holoview.engine.experiment import Experiment
from holoview.errors import InputError
from holoview.file_kinds import special_file
from holoview.optics.setup import FLUIDS, check_optics
from holoview.processing.fourier.frames import check_frame, check_frame_content, frame_damage
from holoview.processing.series.frame_gaps import intervals_of

logger = logging.getLogger(__name__)

#: Refractive index above the surface when neither the file nor the user gives one (air).
DEFAULT_N1 = FLUIDS["air"]

#: Plausible frame rates, frames per second (a time-lapse at one frame a week to the
#: fastest cameras); outside, the series' arithmetic overflows.
FPS_RANGE = (1e-6, 1e7)

#: Plausible basin areas, m^2 (a square millimetre to a square kilometre).
AREA_RANGE = (1e-6, 1e6)

#: Frames tried, from the first of a run, for one that peaks can be detected on.
FIRST_FRAME_TRIES = 10

#: A hologram's mean intensity exceeds its spread (by sqrt(2) at full fringe contrast);
#: below this fraction of it, the frames have had their background subtracted.
MIN_MEAN_TO_SPREAD = 0.5


@dataclass(frozen=True)
class OpticsOptions:
    """What the user gave on the command line (None: not given), SI units.

    Attributes
    ----------
    wavelength_m : float or None
        Laser wavelength in vacuum, m.
    pixel_pitch_m : float or None
        Object-side pixel pitch, m.
    n1, n2 : float or None
        Refractive indices above the surface and of the fluid.
    fluid : str or None
        A name of :data:`holoview.optics.setup.FLUIDS` setting ``n2``.
    fps_hz : float or None
        Frame rate, frames per second, replacing the file's timestamps.
    """

    wavelength_m: float | None = None
    pixel_pitch_m: float | None = None
    n1: float | None = None
    n2: float | None = None
    fluid: str | None = None
    fps_hz: float | None = None


@dataclass(frozen=True)
class Optics:
    """The physical parameters a run uses, and where each came from.

    Attributes
    ----------
    wavelength_m : float or None
        Laser wavelength, m (None: unknown; heights need it).
    pixel_pitch_m : float or None
        Object-side pixel pitch, m (None: unknown; maps are then in pixels only).
    n1, n2 : float or None
        Refractive indices above the surface and of the fluid (n2 None: unknown).
    sources : dict of str to str
        Per parameter, ``"recording"``, ``"option"`` or ``"default"``.
    """

    wavelength_m: float | None
    pixel_pitch_m: float | None
    n1: float
    n2: float | None
    sources: dict[str, str] = field(default_factory=dict)

    def require(self, *names: str) -> None:
        """Raise InputError naming the option to give for each parameter that is unknown."""
        options = {
            "wavelength_m": "the laser wavelength is not known: give --wavelength-nm",
            "n2": "the fluid's refractive index is not known: give --n2 or --fluid",
            "pixel_pitch_m": "the pixel pitch is not known: give --pixel-pitch-um",
        }
        missing = [options[name] for name in names if getattr(self, name) is None]
        if missing:
            raise InputError("; ".join(missing))


#: How the user gives each parameter (``process`` and ``peaks``), with its unit factor to SI.
OPTION_NAMES: dict[str, tuple[str, float]] = {
    "wavelength_m": ("--wavelength-nm", 1e-9),
    "pixel_pitch_m": ("--pixel-pitch-um", 1e-6),
    "n1": ("--n1", 1.0),
    "n2": ("--n2", 1.0),
}


def _stored(setup: dict[str, Any], name: str) -> float | None:
    """A recording's value of ``name`` if plausible, else None (with a warning)."""
    stored = setup.get(name)
    if stored is None:
        return None
    try:
        check_optics(**{name: stored}, names={name: (f"the recording's {name}", 1.0)})
    except InputError as exc:
        logger.warning("%s; ignored", exc)
        return None
    return float(stored)


def resolve_optics(
    setup: dict[str, Any], options: OpticsOptions, experiment: Experiment | None = None
) -> Optics:
    """Combine a recording's setup with the user's options (options win, with a warning).

    Parameters
    ----------
    setup : dict
        The recording's ``/setup`` attributes (``wavelength_m``, ``pixel_pitch_m``,
        ``n1``, ``n2``); empty for files that carry none.
    options : OpticsOptions
        The user's values.
    experiment : Experiment, optional
        An experiment file the user gave: its optics come after the options and before
        the recording's.

    Raises
    ------
    InputError
        For an implausible value (:func:`~holoview.optics.setup.check_optics`: a
        wavelength of 532 m, a negative pitch, NaN; with a hint about units), an
        unknown fluid, both ``n2`` and ``fluid``, or ``n2`` not above ``n1``. A
        recording's implausible value is ignored with a warning.
    """
    if options.fluid is not None and options.n2 is not None:
        raise InputError("give --n2 or --fluid, not both")
    n2_option = options.n2
    if options.fluid is not None:
        if options.fluid not in FLUIDS:
            raise InputError(
                f"unknown fluid {options.fluid!r}; choose one of {', '.join(sorted(FLUIDS))}"
            )
        n2_option = FLUIDS[options.fluid]
    given = {
        "wavelength_m": options.wavelength_m,
        "pixel_pitch_m": options.pixel_pitch_m,
        "n1": options.n1,
        "n2": n2_option,
    }
    first = {**given, "n1": given["n1"] or (DEFAULT_N1 if given["n2"] is not None else None)}
    check_optics(**first, names=OPTION_NAMES)  # the user's own first, before any warning
    values: dict[str, float | None] = {}
    sources: dict[str, str] = {}
    for name, option in given.items():
        stored_value = _stored(setup, name)
        if option is None and experiment is not None and getattr(experiment, name) is not None:
            values[name], sources[name] = getattr(experiment, name), "experiment"
            continue
        if option is not None:
            value = float(option)
            if stored_value is not None and not math.isclose(value, stored_value, rel_tol=1e-9):
                logger.warning(
                    "%s: the option's %.6g replaces the recording's %.6g",
                    name,
                    value,
                    stored_value,
                )
            values[name], sources[name] = value, "option"
        elif stored_value is not None:
            values[name], sources[name] = stored_value, "recording"
        else:
            values[name], sources[name] = None, "unknown"
    if values["n1"] is None:
        values["n1"], sources["n1"] = DEFAULT_N1, "default"
    n1, n2 = values["n1"], values["n2"]
    assert n1 is not None
    names = {
        name: OPTION_NAMES[name] if source == "option" else (f"the {source}'s {name}", 1.0)
        for name, source in sources.items()
    }
    check_optics(**values, names=names)
    return Optics(
        wavelength_m=values["wavelength_m"],
        pixel_pitch_m=values["pixel_pitch_m"],
        n1=n1,
        n2=n2,
        sources=sources,
    )


def parse_frame_range(text: str | None, n_frames: int) -> range:
    """Return the frame indices ``START:STOP`` selects (Python slice rules, no step).

    Parameters
    ----------
    text : str or None
        ``"START:STOP"``, either side optional (``"100:"``, ``":500"``), negative
        counting from the end; None for every frame.
    n_frames : int
        Frames in the file.

    Raises
    ------
    InputError
        For text that is not ``START:STOP`` with integers, or a range with no frame.
    """
    if text is None:
        return range(n_frames)
    start_text, sep, stop_text = text.partition(":")
    if not sep:
        raise InputError(f"--frames takes START:STOP (e.g. 0:500), got {text!r}")
    try:
        start = int(start_text) if start_text.strip() else None
        stop = int(stop_text) if stop_text.strip() else None
    except ValueError as exc:
        raise InputError(f"--frames takes integers START:STOP, got {text!r}") from exc
    selected = range(n_frames)[slice(start, stop)]
    if len(selected) == 0:
        raise InputError(f"--frames {text} selects no frame of the {n_frames} in the input")
    return selected


def check_run_settings(
    *, area_m2: float | None, radius: float | str | None, frame_shape: tuple[int, int]
) -> None:
    """Refuse a basin area or window radius that cannot give a sensible result.

    Parameters
    ----------
    area_m2 : float or None
        Basin area, m^2 (:data:`AREA_RANGE`).
    radius : float, str or None
        Window radius, cycles/pixel: at least one FFT bin of the frame, below 0.5 (a
        rule, ``"matched"`` or ``"bound"``, is not checked here).
    frame_shape : tuple of int
        ``(rows, cols)`` of the frames, pixels.
    """
    if area_m2 is not None:
        if not (math.isfinite(area_m2) and area_m2 > 0):
            raise InputError(f"--area must be a positive area in m^2, got {area_m2}")
        if not AREA_RANGE[0] <= area_m2 <= AREA_RANGE[1]:
            raise InputError(
                f"--area {area_m2:g} m^2 is not a plausible basin area "
                f"({AREA_RANGE[0]:g} to {AREA_RANGE[1]:g} m^2)"
            )
    if isinstance(radius, float | int):
        smallest = 1.0 / min(frame_shape)
        if not (math.isfinite(radius) and smallest <= radius < 0.5):
            raise InputError(
                f"--radius {radius:g} cycles/pixel: give a radius from {smallest:.3g} (one FFT "
                f"bin of {frame_shape[0]} x {frame_shape[1]} frames) to below 0.5"
            )


def frame_problem(frame: np.ndarray) -> str | None:
    """Why peaks cannot be detected on ``frame`` (damaged, non-finite, blank), or None."""
    try:
        array = check_frame(frame)
        check_frame_content(array)
    except InputError as exc:
        return str(exc).removeprefix("frame ")
    damage = frame_damage(array)
    if damage is not None:
        return f"is damaged: {damage}"
    return None


def check_not_background_subtracted(frame: np.ndarray, where: str) -> None:
    """Refuse a frame whose mean intensity is near zero: its background was subtracted.

    Amplitudes and trusted pixels are measured against the mean intensity, so such
    frames demodulate to nothing ("no_signal" on every frame).
    """
    values = np.asarray(frame, dtype=np.float64)[::2, ::2]
    mean, spread = float(values.mean()), float(values.std())
    if values.min() < 0 and mean < MIN_MEAN_TO_SPREAD * spread:
        raise InputError(
            f"{where} has a mean intensity of {mean:.3g} for a spread of {spread:.3g} "
            f"(values {values.min():.3g} to {values.max():.3g}): background-subtracted frames "
            "cannot be demodulated (amplitudes are measured against the mean intensity); "
            "give the raw frames"
        )


def first_good_frame(source: InputFile, frames: range) -> tuple[int, np.ndarray]:
    """Return ``(index, frame)``: the first of ``frames`` that peaks can be detected on.

    Frames damaged in transfer, holding NaN or infinite values, or blank are skipped
    with a warning naming them (up to :data:`FIRST_FRAME_TRIES`).

    Raises
    ------
    InputError
        None of the first frames is usable (naming the file, the frame and why), or
        the frames are background-subtracted.
    """
    problems: list[str] = []
    for index in list(frames)[:FIRST_FRAME_TRIES]:
        frame = source.read(index)
        problem = frame_problem(frame)
        if problem is None:
            check_not_background_subtracted(frame, f"{source.path} frame {index}")
            if problems:
                logger.warning(
                    "%s: peaks detected on frame %d (frame %s)", source.path, index, problems[0]
                )
            return index, frame
        problems.append(f"{index} {problem}")
    span = f"frame {frames[0]}" if len(problems) == 1 else f"frames {frames[0]}..{index}"
    raise InputError(f"{source.path}: no peaks can be detected on {span}: frame {problems[0]}")


@dataclass(frozen=True)
class FrameTimes:
    """The times of a run's frames and the rule that gave them.

    Attributes
    ----------
    times : ndarray
        Seconds from 0 at the run's first frame.
    note : str
        Which clock (or ``--fps``) timed which frames, and why not the camera's.
    warning : bool
        True when the camera's clock was damaged and another was used.
    intervals : ndarray of int, optional
        Per frame, the frame intervals since the one before (more than one after
        frames the camera lost; 1 for the first): :func:`frame_intervals`.
    """

    times: np.ndarray
    note: str
    warning: bool = False
    intervals: np.ndarray | None = None

    def interval(self, position: int) -> int:
        """The frame intervals before the frame at ``position`` (1 when not known)."""
        return 1 if self.intervals is None else int(self.intervals[position])


def frame_intervals(times: np.ndarray, camera: bool, ids: np.ndarray) -> np.ndarray:
    """Per frame, the frame intervals since the one before (1 for the first).

    A camera's clock says how much time passed, which is what the surface's motion
    follows: a step over ``1 + GAP_TOLERANCE`` median steps spans ``round(step /
    median)`` intervals (:func:`~holoview.processing.series.frame_gaps.intervals_of`; a pause
    of the camera counts as well as its lost frames). Host arrival times come late and
    in bursts: there, and under ``--fps``, the camera's frame counter says what was lost,
    where it steps forward throughout; else every step is one interval.

    Examples
    --------
    >>> frame_intervals(np.array([0.0, 0.05, 0.1, 0.6]), True, np.arange(4))
    array([ 1,  1,  1, 10])
    >>> frame_intervals(np.array([0.0, 0.01, 0.3, 0.31]), False, np.array([7, 8, 10, 11]))
    array([1, 1, 2, 1])
    """
    if camera:
        return intervals_of(times)
    out = np.ones(len(times), dtype=np.int64)
    if len(times) >= 3 and np.all(np.diff(ids) >= 1):
        out[1:] = np.diff(ids)
    return out


class InputFile:
    """A frame file opened for a headless run, with its metadata.

    Parameters
    ----------
    path : str or Path
        A holoview recording, a TIFF stack, a folder of TIFF/PNG images, or a video.

    Attributes
    ----------
    path : Path
    kind : str
        ``"hdf5"``, ``"tiff"``, ``"folder"`` or ``"video"``.
    frame_shape : tuple of int
        ``(rows, cols)``, pixels.
    dtype : numpy dtype
    setup : dict
        A recording's ``/setup`` attributes (empty for other files).
    experiments : list of (int, str)
        The experiments a recording carries: the frame each holds from, and its JSON
        text (empty for other files and for recordings made without one).
    saturation : float or None
        The largest value the camera gives (counts), from the recording's significant
        bits or the integer dtype; None for real-valued frames.
    notes : list of str
        What a reader of the results should know about the frames (a recording still
        being written, frames left out because their time stamps are missing).
    info : dict
        What ``summary.json`` says of the input (path, kind, frames, shape, dtype and,
        for a recording, its uuid, source and creation time).

    Raises
    ------
    InputError
        For a missing, unreadable, empty or unknown file (one line naming it).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        special = special_file(self.path)
        if special is not None:  # never opened: a FIFO would wait for a writer
            raise InputError(f"{self.path}: {special}, not a file or folder of frames")
        if not self.path.exists():
            raise InputError(f"{self.path}: no such file or folder")
        self.setup: dict[str, Any] = {}
        self.info: dict[str, Any] = {"path": str(self.path)}
        bits: int | None = None
        if self.path.is_file() and self.path.suffix.lower() in (".h5", ".hdf5"):
            with RecordingReader(self.path) as reader:
                self.setup = dict(reader.setup)
                bits = reader.significant_bits
                self.info.update(
                    uuid=reader.uuid, source=reader.source, created_utc=reader.created_utc
                )
        self._file: FrameFile = open_frame_file(self.path)
        self.experiments = self._file.experiments
        self.kind = self._file.kind
        self.frame_shape = self._file.frame_shape
        self.dtype = np.dtype(self._file.dtype)
        self._bits = bits
        self._bits_limit: int | None = None
        if self.dtype.kind in "ui":
            if bits is not None and bits < 8 * self.dtype.itemsize:
                self._bits_limit = 2**bits - 1  # Mono10/12/14 in 16-bit words
            bits = bits or 8 * self.dtype.itemsize
            self.saturation: float | None = float(2**bits - 1)
        else:
            self.saturation = None
        self.notes = self._file.notes()
        self.info.update(
            kind=self.kind,
            frames_in_file=len(self),
            frame_shape=list(self.frame_shape),
            dtype=str(self.dtype),
        )

    def __len__(self) -> int:
        return len(self._file)

    def experiment_at(self, frame: int) -> tuple[Experiment | None, list[str]]:
        """The experiment the recording carries for ``frame``, and notes about it.

        Returns the last one stored from ``frame`` or before (None when there is none,
        or it cannot be read, its layout in the file included: a note says why). A change
        stored after ``frame`` gets a note naming the frame it holds from: one run uses
        one experiment.
        """
        notes: list[str] = []
        if self._file.experiment_problem is not None:
            return None, [f"{self._file.experiment_problem}; ignored"]
        in_force = [(start, text) for start, text in self.experiments if start <= frame]
        later = [start for start, _ in self.experiments if start > frame]
        if later:
            notes.append(
                f"the recording's experiment changes at frame{'s' if len(later) > 1 else ''} "
                f"{', '.join(map(str, later))}; this run used the one in force at frame "
                f"{frame} (give --frames to process after a change)"
            )
        if not in_force:
            return None, notes
        start, text = in_force[-1]
        try:
            return Experiment.from_json(text, f"{self.path} experiment (from frame {start})"), notes
        except InputError as exc:
            notes.append(f"{exc}; ignored")
            return None, notes

    def read(self, index: int) -> np.ndarray:
        """Return frame ``index`` as a new array.

        Raises
        ------
        InputError
            The frame cannot be read, or holds values beyond the recording's pixel
            format (its ``significant_bits``).
        """
        frame = self._file.read(index)
        if self._bits_limit is not None:
            top = frame.max()
            if top > self._bits_limit:
                raise InputError(
                    f"{self.path} frame {index} holds values up to {top}, beyond the "
                    f"{self._bits}-bit range of its pixel format (0..{self._bits_limit}): "
                    "the file's pixel format or significant_bits is wrong"
                )
        return frame

    def times(self, frames: range, fps_hz: float | None = None) -> FrameTimes:
        """Return the times of ``frames`` in s, from 0 at the first of them, and their rule.

        With ``fps_hz`` the times are ``(index - first) / fps_hz``; otherwise the file's
        clock by the one rule (:meth:`~holoview.acquire.frame_file.FrameFile.clock`:
        a recording's camera clock, else its host arrival times; a video's frame rate).

        Raises
        ------
        InputError
            When the file has no usable times and ``fps_hz`` is not given (the line
            says why each clock is not usable).
        """
        indices = np.asarray(frames, dtype=np.int64)
        span = f"frames {frames[0]}..{frames[-1]}" if len(frames) > 1 else f"frame {frames[0]}"
        if fps_hz is not None:
            if not (math.isfinite(fps_hz) and fps_hz > 0):
                raise InputError(f"--fps must be a positive number, got {fps_hz}")
            if not FPS_RANGE[0] <= fps_hz <= FPS_RANGE[1]:
                raise InputError(
                    f"--fps {fps_hz:g} is not a plausible frame rate "
                    f"({FPS_RANGE[0]:g} to {FPS_RANGE[1]:g} frames/s)"
                )
            note = f"frame times of {span}: --fps {fps_hz:g} (the file's own times not used)"
            times = (indices - indices[0]) / float(fps_hz)
            return FrameTimes(
                times, note, intervals=frame_intervals(times, False, self._ids(frames))
            )
        if indices.size == 1:
            return FrameTimes(np.zeros(1), f"{span}: one frame, no times needed")
        clock = self._file.clock(frames)
        if not clock.usable:
            raise InputError(f"{self.path}: {clock.note}: give --fps (frames per second)")
        times = clock.times - clock.times[0]
        intervals = frame_intervals(times, clock.source == "camera", self._ids(frames))
        return FrameTimes(times, clock.note, warning=clock.fallback, intervals=intervals)

    def _ids(self, frames: range) -> np.ndarray:
        """The camera's frame counter of ``frames`` (their indices where it has none)."""
        return np.array([self._file.frame_id(i) for i in frames], dtype=np.int64)

    def close(self) -> None:
        """Release the file."""
        self._file.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
