"""SIGTERM, SIGHUP and Ctrl-C stop record, process and the GUI cleanly (real child processes)."""

from __future__ import annotations

import json
import os
import signal
import sys
import time
import types
import weakref
from pathlib import Path

import h5py
import numpy as np
import pytest
from faults_helpers import (
    cpu_seconds,
    finish,
    plain_h5py_frames,
    run_holoview,
    start_holoview,
    stop_signal,
    wait_for,
    write_recording,
)

from holoview.cli.signals import Stopped, deferred_signals, stop_on_signals

NUMPY = str(Path(np.__file__).parent) + os.sep  # numpy's own Python code lies below


@pytest.fixture(scope="module")
def replay_source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    frames = np.random.default_rng(2).integers(0, 4096, (50, 96, 96), dtype=np.uint16)
    return write_recording(tmp_path_factory.mktemp("signals") / "in.h5", frames)


def start_recording(source: Path, out: Path):
    child = start_holoview(
        "-q",
        "record",
        str(out),
        "--source",
        f"replay:{source}",
        "--set",
        "loop=on",
        "--set",
        "rate_hz=50",
        "--seconds",
        "60",
    )
    wait_for(lambda: out.exists() and out.stat().st_size > 200_000, what="frames on the disk")
    return child


@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP", "SIGINT"])
def test_record_stopped_by_a_signal_keeps_a_closed_file(
    replay_source: Path, tmp_path: Path, name: str
) -> None:
    out = tmp_path / "out.h5"
    child = start_recording(replay_source, out)
    stop_signal(child, name)
    done = finish(child, timeout=30)
    assert done.status == 130, done.err
    assert "Traceback" not in done.err
    assert "interrupted" in done.err
    words = done.out.replace(",", "").split()
    acquired = int(words[words.index("acquired") + 1])
    recorded = int(words[words.index("recorded") + 1])
    dropped = int(words[words.index("dropped") + 1])
    pixels, ids, _ = plain_h5py_frames(out)  # plain h5py: not left open for writing
    assert len(pixels) == recorded == acquired - dropped > 5
    np.testing.assert_array_equal(np.diff(ids) > 0, True)


