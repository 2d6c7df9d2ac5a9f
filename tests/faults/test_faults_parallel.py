"""``holoview process --jobs`` and ``--scheduler local``: whatever happens to the parent, no
process is left behind, and what was done is kept (real child processes, real signals)."""

from __future__ import annotations

import http.server
import json
import re
import signal
import threading
from collections.abc import Iterator
from pathlib import Path

import h5py
import pytest
from faults_helpers import (
    REPO,
    alive,
    command_line,
    cpu_seconds,
    descendants,
    finish,
    one_line_error,
    output_of,
    run_holoview,
    start_holoview,
    start_holoview_to_files,
    wait_for,
)

from holoview.processing.fourier.fftplans import usable_cpus


@pytest.mark.slow
def test_sigterm_stops_the_workers_and_keeps_the_frames_done(
    long_stack: Path, tmp_path: Path
) -> None:
    """SIGTERM mid-run: no worker left, exit 130, the results of the frames done marked.

    The stop lands in any of the auto run's passes (on a loaded machine often after the
    series): in the series, the frames measured; in the naming, the spread pass or before
    the first chunk of maps, every frame's series and no maps; later, the frames whose
    maps are made. Before: a stop between the series and the first maps wrote nothing."""
    out = tmp_path / "results"
    child = start_holoview(
        "-q", "process", str(long_stack), "--out", str(out), "--fps", "20", "--maps",
        "--wavelength-nm", "532", "--fluid", "water", "--jobs", "2",
    )  # fmt: skip
    wait_for(lambda: out.is_dir() and any(out.glob(".results.*.partial.h5")), what="the run")
    wait_for(lambda: len(descendants(child.pid)) >= 3, what="the workers")
    # Every process seen below the run from here on, with the CPU time it had when first
    # seen and the most since: on a loaded machine the first three seen may be the
    # forkserver and processes that end before the maps' workers are at work.
    first: dict[int, float] = {}
    most: dict[int, float] = {}

    def worked() -> float:
        for pid in descendants(child.pid):
            first.setdefault(pid, cpu_seconds(pid))
        for pid in first:
            most[pid] = max(most.get(pid, 0.0), cpu_seconds(pid))
        return sum(most[pid] - first[pid] for pid in first)

    wait_for(lambda: worked() > 1.0, what="the workers at work")
    workers = set(first)
    child.send_signal(signal.SIGTERM)
    done = finish(child, timeout=60)
    assert done.status == 130, done.err
    assert "Traceback" not in done.err
    wait_for(lambda: not any(alive(p) for p in workers), timeout=10, what="the workers' end")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["input"]["interrupted"] is True
    processed = summary["frames"]["processed"]
    assert 0 < processed <= 3000
    assert summary["timing"]["workers"] == "2 processes"
    with h5py.File(out / "results.h5", "r") as f:
        assert f["trends/frame"].shape[0] == processed
        group = f.get("maps", {})
        # the maps themselves (time, y, x), not their coordinates (time, y, x, label)
        maps = [group[name].shape[0] for name in group if group[name].ndim == 3]
    if maps:  # the frames done are those whose maps are made
        assert set(maps) == {processed} and processed < 3000
    else:  # stopped before any frame's maps
        assert any("results.h5 holds none" in note for note in summary["notes"]), summary


def _stitched(err_file: Path) -> int:
    """The frames stitched in order, as the log on stderr says (with ``-vv``)."""
    found = re.findall(r"(\d+) frames stitched in order", err_file.read_text(errors="replace"))
    return int(found[-1]) if found else 0


@pytest.mark.slow
@pytest.mark.parametrize(
    "runner", [("--jobs", "2"), ("--jobs", "2", "--maps"), ("--scheduler", "local", "--jobs", "2")]
)
def test_sigkill_to_the_parent_leaves_no_process_behind(
    runner: tuple[str, ...], long_stack: Path, tmp_path: Path
) -> None:
    """SIGKILL mid-run: the forkserver, the workers and the resource tracker (or Dask's
    workers) end with the parent. Before: all four alive 11 minutes later."""
    out = tmp_path / "results"
    child = start_holoview_to_files(
        tmp_path, "-q", "process", str(long_stack), "--out", str(out), "--fps", "20",
        "--wavelength-nm", "532", "--fluid", "water", *runner,
    )  # fmt: skip
    wait_for(lambda: out.is_dir() and any(out.glob(".results.*.partial.h5")), 120, "the run")
    below = descendants(child.pid)
    assert len(below) >= 2, [command_line(p) for p in below]  # the workers at least
    child.send_signal(signal.SIGKILL)
    child.wait(timeout=30)
    wait_for(
        lambda: not any(alive(p) for p in below),
        timeout=30,
        what=f"the end of {[command_line(p) for p in below if alive(p)]}",
    )


