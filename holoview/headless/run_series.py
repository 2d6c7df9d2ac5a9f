"""A recording's whole series at a glance: what ``holoview process`` measures for its trends.

A window that opens a recording shows the run's trends, rates and fits at once, not
only from the frames it has played: :func:`measure_series` measures every frame of the
file (or of ``--frames A:B``) as ``holoview process`` does for its series, by its
functions: :func:`~holoview.headless.prepare.prepare_run` settles the experiment (the
window's, or the one the recording carries), the optics and the frame times, and
chooses the peaks detected on the first usable frame;
:func:`~holoview.headless.run_passes.run_passes` (series only) measures every frame's
carrier values with the carrier probe
(:class:`~holoview.engine.frame_core.CarrierCore`, about a millisecond a 512^2 frame)
into a :class:`~holoview.engine.series.PhaseSeries` and names the peaks; then the
depths, the fused depth and the rates (:func:`~holoview.headless.analysis.analyse`).
No map and no file is written. The rate over a range of frames (a selection on the
window's trends plot) is :func:`measure_series` over that range: the rate ``holoview
process --frames A:B`` writes, by the same code.

Times in s from the first frame measured, depths in m, rates in m/s.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from holoview.engine.experiment import Experiment
from holoview.errors import HoloviewError
from holoview.headless.analysis import Analysis, analyse
from holoview.headless.inputs import InputFile, OpticsOptions, parse_frame_range
from holoview.headless.prepare import prepare_run
from holoview.headless.run_passes import run_passes
from holoview.headless.settings import PeakChoice, ProcessOptions
from holoview.processing.series.rate_fits import RateFit

logger = logging.getLogger(__name__)

__all__ = [
    "CancelledError",
    "RunSeries",
    "SeriesRequest",
    "frame_range_text",
    "measure_series",
    "recording_experiment",
]


class CancelledError(HoloviewError):
    """A measurement was given up before its end (a newer one replaces it)."""


@dataclass(frozen=True)
class SeriesRequest:
    """What to measure: a file, its peaks, its clock, its frames.

    Attributes
    ----------
    path : Path
        A holoview recording, TIFF stack, image folder, video or NumPy file.
    experiment : Experiment or None
        The labels and optics to use (a window's; as ``--experiment FILE``); None: the
        experiment the recording carries, as ``holoview process`` with no choice.
    fps_hz : float or None
        Frame rate, frames per second, replacing the file's times (``--fps``); files
        without times need it.
    frames : str or None
        ``"A:B"`` of the file's frames (``--frames``); None: every frame.
    """

    path: Path
    experiment: Experiment | None = None
    fps_hz: float | None = None
    frames: str | None = None


@dataclass(frozen=True)
class RunSeries:
    """The series of a run and what was fitted to it.

    Attributes
    ----------
    request : SeriesRequest
        What was measured.
    frames : ndarray of int, shape (N,)
        The file's frame indices measured, in order.
    times : ndarray, shape (N,)
        Their times, s, from 0 at the first.
    labels : tuple of str
        The peaks, in the order of the analysis' columns.
    analysis : Analysis
        Depths per peak, the fused depth, the rates (``analysis.fit``: the fused
        depth's line) and the notes, as ``holoview process`` reports them.
    seconds : float
        Wall time of the measurement, s.
    """

    request: SeriesRequest
    frames: np.ndarray
    times: np.ndarray
    labels: tuple[str, ...]
    analysis: Analysis
    seconds: float

    @property
    def fit(self) -> RateFit | None:
        """The fused depth's line over the run (None without a fused depth)."""
        return self.analysis.fit

    def depths(self) -> dict[str, np.ndarray]:
        """Depth change per peak with a height, then ``"fused"``, m, shape (N,) each."""
        out = {
            label: self.analysis.heights[:, j]
            for j, label in enumerate(self.labels)
            if np.any(np.isfinite(self.analysis.heights[:, j]))
        }
        if self.analysis.fused is not None:
            out["fused"] = self.analysis.fused
        return out

    def time_of(self, index: int) -> float:
        """The run's time of the file's frame ``index``, s (NaN outside the frames measured)."""
        position = int(np.searchsorted(self.frames, index))
        if position < len(self.frames) and self.frames[position] == index:
            return float(self.times[position])
        return math.nan

    def frames_between(self, t0_s: float, t1_s: float) -> range | None:
        """The file's frames whose times lie in ``[t0_s, t1_s]`` (None: fewer than three).

        Frames are consecutive in a run, so the frames are one range ``A:B``.
        """
        low, high = sorted((t0_s, t1_s))
        inside = np.flatnonzero((self.times >= low) & (self.times <= high))
        if inside.size < 3:
            return None
        return range(int(self.frames[inside[0]]), int(self.frames[inside[-1]]) + 1)


def recording_experiment(path: Path) -> tuple[Experiment | None, list[str]]:
    """The experiment ``holoview process`` applies to ``path`` when given none, and notes.

    The one a recording carries for its first frame
    (:meth:`~holoview.headless.inputs.InputFile.experiment_at`); None for a recording
    without one and for other files (TIFF stacks, folders, videos carry none).

    Raises
    ------
    InputError
        The recording cannot be read.
    """
    if not (path.is_file() and path.suffix.lower() in (".h5", ".hdf5")):
        return None, []
    with InputFile(path) as source:
        return source.experiment_at(0)


def frame_range_text(frames: range) -> str:
    """``"A:B"`` of a range of frames, as ``--frames`` takes it."""
    return f"{frames.start}:{frames.stop}"


def measure_series(
    request: SeriesRequest,
    *,
    progress: Callable[[int, int], None] | None = None,
    cancelled: Callable[[], bool] | None = None,
) -> RunSeries:
    """Measure the series of a file's frames and fit it, as ``holoview process`` does.

    Parameters
    ----------
    request : SeriesRequest
        The file, the experiment, the frame rate and the frames.
    progress : callable, optional
        ``progress(done, total)`` after each frame.
    cancelled : callable, optional
        Asked after each frame; True gives the measurement up (:class:`CancelledError`).

    Returns
    -------
    RunSeries

    Raises
    ------
    InputError
        As ``holoview process`` would for the same file, frames, rate and experiment
        (an unreadable file, no usable frame times and no rate, no labelled peak, a
        label on no detected peak, ...).
    CancelledError
        ``cancelled()`` said so.
    """
    started = time.perf_counter()
    with InputFile(request.path) as source:
        selected = parse_frame_range(request.frames, len(source))
        options = ProcessOptions(
            choice=PeakChoice(experiment=request.experiment),
            optics=OpticsOptions(fps_hz=request.fps_hz),
        )
        prepared = prepare_run(source, selected, options)

        def step(done: int, total: int) -> None:
            if cancelled is not None and cancelled():
                raise CancelledError(f"{source.path}: measurement given up after {done} frames")
            if progress is not None:
                progress(done, total)

        data, naming = run_passes(
            prepared.frames, runner=None, sink=None, progress=step, series_only=True
        )
        analysis = analyse(data, prepared.selection, prepared.optics, naming)
    return RunSeries(
        request=request,
        frames=np.asarray(data.frames).copy(),
        times=np.asarray(data.times).copy(),
        labels=tuple(p.label for p in analysis.peaks),
        analysis=analysis,
        seconds=time.perf_counter() - started,
    )
