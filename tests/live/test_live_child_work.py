"""Side work in a child process (:class:`holoview.live.child_work.ChildWork`): real
processes, real signals; results, errors and the child's end as a side thread's would be."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FrameCore
from holoview.engine.window_matching import MatchJob, WindowMatcher, windows_in_use
from holoview.errors import HoloviewError
from holoview.live.child_work import ChildWork
from holoview.live.side_workers import MatchWorker

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "processing"))
from wavy_scene import render, travelling_waves, true_peaks, wavy_setup  # noqa: E402


def _counting() -> Callable[[object], object]:
    """A work with state kept in the child: each job's result says the child and its count."""
    seen: list[object] = []

    def work(job: object) -> object:
        if job == "input":
            raise HoloviewError("the job names no frame")
        if job == "bug":
            raise ZeroDivisionError("a bug in the work")
        seen.append(job)
        return os.getpid(), len(seen), os.getpriority(os.PRIO_PROCESS, 0)

    return work


def _alive(pid: int) -> bool:
    try:  # gone between the two looks: not alive either
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def _gone(pid: int, seconds: float = 10.0) -> bool:
    deadline = time.monotonic() + seconds
    while _alive(pid):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def _slow_to_start() -> Callable[[object], object]:
    """A work that takes a second to make (imports, buffers), then counts as above."""
    time.sleep(1.0)
    return _counting()


def test_the_child_says_when_it_is_ready() -> None:
    """A live session starts its camera once the maps' process is ready (a second or two),
    so that no frame waits in the ring meanwhile: the wait is bounded and says whether."""
    work = ChildWork(_slow_to_start, "holoview-test", niceness=0)
    try:
        work.start()
        assert not work.wait_ready(0.01)  # still making its work
        assert work.wait_ready(60)
        assert work.wait_ready(0.0)  # said once, known since
        assert work("a")[1] == 1  # the first job's result, not the "ready"
    finally:
        work.close()
    with pytest.raises(HoloviewError, match="holoview-test was stopped"):
        work.wait_ready(1.0)


def test_jobs_run_in_one_child_that_keeps_its_state_at_a_lower_priority() -> None:
    work = ChildWork(_counting, "holoview-test", niceness=3)
    try:
        first = work("a")
        second = work("b")
    finally:
        work.close()
    assert first[0] == second[0] != os.getpid()  # one child, not this process
    assert (first[1], second[1]) == (1, 2)  # its state kept between jobs
    assert first[2] == min(os.getpriority(os.PRIO_PROCESS, 0) + 3, 19)
    assert _gone(first[0])
    with pytest.raises(HoloviewError, match="holoview-test was stopped"):
        work("c")


def test_errors_come_back_as_the_thread_s_would() -> None:
    work = ChildWork(_counting, "holoview-test", niceness=0)
    try:
        with pytest.raises(HoloviewError, match="the job names no frame"):
            work("input")
        with pytest.raises(RuntimeError, match="ZeroDivisionError: a bug in the work"):
            work("bug")
        assert work("a")[1] == 1  # the same child goes on
    finally:
        work.close()


def test_a_killed_child_is_said_once_and_started_again() -> None:
    work = ChildWork(_counting, "holoview-test", niceness=0)
    try:
        pid = work("a")[0]
        os.kill(pid, signal.SIGKILL)
        assert _gone(pid)
        with pytest.raises(HoloviewError, match=r"process ended \(exit code -9\); it starts again"):
            work("b")
        again = work("c")
        assert again[0] != pid and again[1] == 1  # a new child, its state new
    finally:
        work.close()


def _summing() -> Callable[[np.ndarray], float]:
    def work(job: np.ndarray) -> float:
        return float(np.sum(job, dtype=np.float64))

    return work


def test_closing_during_a_job_s_sending_leaves_the_pipe_whole(capfd) -> None:
    """The window closes while a frame is on its way to the child, written in pieces as a
    pipe takes it from a slow reader (niced on a busy machine): the message to stop goes
    after the frame, not between its pieces (before: the child read garbage and printed
    an unpickling traceback as the window closed, seen in four window tests)."""
    work = ChildWork(_summing, "holoview-test", niceness=0)
    assert work(np.ones(3)) == 3.0  # the child started
    pid, conn = work.pid, work._conn
    assert pid is not None and conn is not None
    whole = conn._send  # type: ignore[attr-defined]

    def in_pieces(buf: bytes) -> None:  # what a full pipe does to a large write
        view = memoryview(buf)
        for start in range(0, len(view), 1 << 16):
            whole(view[start : start + (1 << 16)])
            time.sleep(0.002)

    conn._send = in_pieces  # type: ignore[attr-defined]
    frame = np.random.default_rng(1).random(1_000_000)  # 8 MB: 123 pieces
    outcome: list[object] = []

    def call() -> None:
        try:
            outcome.append(work(frame))
        except HoloviewError as exc:
            outcome.append(str(exc))

    caller = threading.Thread(target=call)
    caller.start()
    time.sleep(0.05)  # the frame half sent
    work.close()
    caller.join(30)
    # the frame's own sum (read whole), or dropped at the stop: never garbage
    assert outcome in ([float(np.sum(frame))], ["holoview-test was stopped"]), outcome
    assert _gone(pid)
    assert "Traceback" not in capfd.readouterr().err