@pytest.mark.slow
@pytest.mark.parametrize("name", ["SIGTERM", "SIGINT"])
def test_a_stop_signal_during_a_dask_run_keeps_the_frames_done(
    name: str, long_stack: Path, tmp_path: Path
) -> None:
    """``--scheduler local`` without ``--maps``, stopped mid-run: exit 130, the chunks done
    written and marked. Before: exit 1, ``AttributeError: 'NoneType' object has no
    attribute 'cancel'``, nothing written."""
    out = tmp_path / "results"
    child = start_holoview_to_files(
        tmp_path, "-vv", "process", str(long_stack), "--out", str(out), "--fps", "20",
        "--wavelength-nm", "532", "--fluid", "water", "--scheduler", "local", "--jobs", "2",
    )  # fmt: skip
    wait_for(lambda: _stitched(tmp_path / "stderr.txt") > 0, 180, "a chunk stitched")
    below = descendants(child.pid)
    child.send_signal(getattr(signal, name))
    done = output_of(tmp_path, child, timeout=60)
    assert done.status == 130, done.err
    # -vv shows Dask's own debug output, its shutdown's complaints included (some at
    # exit, after the last line): no traceback through holoview's code, no error or
    # traceback after the run's last line
    assert f'File "{REPO / "holoview"}' not in done.err, done.err
    last = [i for i, line in enumerate(done.err_lines) if "(marked interrupted)" in line]
    assert last, done.err
    after = done.err_lines[last[-1] + 1 :]
    said = [line for line in after if re.search(r" (ERROR|CRITICAL) |Traceback", line)]
    assert not said, done.err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["input"]["interrupted"] is True
    assert _stitched(tmp_path / "stderr.txt") <= summary["frames"]["processed"] < 3000
    assert summary["timing"]["workers"].startswith("Dask at")
    wait_for(lambda: not any(alive(p) for p in below), timeout=30, what="the workers' end")


@pytest.mark.slow
def test_a_stop_signal_while_the_local_cluster_starts_stops_it(
    sim_recording: Path, tmp_path: Path
) -> None:
    """SIGTERM as the first Dask worker process starts: exit 130 at once, one line, no
    process left. Before: Dask went on starting its workers behind the interruption and
    failed an assertion at exit, 10 s later."""
    out = tmp_path / "results"
    child = start_holoview_to_files(
        tmp_path, "-q", "process", str(sim_recording), "--out", str(out),
        "--scheduler", "local", "--jobs", "2",
    )  # fmt: skip

    def spawned() -> set[int]:
        return {p for p in descendants(child.pid) if "multiprocessing.spawn" in command_line(p)}

    wait_for(lambda: bool(spawned()), 120, "a Dask worker process")
    below = descendants(child.pid)
    child.send_signal(signal.SIGTERM)
    done = output_of(tmp_path, child, timeout=30)
    assert not out.exists() or not any(out.glob("*.csv"))  # stopped before any frame
    assert done.status == 130, done.err
    assert done.err_lines == ["holoview process: interrupted by SIGTERM"], done.err
    wait_for(lambda: not any(alive(p) for p in below), timeout=30, what="the workers' end")


@pytest.mark.slow
def test_more_local_dask_workers_than_cores_are_capped(sim_recording: Path, tmp_path: Path) -> None:
    """``--scheduler local --jobs 200``: a warning, one worker a usable core, the run done.
    Before: 200 workers, still starting after 120 s (24: 44 s and Dask tracebacks)."""
    cores = usable_cpus()
    out = tmp_path / "results"
    done = run_holoview(
        "process", str(sim_recording), "--out", str(out), "--scheduler", "local",
        "--jobs", "200", timeout=180,
    )  # fmt: skip
    assert done.status == 0, done.err
    assert "Traceback" not in done.err
    assert f"--jobs 200: this machine has {cores} usable cores; using {cores}" in done.err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["timing"]["workers"].endswith(f"({cores} workers)")


@pytest.fixture
def http_listener() -> Iterator[int]:
    """A real HTTP server on a free port of 127.0.0.1, in a thread; its port."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _QuietHandler)
    thread = threading.Thread(target=server.serve_forever, name="http-listener", daemon=True)
    thread.start()
    try:
        yield server.server_address[1]
    finally:
        server.shutdown()
        server.server_close()
        thread.join(10)


class _QuietHandler(http.server.BaseHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:
        """Nothing on the test's stderr."""


def test_a_scheduler_address_where_http_answers_is_one_line(
    http_listener: int, sim_recording: Path, tmp_path: Path
) -> None:
    """``--scheduler`` at an HTTP server: one line, exit 2, nothing written. Before: no end
    after 120 s (Dask read the HTTP reply's first bytes as a message's length)."""
    address = f"127.0.0.1:{http_listener}"
    out = tmp_path / "results"
    done = run_holoview(
        "process", str(sim_recording), "--out", str(out), "--scheduler", address, timeout=60
    )
    one_line_error(done, 2, f"--scheduler {address}", "Dask scheduler")
    assert not out.exists()


def test_a_tls_scheduler_without_tls_settings_is_one_line(
    sim_recording: Path, tmp_path: Path
) -> None:
    """``--scheduler tls://...`` without Dask's TLS settings: one line, exit 2. Before: a
    ``TypeError`` traceback."""
    out = tmp_path / "results"
    done = run_holoview(
        "process", str(sim_recording), "--out", str(out), "--scheduler", "tls://127.0.0.1:1",
        timeout=60,
    )  # fmt: skip
    one_line_error(done, 2, "--scheduler tls://127.0.0.1:1", "TLS settings")
    assert not out.exists()
