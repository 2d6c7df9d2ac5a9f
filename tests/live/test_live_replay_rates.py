"""A replay's rate is the same at every playback speed (issue 27's rate bug).

A TIFF stack has no frame times. The live engine once timed its frames by their
arrival, so the rate scaled with the playback speed (4x gave four times the rate,
"fast" a hundred). Now each replayed frame carries its time in the recording: the
rate given (``rate_hz``), else an assumed one that the replay says is assumed. The
same frames replayed through the live engine at 1x, 4x and as fast as they read give
the rate ``holoview process --fps`` gives.
"""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile

from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.replay import DEFAULT_RATE_HZ, ReplayClock
from holoview.engine.experiment import Experiment
from holoview.headless.inputs import OpticsOptions
from holoview.headless.run import process_file
from holoview.headless.settings import PeakChoice, ProcessOptions
from holoview.live.session import LiveSession

#: The frame rate given to the replay and to ``process --fps``, frames per second.
RATE_HZ = 40.0


@pytest.fixture(scope="module")
def stack(simulate_evaporation, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A TIFF stack of 120 frames of evaporation (128 x 128), and its experiment file."""
    recording = simulate_evaporation(120)
    folder = tmp_path_factory.mktemp("stack")
    with RecordingReader(recording) as reader:
        frames = reader[:]
        stored = Experiment.from_json(reader.experiments()[-1][1], where="test")
    path = folder / "stack.tif"
    tifffile.imwrite(path, frames)
    experiment = folder / "experiment.json"
    stored.save(experiment)
    return path, experiment


def _process_rate(stack: tuple[Path, Path], tmp_path: Path, fps: float | None) -> float:
    outcome = process_file(
        stack[0],
        tmp_path / f"out-{stack[0].name}-{fps}",
        ProcessOptions(
            choice=PeakChoice(experiment=stack[1]),
            optics=OpticsOptions(fps_hz=fps),
            report=None,
        ),
    )
    assert outcome.analysis.fit is not None
    return outcome.analysis.fit.rate


def _live_rate(stack: tuple[Path, Path], **options: object) -> tuple[float, int, ReplayClock]:
    """Replay the input once through the live engine; its rate, frames in the series, clock."""
    experiment = Experiment.load(stack[1])
    session = LiveSession.open(
        f"replay:{stack[0]}",
        experiment,
        every_frame=True,
        source_options={"loop": False, "hold": False, **options},
    )
    try:
        assert session.replay is not None
        clock = session.replay.clock()
        deadline = time.monotonic() + 120
        while session.series_worker.running:  # the stream ends, the ring closes
            assert time.monotonic() < deadline, "the replay did not end"
            time.sleep(0.02)
        summary = session.summary()
    finally:
        session.close()
    assert summary is not None and summary.fit is not None
    return summary.fit.rate, len(summary.times), clock


@pytest.mark.slow
def test_a_tiff_replay_has_the_rate_of_process_at_every_speed(stack, tmp_path: Path) -> None:
    truth = _process_rate(stack, tmp_path, RATE_HZ)
    speeds = {
        "1x": {"rate_hz": RATE_HZ},
        "4x": {"rate_hz": RATE_HZ, "speed_factor": 4.0},
        "fastest": {"rate_hz": RATE_HZ, "speed": "fast"},
    }
    for name, options in speeds.items():
        rate, frames, clock = _live_rate(stack, **options)
        assert clock.text == f"{RATE_HZ:g} frames/s, given"
        assert frames >= 100, f"{name}: the series took {frames} of 120 frames"
        # before: 4x gave four times the rate, fastest a hundred times
        assert rate == pytest.approx(truth, rel=2e-3), f"{name}: {rate} against {truth}"


@pytest.mark.slow
def test_a_tiff_replay_without_a_rate_says_the_rate_it_assumes(stack, tmp_path: Path) -> None:
    rate, _, clock = _live_rate(stack, speed="fast")
    assert clock.text.startswith(
        f"{DEFAULT_RATE_HZ:g} frames/s, assumed: stack.tif carries no frame"
    )
    assert rate == pytest.approx(_process_rate(stack, tmp_path, DEFAULT_RATE_HZ), rel=2e-3)


def _write_video(path: Path, frames: np.ndarray, rate_hz: float) -> None:
    """Lossless 16-bit grey (FFV1) at ``rate_hz`` frames/s, as OpenCV writes it headless."""
    params = [cv2.VIDEOWRITER_PROP_IS_COLOR, 0, cv2.VIDEOWRITER_PROP_DEPTH, cv2.CV_16U]
    fourcc = cv2.VideoWriter_fourcc(*"FFV1")
    size = frames.shape[2:0:-1]
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, fourcc, rate_hz, size, params)
    assert writer.isOpened()
    for frame in frames:
        writer.write(frame)
    writer.release()


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["folder", "numpy", "video", "hdf5"])
def test_every_input_kind_replays_at_the_rate_of_process(
    kind: str, stack, simulate_evaporation, tmp_path: Path
) -> None:
    """Files without times take the rate given (as ``--fps``); a video its own frame rate,
    a recording its camera clock: as fast as they read, process's rate (the speeds
    between are the TIFF's test: each kind's frames reach the clock the same way)."""
    frames = tifffile.imread(stack[0])
    path = tmp_path / {"folder": "images", "numpy": "stack.npy", "video": "stack.mkv"}.get(
        kind, "rec.h5"
    )
    given: float | None = RATE_HZ
    if kind == "folder":
        path.mkdir()
        for i, frame in enumerate(frames):
            cv2.imwrite(str(path / f"img{i}.png"), frame)
    elif kind == "numpy":
        np.save(path, frames)
    elif kind == "video":
        _write_video(path, frames, 25.0)
        given = None  # the video's own frame rate
    else:
        path = simulate_evaporation(120)  # the camera's clock
        given = None
    truth = _process_rate((path, stack[1]), tmp_path, given)
    rated = {} if given is None else {"rate_hz": given}
    rate, count, clock = _live_rate((path, stack[1]), **rated, speed="fast")
    assert clock.origin == ("file" if given is None else "given"), clock.text
    assert count >= 100, f"{kind}: the series took {count} of 120 frames"
    assert rate == pytest.approx(truth, rel=2e-3), f"{kind}: {rate} against {truth}"
