"""Recording from the live session: a timed recording ends by itself."""

from __future__ import annotations

import time
from pathlib import Path

from holoview.acquire.recording_reader import RecordingReader
from holoview.engine.experiment import Experiment
from holoview.live.session import LiveSession, RecordRequest


def test_a_timed_recording_stops_by_itself_when_nobody_polls_its_progress(tmp_path: Path) -> None:
    options = {"shape": (128, 128), "frame_rate_hz": 60}
    path = tmp_path / "timed.h5"
    session = LiveSession.open("sim:evaporation", Experiment(), source_options=options)
    try:
        session.start_recording(RecordRequest(path, duration_s=0.5, frames=None))
        recorder = session.recorder
        assert recorder is not None
        deadline = time.monotonic() + 60
        while recorder.running and time.monotonic() < deadline:  # never asks for progress
            time.sleep(0.05)
        assert not recorder.running, "the recording went on past its duration"
        assert session.running  # the live view goes on
        progress = session.recording_progress()
        assert progress is not None and not progress.active
        assert 0.5 <= progress.elapsed_s < 30
    finally:
        session.close()
    with RecordingReader(path) as reader:
        assert len(reader) == progress.frames > 0
        assert float(reader.t_host[-1] - reader.t_host[0]) < 0.5
