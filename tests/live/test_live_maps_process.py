"""The live maps in a process of their own: the same series, a killed process said once and
started again, nothing left behind (real processes, signals and shared memory)."""

from __future__ import annotations

import logging
import os
import signal
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from holoview.live.session import LiveSession

from .test_live_child_work import _alive, _gone
from .test_live_waves import stored_experiment, wait_for


def test_a_killed_maps_process_is_said_once_and_the_maps_go_on(
    simulate_evaporation: Callable[[int], Path], caplog: pytest.LogCaptureFixture
) -> None:
    recording = simulate_evaporation(60)
    session = LiveSession(
        f"replay:{recording}", stored_experiment(recording), source_options={"loop": True}
    )
    caplog.set_level(logging.WARNING, logger="holoview.live.worker")
    try:
        session.start()
        worker = session.worker
        assert worker.child is not None and worker.server is None  # in its process
        wait_for(lambda: (r := worker.latest()) is not None and r.seq >= 10)
        pid = worker.child.pid
        assert pid is not None and _alive(pid)
        os.kill(pid, signal.SIGKILL)
        assert _gone(pid)
        wait_for(lambda: worker.child is not None and worker.child.pid not in (None, pid))
        latest = worker.latest()
        assert latest is not None
        wait_for(lambda: (r := worker.latest()) is not None and r.seq >= 10 and r is not latest)
        assert worker.latest().heights_m  # a new process's maps, every peak's
        assert worker.running and session.running
        said = [m for m in session.drain_messages() if "process ended" in m]
        new_pid = worker.child.pid
        slot_name = worker._slot.name if worker._slot is not None else ""
    finally:
        session.close()
    assert len(said) == 1 and "holoview-maps" in said[0] and "exit code -9" in said[0], said
    logged = [r.getMessage() for r in caplog.records if "process ended" in r.getMessage()]
    assert len(logged) == 1, logged
    assert new_pid is not None and _gone(new_pid)  # the session's close ends it
    assert slot_name and not Path("/dev/shm", slot_name).exists()


def test_a_display_spectrum_comes_once_from_the_maps_process_and_is_shared_after(
    simulate_evaporation: Callable[[int], Path],
) -> None:
    """The display spectrum is made at most SPECTRUM_HZ times a second, the maps at the
    camera's rate: results that keep a spectrum share the one array the window drew (each
    sent again had been unpickled into a new one, which the window took for a new
    spectrum and drew again, ten times more often than there were spectra)."""
    recording = simulate_evaporation(60)
    session = LiveSession(
        f"replay:{recording}", stored_experiment(recording), source_options={"loop": True}
    )
    results = {}
    try:
        session.start()
        worker = session.worker
        assert worker.child is not None  # the maps in their process
        wait_for(lambda: (r := worker.latest()) is not None and r.spectrum is not None)
        while len(results) < 40:
            wait_for(lambda: (r := worker.latest()) is not None and r.seq not in results)
            latest = worker.latest()
            results[latest.seq] = latest
    finally:
        session.close()
    spectra = [r.spectrum for r in results.values() if r.spectrum is not None]
    assert len(spectra) >= 39
    distinct: list = []
    for spectrum in spectra:
        same = [s for s in distinct if s.shape == spectrum.shape and np.array_equal(s, spectrum)]
        if same:
            assert spectrum is same[0]  # the same spectrum is the same array
        else:
            distinct.append(spectrum)
    assert len(distinct) < len(spectra) / 2, (len(distinct), len(spectra))
