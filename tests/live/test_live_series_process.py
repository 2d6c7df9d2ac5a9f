"""The live series in a process of its own: the window's lock left to the window, the series
brought back at the end, a killed process said once and started again, nothing left behind
(real processes, signals and shared memory)."""

from __future__ import annotations

import logging
import math
import os
import signal
from collections.abc import Callable
from pathlib import Path

import pytest

from holoview.live import series_pipeline
from holoview.live.session import LiveSession

from .test_live_child_work import _alive, _gone
from .test_live_waves import stored_experiment, wait_for


def test_a_killed_series_process_is_said_once_and_the_series_goes_on(
    simulate_evaporation: Callable[[int], Path],
    caplog: pytest.LogCaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(series_pipeline, "TREND_HZ", math.inf)  # reaches the process too
    recording = simulate_evaporation(60)
    session = LiveSession(
        f"replay:{recording}", stored_experiment(recording), source_options={"loop": True}
    )
    caplog.set_level(logging.WARNING, logger="holoview.live.worker")
    try:
        session.start()
        worker = session.series_worker
        assert worker.child is not None and worker.pipeline is None  # in its process
        wait_for(lambda: (t := session.trend()) is not None and len(t.times_s) >= 10)
        pid = worker.child.pid
        assert pid is not None and pid != os.getpid() and _alive(pid)
        os.kill(pid, signal.SIGKILL)
        assert _gone(pid)
        wait_for(lambda: worker.child is not None and worker.child.pid not in (None, pid))
        before = session.trend()
        wait_for(lambda: (t := session.trend()) is not before and t is not None)
        assert worker.running and session.running
        said = [m for m in session.drain_messages() if "process ended" in m]
        new_pid = worker.child.pid
        slot_name = worker._slot.name if worker._slot is not None else ""
    finally:
        session.close()
    assert len(said) == 1 and "holoview-series" in said[0] and "exit code -9" in said[0], said
    logged = [r.getMessage() for r in caplog.records if "process ended" in r.getMessage()]
    assert len(logged) == 1, logged
    assert new_pid is not None and _gone(new_pid)  # the session's close ends it
    assert slot_name and not Path("/dev/shm", slot_name).exists()
    series = session.series_worker.series  # the new process's, brought back at the end
    summary = session.summary()
    assert series is not None and summary is not None
    assert len(summary.times) == len(series.frames) >= 3