def test_a_second_signal_does_not_cut_the_close_short(replay_source: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.h5"
    child = start_recording(replay_source, out)
    child.send_signal(signal.SIGTERM)
    time.sleep(0.05)
    child.send_signal(signal.SIGTERM)
    done = finish(child, timeout=30)
    # during the close the second signal waits; after it, the process is only exiting
    assert done.status in (130, -signal.SIGTERM), done.err
    assert "Traceback" not in done.err
    pixels, _, _ = plain_h5py_frames(out)
    assert len(pixels) > 5


def interrupt_process(long_stack: Path, out: Path, *extra: str):
    child = start_holoview(
        "-q",
        "process",
        str(long_stack),
        "--out",
        str(out),
        "--fps",
        "20",
        "--maps",
        "--wavelength-nm",
        "532",
        "--fluid",
        "water",
        *extra,
    )
    wait_for(lambda: out.is_dir() and any(out.glob(".results.*.partial.h5")), what="the run")
    start = cpu_seconds(child.pid)
    wait_for(lambda: cpu_seconds(child.pid) > start + 0.5, what="frames done")
    child.send_signal(signal.SIGTERM)
    return finish(child, timeout=60)


def test_process_stopped_by_sigterm_keeps_the_earlier_results(
    long_stack: Path, sim_recording: Path, tmp_path: Path
) -> None:
    out = tmp_path / "results"
    first = run_holoview("-q", "process", str(sim_recording), "--out", str(out), "--frames", ":20")
    assert first.status == 0, first.err
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    done = interrupt_process(long_stack, out, "--overwrite")
    assert done.status == 130, done.err
    assert "the earlier results" in done.err and "are kept" in done.err
    assert "Traceback" not in done.err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # no temporary left


def test_process_stopped_by_sigterm_writes_partial_results_marked(
    long_stack: Path, tmp_path: Path
) -> None:
    out = tmp_path / "results"
    done = interrupt_process(long_stack, out)
    assert done.status == 130, done.err
    assert "frames done (marked interrupted)" in done.err
    assert sorted(p.name for p in out.iterdir()) == [
        "report.png",
        "results.h5",
        "summary.json",
        "trends.csv",
    ]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["input"]["interrupted"] is True
    assert 0 < summary["frames"]["processed"] < 3000
    with h5py.File(out / "results.h5", "r") as f:
        assert bool(f.attrs["interrupted"]) is True
        assert f["trends/frame"].shape[0] == summary["frames"]["processed"]


@pytest.mark.gui
@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP"])
def test_the_window_closes_cleanly_on_a_signal(tmp_path: Path, name: str) -> None:
    experiment = tmp_path / "experiment.json"  # saved once the simulated camera is open
    child = start_holoview("live", "--quit-after", "120", "--experiment", str(experiment))
    wait_for(experiment.exists, timeout=60, what="the window on the simulated camera")
    stop_signal(child, name)
    done = finish(child, timeout=30)
    assert done.status == 130, done.err  # before: 0, as if closed by its button
    assert "Traceback" not in done.err
    assert f"{name}: closing the window" in done.err


def test_stop_signals_raise_the_interrupt_and_are_deferred_while_closing() -> None:
    with stop_on_signals(), pytest.raises(Stopped, match="SIGTERM"):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(1)  # the handler runs before this ends
    with stop_on_signals(), deferred_signals() as received:
        os.kill(os.getpid(), signal.SIGHUP)
        os.kill(os.getpid(), signal.SIGTERM)
        deadline = time.monotonic() + 1
        while len(received) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
    assert received == [signal.SIGHUP, signal.SIGTERM]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # handlers put back


class _SignalledOnCollection:
    """Sends ``signum`` to this process from its finaliser."""

    def __init__(self, signum: int) -> None:
        self.signum = signum

    def __del__(self) -> None:
        signal.raise_signal(self.signum)


def _signal_from_a_weakref_callback(signum: int) -> None:
    holder = type("Holder", (), {})()
    weakref.finalize(holder, signal.raise_signal, signum)  # called from weakref.py
    del holder


@pytest.mark.parametrize("where", ["__del__", "weakref callback"])
@pytest.mark.parametrize("name", ["SIGTERM", "SIGINT"])
def test_a_stop_signal_landing_in_a_finaliser_still_stops(where: str, name: str) -> None:
    """Raised in a finaliser, the interrupt would be printed and dropped: it comes again."""
    signum = signal.Signals[name]
    with stop_on_signals(), pytest.raises(KeyboardInterrupt) as caught:
        if where == "__del__":
            _SignalledOnCollection(signum)  # collected at once: __del__ runs here
        else:
            _signal_from_a_weakref_callback(signum)
        deadline = time.monotonic() + 2
        while time.monotonic() < deadline:
            time.sleep(0.005)
    assert isinstance(caught.value, Stopped) == (name != "SIGINT")
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # handlers put back


def test_a_stop_signal_landing_in_numpy_still_stops() -> None:
    """numpy's C code turns what its Python helpers raise into its own errors: the interrupt
    raised there would be a ``TypeError`` (seen: SIGTERM during a Dask run, in
    ``_promote_fields`` under ``np.unique``, exit 1). It is raised again outside numpy."""
    a = np.zeros(3, dtype=[("x", np.int64), ("y", np.float64)])
    b = np.zeros(3, dtype=[("x", np.float64), ("y", np.float64)])
    entered: list[str] = []

    def in_numpy(frame: types.FrameType, event: str, arg: object) -> None:
        """The stop signal's handler, run in the first Python helper numpy's C code calls."""
        if event == "call" and not entered and frame.f_code.co_filename.startswith(NUMPY):
            entered.append(frame.f_code.co_name)
            handler = signal.getsignal(signal.SIGTERM)
            assert callable(handler)
            handler(signal.SIGTERM, frame)

    with stop_on_signals(), pytest.raises(Stopped, match="SIGTERM"):
        sys.setprofile(in_numpy)
        try:
            equal = a == b  # a structured comparison: numpy promotes the fields in Python
        finally:
            sys.setprofile(None)
        assert entered, "numpy's C code called no Python helper"
        assert equal.all()
        deadline = time.monotonic() + 2
        while time.monotonic() < deadline:
            time.sleep(0.005)
