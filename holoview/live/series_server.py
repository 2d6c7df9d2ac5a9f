"""The live series, made in a process of its own.

The series takes every camera frame: at 1024^2 and 60 frames/s with six peaks its carrier
probe, joint estimate and twice-a-second summaries are some 6 ms of CPU a frame, much of
it in Python. On a thread of the window's process it held the interpreter's lock as
long as the window's own thread did: ``benchmarks/bench_gui.py`` (2 cores, AVX2) gave the
window's process exactly one core, the GUI thread 49 %, the series 38 %, the camera and
the maps' hand-over the rest, and the display 13.7 Hz. In a process of its own the series
takes its time from the cores, not from the window's lock.

The series worker (:class:`~holoview.live.worker.SeriesWorker`) reads each frame from the
ring straight into shared memory (:class:`~holoview.live.wave_map.FrameSlot`) and sends a
:class:`SeriesJob` (the frame's metadata, the peaks when they changed, the commands posted
since the last frame); :class:`SlotSeries`, the child's work, runs the
:class:`~holoview.live.series_pipeline.SeriesPipeline` on it and sends back the trends'
summary when one is due. When the thread ends, a last job brings the series and its
summary back (:class:`SeriesReply`), for the session's :meth:`summary`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from holoview.acquire.source import FrameMeta
from holoview.engine.depth import DepthSummary
from holoview.engine.experiment import Experiment
from holoview.engine.series import PhaseSeries
from holoview.errors import HoloviewError
from holoview.live.series_pipeline import SeriesPipeline, TrendSummary
from holoview.live.wave_map import SharedFrames
from holoview.processing.peaks.detection import Peak

__all__ = ["SeriesJob", "SeriesReply", "SlotSeries"]


@dataclass(frozen=True)
class SeriesJob:
    """One frame for the series (in the shared block), or the end of the run.

    Attributes
    ----------
    meta : FrameMeta or None
        The frame's metadata; None asks for the series instead (the run ended).
    peak_set : tuple or None
        The maps' peaks and experiment, when they changed since the last job.
    commands : tuple
        ``pca`` and ``reset`` commands posted since the last frame, applied before it.
    """

    meta: FrameMeta | None
    peak_set: tuple[tuple[Peak, ...], Experiment] | None = None
    commands: tuple[tuple[str, Any], ...] = ()


@dataclass(frozen=True)
class SeriesReply:
    """What the series sends back.

    Attributes
    ----------
    trend : TrendSummary or None
        For a frame: the trends' summary when one was due.
    series : PhaseSeries or None
        At the end: the series so far.
    summary : DepthSummary or None
        At the end: its depths and rates (None before a wavelength or three frames).
    problem : str or None
        At the end: why there is no summary, where the series could not be summarised.
    """

    trend: TrendSummary | None = None
    series: PhaseSeries | None = None
    summary: DepthSummary | None = None
    problem: str | None = None


class SlotSeries:
    """The series process's work: a :class:`SeriesPipeline` on the frames of a shared block.

    Made in the child; called with each job once the window's process has put the frame
    in the block's one place.
    """

    def __init__(self, frames: SharedFrames, saturation: float | None, trend_hz: float) -> None:
        self._memory, self._frames = frames.attach()
        self.pipeline = SeriesPipeline(frames.shape, saturation=saturation, trend_hz=trend_hz)

    def __call__(self, job: SeriesJob) -> SeriesReply:
        for name, value in job.commands:
            self.pipeline.apply(name, value)
        if job.peak_set is not None:
            self.pipeline.set_peaks(*job.peak_set)
        if job.meta is None:
            try:
                summary = self.pipeline.summary()
            except HoloviewError as exc:
                return SeriesReply(series=self.pipeline.series, problem=str(exc))
            return SeriesReply(series=self.pipeline.series, summary=summary)
        return SeriesReply(trend=self.pipeline.process(self._frames[0], job.meta))