def _sleeping() -> Callable[[float], float]:
    def work(job: float) -> float:
        time.sleep(job)
        return job

    return work


def test_closing_while_the_child_works_says_stopped_at_once() -> None:
    """A measurement under way when the window closes is dropped: the waiting thread is
    told "stopped", also when the pipe's end was closed under it between two reads (its
    second read here comes after the close; before: a TypeError logged as a bug)."""
    for late in (False, True):
        work = ChildWork(_sleeping, "holoview-test", niceness=0)
        assert work(0.0) == 0.0
        if late:  # the waiting thread reads only after the close
            conn = work._conn
            assert conn is not None
            reading = conn._recv  # type: ignore[attr-defined]
            conn._recv = lambda size, read=reading: time.sleep(1.5) or read(size)  # type: ignore[attr-defined]
        outcome: list[object] = []

        def call(work: ChildWork = work, outcome: list[object] = outcome) -> None:
            try:
                outcome.append(work(30.0))
            except HoloviewError as exc:
                outcome.append(str(exc))

        caller = threading.Thread(target=call)
        caller.start()
        time.sleep(0.2)
        start = time.monotonic()
        work.close()
        assert time.monotonic() - start < 3.0
        caller.join(30)
        assert outcome == ["holoview-test was stopped"]


def _run(script: Path) -> subprocess.CompletedProcess[str]:
    """Run ``script`` in a Python of its own (the window's process), its output kept."""
    return subprocess.run(
        [sys.executable, str(script)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
        check=False,
    )


def test_the_child_ends_with_the_process_that_started_it(tmp_path: Path) -> None:
    """A window killed outright (no exit handler runs) leaves no matcher behind."""
    script = tmp_path / "parent.py"
    script.write_text(
        textwrap.dedent(
            f"""
            import os, sys
            sys.path.insert(0, {str(Path(__file__).parent)!r})
            from test_live_child_work import _counting
            from holoview.live.child_work import ChildWork
            if __name__ == "__main__":
                work = ChildWork(_counting, "holoview-test", niceness=0)
                print(work("a")[0], flush=True)
                os.kill(os.getpid(), 9)
            """
        )
    )
    done = _run(script)
    assert done.returncode == -signal.SIGKILL, done.stderr
    assert _gone(int(done.stdout.split()[0]))


def test_starting_a_child_does_not_wait_for_it_to_start_python(tmp_path: Path) -> None:
    """The window's thread starts the Waves map's process when the panel opens: its FFT
    wisdom (75 KB after a session's plans) went with the process's arguments, more than
    a pipe holds, and the child reads them only once it has started Python and imported
    the window's main module: the window froze for that, 0.25-1.3 s. Here the main
    module takes 2 s to import in the child; start() returns long before."""
    script = tmp_path / "window.py"
    script.write_text(
        textwrap.dedent(
            f"""
            import sys, time
            if __name__ == "__mp_main__":  # the child imports the main module first
                time.sleep(2.0)
            sys.path.insert(0, {str(Path(__file__).parent)!r})
            from test_live_child_work import _counting
            from holoview.live import child_work
            if __name__ == "__main__":
                wisdom = (b"", bytes(200_000), b"")  # a session's wisdom and more
                child_work.current_wisdom = lambda: wisdom
                work = child_work.ChildWork(_counting, "holoview-test", niceness=0)
                began = time.perf_counter()
                work.start()
                started = time.perf_counter() - began
                assert work.wait_ready(60)
                ready = time.perf_counter() - began
                print(started, ready, work("a")[1], flush=True)
                work.close()
            """
        )
    )
    done = _run(script)
    assert done.returncode == 0, done.stderr
    started, ready, count = done.stdout.split()
    assert float(ready) > 2.0 and count == "1"  # the child started, took its wisdom, works
    assert float(started) < 0.5, done.stdout


def test_the_match_worker_measures_in_its_process_as_the_maps_worker_would() -> None:
    """The same detections' frames give the same windows in the child as in this process."""
    setup = wavy_setup(256)
    waves = travelling_waves(2, k_range=(300.0, 600.0), rms=10e-9, shape=setup.shape)
    frames, _ = render(setup, waves, 4, seed=2)
    experiment = Experiment(reference="absolute", wavelength_m=setup.wavelength)
    core = FrameCore(setup.shape, experiment, true_peaks(setup)[:4])
    core.build()
    here, worker = WindowMatcher(), MatchWorker()
    worker.start()
    matched = 0
    try:
        for i, frame in enumerate(frames):
            job = MatchJob(windows_in_use(core), np.array(frame), band=0.0)
            expected = job.run(here)
            assert worker.submit(job)
            deadline = time.monotonic() + 120
            while (taken := worker.take()) is None:
                assert time.monotonic() < deadline, "no result from the match process"
                time.sleep(0.01)
            assert not isinstance(taken, str), taken
            result = taken[0]
            assert (result is None) == (expected is None), i
            if expected is not None and result is not None:
                assert result.note == expected.note
                assert {k: w.radius for k, w in result.windows.items()} == {
                    k: w.radius for k, w in expected.windows.items()
                }
                result.apply(core)
                core.build()
                matched += 1
        pid = worker.child.pid
        assert matched and pid is not None and pid != os.getpid()
    finally:
        worker.stop()
    assert _gone(pid) and not worker._thread.is_alive()
