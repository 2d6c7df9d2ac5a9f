"""The live mean-phase series: every frame's carrier values, depths and rates for the trends view.

The series worker (:class:`holoview.live.worker.SeriesWorker`) runs a
:class:`SeriesPipeline` on *every* frame from the camera: the carrier probe
(:class:`holoview.engine.frame_core.CarrierCore`, a quarter of a full FFT's time) gives
each peak's value, a :class:`holoview.engine.series.PhaseSeries` keeps them, and at
most :data:`TREND_HZ` times a second :func:`holoview.engine.series.summarise` (what
``holoview process`` runs) gives the depths, the fused depth and the rate. So the
series, its temporal unwrapping and the rates use every frame while the maps take the
newest frame at whatever rate is left. The series is estimated jointly over the peaks
the lattice places (:meth:`holoview.engine.series.PhaseSeries.track_joint`), frame by
frame as ``holoview process`` does over a file. The peaks come from the maps pipeline
(the demodulator's, :meth:`set_peaks`); a new set of peaks starts a new series, and
so does a replay's jump (:mod:`holoview.live.continuity`): no rate is fitted across it.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from holoview.acquire.source import FrameMeta
from holoview.engine.depth import DepthSummary, pca_check, summarise
from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import CarrierCore
from holoview.engine.series import LIVE_LENGTH, JointSetup, PhaseSeries, frame_time
from holoview.errors import HoloviewError
from holoview.live.continuity import Continuity
from holoview.processing.peaks.detection import Peak

logger = logging.getLogger(__name__)

__all__ = ["COMMANDS", "TREND_HZ", "SeriesPipeline", "TrendSummary", "trend_summary"]

#: Highest rate at which depths, rate and PCA are recomputed from the series, Hz.
TREND_HZ = 2.0
#: The commands a series takes between frames (:meth:`SeriesPipeline.apply`).
COMMANDS = ("pca", "reset")


@dataclass(frozen=True)
class TrendSummary:
    """What the trends view draws: depth series by label (and ``fused``), rate, PCA.

    Times in s from the series' first frame, depths in m, rates in m/s. ``segment``:
    the replay segment the series belongs to (:mod:`holoview.live.continuity`); a
    summary with no depth starts a segment's series.
    """

    seq: int
    times_s: np.ndarray
    depths_m: dict[str, np.ndarray]
    rate_m_per_s: float | None
    rate_stderr_m_per_s: float | None
    rate_fit: tuple[list[float], list[float]] | None
    pca_confidence: float | None = None
    pca_prefactors: dict[str, float] | None = None
    segment: int = 0


def trend_summary(
    seq: int,
    summary: DepthSummary,
    labels: tuple[str, ...],
    pca: dict[str, Any] | None,
    segment: int = 0,
) -> TrendSummary:
    """Pack a series' :class:`~holoview.engine.series.DepthSummary` for the trends view."""
    depths = {
        k: summary.heights[:, j]
        for j, k in enumerate(labels)
        if np.any(np.isfinite(summary.heights[:, j]))
    }
    if summary.fused is not None:
        depths["fused"] = summary.fused
    fit, line = summary.fit, None
    if fit is not None:
        ends = [float(summary.times[0]), float(summary.times[-1])]
        line = (ends, [fit.intercept + fit.rate * t for t in ends])
    return TrendSummary(
        seq=seq,
        times_s=summary.times,
        depths_m=depths,
        rate_m_per_s=None if fit is None else fit.rate,
        rate_stderr_m_per_s=None if fit is None else fit.stderr,
        rate_fit=line,
        pca_confidence=None if pca is None else float(pca["confidence"]),
        pca_prefactors=None if pca is None else dict(pca["prefactors"]),
        segment=segment,
    )


