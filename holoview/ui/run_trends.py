"""A replayed file's whole run in the trends view: measured in the background, a cursor, fits.

When the window replays a file, :class:`RunTrends` measures the file's whole series on
a thread (:func:`holoview.headless.run_series.measure_series`: what ``holoview
process`` measures for its trends, by the same code), shows its progress while the
window stays usable, and then draws every peak's depth, the fused depth and the run's
rate at once. The frame the replay shows is a cursor on them (dragging the cursor asks
the replay for that frame); seeking, stepping and looping never discard the run. A
time range chosen on the plot is fitted on another thread by the same function over
those frames: the rate ``holoview process --frames A:B`` gives. A change of labels or
of the file's frame rate measures the run again; a newer measurement replaces one
under way. Where the run cannot be measured (no labelled peak, a label on no detected
peak), the view shows the live series of the frames as they are played.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path
from typing import cast

import numpy as np
from PyQt6.QtCore import QObject, pyqtSignal

from holoview.engine.experiment import Experiment
from holoview.headless.run_series import (
    RunSeries,
    SeriesRequest,
    frame_range_text,
    measure_series,
)
from holoview.live.replay_control import ReplayState
from holoview.live.side_workers import YIELDING_NICENESS
from holoview.processing.series.rate_fits import format_rate
from holoview.ui.background import LatestCall
from holoview.ui.trends_view import MEASURING, NO_TRENDS, TrendsView

logger = logging.getLogger(__name__)

_EMPTY = np.empty(0)


class RunTrends(QObject):
    """The whole run of the replayed file in a :class:`TrendsView`.

    Parameters
    ----------
    view : TrendsView
        Where the run is drawn.
    parent : QObject
        The owner (the main window).

    Signals
    -------
    message(str)
        A problem, in one line (for the banner).
    seekRequested(int)
        The operator dragged the cursor to the file's frame of this index.
    """

    message = pyqtSignal(str)
    seekRequested = pyqtSignal(int)

    def __init__(self, view: TrendsView, parent: QObject) -> None:
        super().__init__(parent)
        self.view = view
        self.path: Path | None = None
        #: The run measured (None before its measurement ends, or without a replay).
        self.series: RunSeries | None = None
        #: The range fitted last (None: none asked for or done).
        self.range_series: RunSeries | None = None
        self._request: SeriesRequest | None = None
        self._clock = ""
        self._problem: str | None = None
        self._cursor_index = -1
        nice = YIELDING_NICENESS
        self.runs = LatestCall("holoview-run-series", "holoview-run-series", self, niceness=nice)
        self.ranges = LatestCall("holoview-range-fit", "holoview-range-fit", self, niceness=nice)
        self.runs.done.connect(self._measured)
        self.ranges.done.connect(self._range_fitted)
        view.rangeChosen.connect(self.fit_range)
        view.rangeCleared.connect(self._range_cleared)
        view.cursorMoved.connect(self._cursor_dragged)
        view.pcaRequested.connect(self._show_pca)

    @property
    def active(self) -> bool:
        """True while the window replays a file."""
        return self.path is not None

    @property
    def showing(self) -> bool:
        """True while the view shows the run (measured or being measured), not the live series."""
        return self.active and self._problem is None

    # ---- the file ----------------------------------------------------------
    def attach(
        self,
        path: Path | None,
        experiment: Experiment | None = None,
        fps_hz: float | None = None,
        clock: str = "",
    ) -> None:
        """Show the run of the file at ``path`` (None: no replay, the live series).

        Parameters
        ----------
        path : Path or None
            The file replayed.
        experiment : Experiment, optional
            The labels and optics in force.
        fps_hz : float, optional
            The frame rate that times the frames (None: the file's own times).
        clock : str
            What times the frames, in words (for the rate's caption).
        """
        self.runs.cancel()
        self.ranges.cancel()
        self.path, self.series, self.range_series = path, None, None
        self._request, self._problem, self._clock = None, None, clock
        self._cursor_index = -1
        self.view.set_range_fit(None)
        self.view.set_run_mode(path is not None)
        if path is not None and experiment is not None:
            self._measure(SeriesRequest(path, experiment, fps_hz))

    def set_experiment(self, experiment: Experiment) -> None:
        """Measure the run again when the labels or optics changed (not for the maps' settings)."""
        if self._request is None or not self.active:
            return
        old = self._request.experiment
        if old is not None and _series_settings(old) == _series_settings(experiment):
            return
        self._measure(replace(self._request, experiment=experiment))

    def set_clock(self, fps_hz: float | None, clock: str) -> None:
        """Measure the run again when the frame rate that times it changed."""
        self._clock = clock
        if self._request is not None and self._request.fps_hz != fps_hz:
            self._measure(replace(self._request, fps_hz=fps_hz))

    def _measure(self, request: SeriesRequest) -> None:
        self._request, self._problem, self.series = request, None, None
        self.ranges.cancel()
        self.view.set_run_mode(True)
        self.view.set_range_fit(None)
        self.view.set_rate(None, caption="whole run")
        self.view.set_pca(None, None)
        if request.experiment is None or not request.experiment.peaks:
            self.runs.cancel()
            self.view.set_progress(None)
            self.view.set_series(_EMPTY, {}, hint=NO_TRENDS)
            return
        self.view.set_series(_EMPTY, {}, hint=MEASURING)
        self.view.set_progress(0, 1, "measuring the run:")
        self.runs.start(
            lambda progress, cancelled: measure_series(
                request, progress=progress, cancelled=cancelled
            )
        )

    def close(self) -> None:
        """Give up any measurement and join its thread."""
        self.runs.wait()
        self.ranges.wait()
        self.path = None

    # ---- drawing -----------------------------------------------------------
    def refresh(self, index: int) -> None:
        """Draw the progress, and the cursor at the file's frame ``index`` (from the redraw)."""
        progress = self.runs.progress()
        if progress is not None:
            self.view.set_progress(progress[0], progress[1], "measuring the run:")
        if self.series is not None and index != self._cursor_index:
            self._cursor_index = index
            self.view.set_cursor(self.series.time_of(index))

    def _measured(self, outcome: object) -> None:
        self.view.set_progress(None)
        if not isinstance(outcome, RunSeries):
            self._problem = f"the whole run's trends cannot be measured: {outcome}"
            self.view.set_run_mode(False)
            self.view.set_series(_EMPTY, {})
            self.message.emit(self._problem)
            return
        self.series = outcome
        self._cursor_index = -1
        fit = outcome.fit
        times = outcome.times
        self.view.set_series(times, outcome.depths())
        clock = self._clock or "the file's clock"
        given = outcome.request.fps_hz is not None  # a rate given or assumed: said
        caption = f"whole run, {clock.split(':')[0]}" if given else "whole run"
        peaks = "\n".join(
            f"{p.label}: {format_rate(p.rate, p.rate_stderr)}"
            for p in outcome.analysis.peaks
            if p.rate is not None
        )
        self.view.rate_label.setToolTip(
            f"every frame of {outcome.request.path.name}: {len(times)} frames, "
            f"{times[0]:.3f} to {times[-1]:.3f} s; frame times: {clock}\n"
            f"the fused depth's rate; each peak's:\n{peaks}"
        )
        line = None
        if fit is not None:
            ends = [float(times[0]), float(times[-1])]
            line = (ends, [fit.intercept + fit.rate * t for t in ends])
        self.view.set_rate(
            None if fit is None else fit.rate,
            None if fit is None else fit.stderr,
            line,
            caption=caption,
        )
        self._show_pca(self.view.pca_box.isChecked())
        logger.info("%s: whole run measured in %.2f s", self.path, outcome.seconds)
        chosen = self.view.chosen_range()
        if chosen is not None:
            self.fit_range(*chosen)

    def _show_pca(self, on: bool) -> None:
        """The run's temporal PCA (what ``holoview process`` reports), or nothing."""
        if not self.showing or self.series is None:
            return
        pca = self.series.analysis.pca
        if not on or pca is None:
            self.view.set_pca(None, None)
            return
        prefactors = cast(dict[str, float], pca["prefactors"])
        self.view.set_pca(float(cast(float, pca["confidence"])), prefactors)

    # ---- the cursor and the range -----------------------------------------
    def index_at(self, time_s: float) -> int | None:
        """The file's frame nearest the run's time ``time_s`` (None before the run is known)."""
        if self.series is None or not len(self.series.times):
            return None
        position = int(np.argmin(np.abs(self.series.times - time_s)))
        return int(self.series.frames[position])

    def _cursor_dragged(self, time_s: float) -> None:
        index = self.index_at(time_s)
        if index is not None and index != self._cursor_index:
            self._cursor_index = index
            self.seekRequested.emit(index)

    def fit_range(self, t0_s: float, t1_s: float) -> None:
        """Fit the rate over the run's frames between ``t0_s`` and ``t1_s`` (s), on a thread."""
        series, request = self.series, self._request
        if series is None or request is None:
            return  # fitted when the run is known
        frames = series.frames_between(t0_s, t1_s)
        if frames is None:
            self.ranges.cancel()
            self.view.set_range_fit("choose a range of at least three frames")
            return
        wanted = replace(request, frames=frame_range_text(frames))
        if self.range_series is not None and self.range_series.request == wanted:
            return
        self.view.set_range_fit(f"frames {frame_range_text(frames)}: fitting...")
        self.ranges.start(
            lambda progress, cancelled: measure_series(
                wanted, progress=progress, cancelled=cancelled
            )
        )

    def _range_fitted(self, outcome: object) -> None:
        series = self.series
        if not isinstance(outcome, RunSeries) or series is None:
            self.view.set_range_fit(f"the range cannot be fitted: {outcome}")
            return
        self.range_series = outcome
        frames = outcome.request.frames or ""
        fit = outcome.fit
        if fit is None:
            self.view.set_range_fit(f"frames {frames}: no fused depth to fit")
            return
        start = series.time_of(int(outcome.frames[0]))
        end = start + float(outcome.times[-1])
        fused = series.analysis.fused
        offset = 0.0
        if fused is not None:
            offset = float(fused[int(np.searchsorted(series.frames, outcome.frames[0]))])
        line = (
            [start, end],
            [offset + fit.intercept, offset + fit.intercept + fit.rate * (end - start)],
        )
        command = f"holoview process {outcome.request.path.name} --frames {frames}"
        if outcome.request.fps_hz is not None:
            command += f" --fps {outcome.request.fps_hz:g}"
        self.view.set_range_fit(
            f"frames {frames} ({start:.2f}-{end:.2f} s): {format_rate(fit.rate, fit.stderr)}",
            line,
        )
        self.view.range_label.setToolTip(f"the rate {command} gives (the same measurement)")

    def _range_cleared(self) -> None:
        self.ranges.cancel()
        self.range_series = None


def maps_frame_text(state: ReplayState, maps_index: int) -> str:
    """Which frame the maps show, and how far behind the frame shown they are, playing.

    The maps worker takes the newest frame at whatever rate is left: at 8x the maps may
    lag the replay; this says so instead of passing an older frame's maps off as the
    frame shown ('' before any map).
    """
    if maps_index < 0:
        return ""
    behind = (state.index - maps_index) % max(1, state.n_frames)
    if state.paused or behind <= 1:
        return f"maps of frame {maps_index}"
    return f"maps of frame {maps_index} ({behind} behind)"


def _series_settings(experiment: Experiment) -> Experiment:
    """The experiment without the settings that change only the maps (reference, unwrapping)."""
    return replace(experiment, reference="relative", unwrap="auto")
