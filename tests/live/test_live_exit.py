"""A worker's job that outlasts the window's stop is waited for at the interpreter's exit."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

CHILD = """
import sys, threading, time
from pathlib import Path
from holoview.live.side_workers import SideWorker

done = Path(sys.argv[1])
started = threading.Event()

def slow(job):
    started.set()
    time.sleep(1.5)  # a measurement longer than the stop's wait
    done.write_text("finished")
    return job

worker = SideWorker("holoview-test-side", slow, "a slow job")
worker.start()
worker.submit(1)
started.wait(60)
worker.stop(timeout=0.05)
print("stopped", worker.busy, flush=True)
"""


def test_a_job_under_way_at_exit_ends_before_the_interpreter_does(tmp_path: Path) -> None:
    done = tmp_path / "done.txt"
    run = subprocess.run(
        [sys.executable, "-c", CHILD, str(done)],
        check=False,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    # the stop came back while the job ran; the exit then waited for it to end
    assert run.stdout.strip() == "stopped True"
    assert done.read_text() == "finished"
    assert "Fatal Python error" not in run.stderr
