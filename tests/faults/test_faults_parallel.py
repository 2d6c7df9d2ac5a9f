"""``holoview process --jobs``: a stop signal stops the workers too (real child processes)."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest
from faults_helpers import cpu_seconds, finish, start_holoview, wait_for


def _descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (from /proc)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    found, todo = set(), [pid]
    while todo:
        parent = todo.pop()
        children = {p for p, pp in parents.items() if pp == parent}
        todo += list(children - found)
        found |= children
    return found


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.slow
def test_sigterm_stops_the_workers_and_keeps_the_frames_done(
    long_stack: Path, tmp_path: Path
) -> None:
    """SIGTERM mid-run: no worker left, exit 130, the results of the frames done marked."""
    out = tmp_path / "results"
    child = start_holoview(
        "-q", "process", str(long_stack), "--out", str(out), "--fps", "20", "--maps",
        "--wavelength-nm", "532", "--fluid", "water", "--jobs", "2",
    )  # fmt: skip
    wait_for(lambda: out.is_dir() and any(out.glob(".results.*.partial.h5")), what="the run")
    wait_for(lambda: len(_descendants(child.pid)) >= 3, what="the workers")
    workers = _descendants(child.pid)
    start = cpu_seconds(*workers)  # the forkserver's import, the workers' start
    wait_for(lambda: cpu_seconds(*workers) > start + 1.0, what="the workers at work")
    child.send_signal(signal.SIGTERM)
    done = finish(child, timeout=60)
    assert done.status == 130, done.err
    assert "Traceback" not in done.err
    wait_for(lambda: not any(_alive(p) for p in workers), timeout=10, what="the workers' end")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["input"]["interrupted"] is True
    assert 0 < summary["frames"]["processed"] < 3000
    assert summary["timing"]["workers"] == "2 processes"
