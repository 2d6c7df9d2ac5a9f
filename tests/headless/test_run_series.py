"""The whole run's series a window shows (headless/run_series): the series and rates
``holoview process`` gives, for the whole run and for a range of frames, by the same code."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import tifffile
from headless_sim import Simulated

from holoview.acquire.recording_reader import RecordingReader
from holoview.engine.experiment import Experiment
from holoview.errors import InputError
from holoview.headless.inputs import OpticsOptions
from holoview.headless.run import process_file
from holoview.headless.run_series import (
    CancelledError,
    SeriesRequest,
    frame_range_text,
    measure_series,
    recording_experiment,
)
from holoview.headless.settings import PeakChoice, ProcessOptions


def _process(path: Path, out: Path, frames: str | None = None):
    return process_file(path, out, ProcessOptions(frames=frames, report=None))


def test_the_whole_run_is_what_process_measures(evaporation: Simulated, tmp_path: Path) -> None:
    run = measure_series(SeriesRequest(evaporation.path))
    outcome = _process(evaporation.path, tmp_path / "out")
    np.testing.assert_array_equal(run.frames, np.arange(evaporation.frames))
    np.testing.assert_array_equal(run.times, outcome.data.times)
    assert run.labels == tuple(p.label for p in outcome.analysis.peaks)
    assert run.fit is not None and outcome.analysis.fit is not None
    assert run.fit.rate == outcome.analysis.fit.rate
    assert run.fit.stderr == outcome.analysis.fit.stderr
    np.testing.assert_array_equal(run.depths()["fused"], outcome.analysis.fused)
    # and it is the truth (the simulator's mean height), within a few standard errors
    assert abs(run.fit.rate - evaporation.rate) < 5 * run.fit.stderr + 1e-3 * abs(evaporation.rate)


def test_a_range_is_what_process_frames_a_b_measures(
    evaporation: Simulated, tmp_path: Path
) -> None:
    run = measure_series(SeriesRequest(evaporation.path))
    frames = run.frames_between(run.time_of(30), run.time_of(89))
    assert frames == range(30, 90) and frame_range_text(frames) == "30:90"
    part = measure_series(replace(run.request, frames=frame_range_text(frames)))
    outcome = _process(evaporation.path, tmp_path / "out", frames="30:90")
    assert part.fit is not None and outcome.analysis.fit is not None
    assert part.fit.rate == outcome.analysis.fit.rate
    assert part.fit.stderr == outcome.analysis.fit.stderr
    np.testing.assert_array_equal(part.frames, np.arange(30, 90))
    assert part.times[0] == 0.0
    assert run.frames_between(0.0, 0.06) is None  # two frames: no fit


def test_the_window_s_experiment_gives_the_same_series(evaporation: Simulated) -> None:
    stored, notes = recording_experiment(evaporation.path)
    assert stored is not None and stored.peaks and notes == []
    with RecordingReader(evaporation.path) as reader:
        assert stored == Experiment.from_json(reader.experiments()[0][1], where="test")
    own = measure_series(SeriesRequest(evaporation.path))
    given = measure_series(SeriesRequest(evaporation.path, stored))
    assert own.fit is not None and given.fit is not None
    assert given.fit.rate == own.fit.rate


def test_a_file_without_times_takes_the_rate_given(evaporation: Simulated, tmp_path: Path) -> None:
    with RecordingReader(evaporation.path) as reader:
        frames = reader[:]
    stack = tmp_path / "stack.tif"
    tifffile.imwrite(stack, frames)
    stored, _ = recording_experiment(evaporation.path)
    assert recording_experiment(stack) == (None, [])  # a TIFF carries none
    with pytest.raises(InputError, match=r"have no usable times .*: give --fps"):
        measure_series(SeriesRequest(stack, stored))
    assert stored is not None
    run = measure_series(SeriesRequest(stack, stored, fps_hz=10.0))
    np.testing.assert_allclose(run.times, np.arange(len(frames)) / 10.0)
    outcome = process_file(
        stack,
        tmp_path / "out",
        ProcessOptions(
            choice=PeakChoice(experiment=_saved(stored, tmp_path)),
            optics=OpticsOptions(fps_hz=10.0),
            report=None,
        ),
    )
    assert run.fit is not None and outcome.analysis.fit is not None
    assert run.fit.rate == pytest.approx(outcome.analysis.fit.rate, rel=1e-12)
    # at half the frame rate the same frames span twice the time: half the rate
    slow = measure_series(SeriesRequest(stack, stored, fps_hz=5.0))
    assert slow.fit is not None
    assert slow.fit.rate == pytest.approx(run.fit.rate / 2, rel=1e-9)


def test_no_label_is_a_clear_line(evaporation: Simulated) -> None:
    stored, _ = recording_experiment(evaporation.path)
    assert stored is not None
    with pytest.raises(InputError, match="the experiment file names no peak to process"):
        measure_series(SeriesRequest(evaporation.path, replace(stored, peaks=())))


def test_a_measurement_is_given_up_when_asked(evaporation: Simulated) -> None:
    seen: list[tuple[int, int]] = []
    with pytest.raises(CancelledError, match="given up after 5 frames"):
        measure_series(
            SeriesRequest(evaporation.path),
            progress=lambda done, total: seen.append((done, total)),
            cancelled=lambda: len(seen) >= 4,
        )
    assert seen == [(k, evaporation.frames) for k in range(1, 5)]


def _saved(experiment: Experiment, folder: Path) -> Path:
    path = folder / "experiment.json"
    experiment.save(path)
    return path