class SeriesPipeline:
    """Turn every frame into a point of the series; summarise it for the trends view.

    Used by one thread at a time. Commands (:meth:`apply`): ``pca`` (bool), ``reset``
    (a new series from the next frame).

    Parameters
    ----------
    frame_shape : tuple of int
        ``(rows, cols)`` of the frames, pixels.
    saturation : float, optional
        Raw value at which the camera saturates.
    trend_hz : float, optional
        Highest rate of the trends' summaries (:data:`TREND_HZ` when None, as it is when
        a frame comes).
    """

    def __init__(
        self,
        frame_shape: tuple[int, int],
        saturation: float | None = None,
        trend_hz: float | None = None,
    ) -> None:
        self.trend_hz = trend_hz
        self.carriers = CarrierCore(frame_shape, saturation)
        self.series: PhaseSeries | None = None
        self.pca = False
        self.experiment: Experiment | None = None
        self._seq = 0
        self._trend_at = -math.inf
        self._continuity = Continuity()

    def apply(self, name: str, value: object = None) -> None:
        """Apply a command: ``pca`` (bool) or ``reset``."""
        if name not in COMMANDS:
            raise ValueError(f"unknown series command {name!r}")
        if name == "pca":
            self.pca = bool(value)
            self._trend_at = -math.inf
        else:  # reset
            self.series = None

    def set_peaks(self, peaks: tuple[Peak, ...], experiment: Experiment) -> None:
        """Measure ``peaks`` from the next frame (a new series when they or the optics changed)."""
        optics = (experiment.wavelength_m, experiment.n1, experiment.n2)
        if (
            self.carriers.configure(peaks)
            or self.experiment is None
            or optics
            != (
                self.experiment.wavelength_m,
                self.experiment.n1,
                self.experiment.n2,
            )
        ):
            self.series = None
        self.experiment = experiment

    def process(self, frame: np.ndarray, meta: FrameMeta) -> TrendSummary | None:
        """Add ``frame`` to the series; return a new summary when one is due, else None.

        A frame of another segment than the last (a replay jumped) starts a new series,
        and an empty summary is returned at once (the trends view clears).

        Raises
        ------
        HoloviewError
            A frame of another shape or type (the message names it).
        """
        broken = self._continuity.breaks(meta)
        if broken:
            self.series = None
        measured = self.carriers.measure(frame)
        if measured is None:
            return None
        if self.series is None:
            self.series = self._new_series()
        before = self.series.frames  # the camera's counter says how many were lost
        intervals = int(meta.frame_id - before[-1]) if before.size else 1
        self.series.add(
            frame_time(meta.t_device, meta.t_host), meta.frame_id, measured, intervals=intervals
        )
        if broken:
            self._seq += 1
            self._trend_at = time.monotonic()
            empty = np.empty(0)
            return TrendSummary(self._seq, empty, {}, None, None, None, segment=meta.segment)
        now = time.monotonic()
        if now - self._trend_at < 1.0 / (self.trend_hz or TREND_HZ):
            return None
        self._trend_at = now
        return self.trend()

    def _new_series(self) -> PhaseSeries:
        """An empty series of the current peaks, estimated jointly where the lattice allows."""
        peaks = self.carriers.peaks
        series = PhaseSeries(
            [p.label or f"P{j}" for j, p in enumerate(peaks)], max_length=LIVE_LENGTH
        )
        e = self.experiment
        if e is not None:
            JointSetup.of(
                [p.label for p in peaks],
                [p.alpha for p in peaks],
                wavelength_m=e.wavelength_m,
                n1=e.n1,
                n2=e.n2,
            ).track(series)
        return series

    def summary(self) -> DepthSummary | None:
        """Depths and rates of the series so far (None before a wavelength or a frame)."""
        e = self.experiment
        if self.series is None or e is None or e.wavelength_m is None or len(self.series) == 0:
            return None
        return summarise(self.series, [p.alpha for p in self.carriers.peaks], e.wavelength_m)

    def trend(self) -> TrendSummary | None:
        """The trends view's summary; None before three frames of the current peaks."""
        if self.series is None or len(self.series) < 3:
            return None
        try:
            summary = self.summary()
        except HoloviewError as exc:
            logger.debug("trends not available: %s", exc)
            return None
        if summary is None:
            return None
        pca = None
        if self.pca:
            alphas = [p.alpha for p in self.carriers.peaks]
            pca = pca_check(summary.phases, self.series.labels, alphas)
        self._seq += 1
        return trend_summary(
            self._seq, summary, self.series.labels, pca, segment=self._continuity.segment or 0
        )
