"""The live window stopped however it is stopped: signals at start-up, its display lost,
an absurd experiment (real child processes, a real X server, real signals; issue 25)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from faults_helpers import (
    alive,
    child_env,
    descendants,
    finish,
    one_line_error,
    output_of,
    run_holoview,
    start_holoview,
    start_holoview_to_files,
    wait_for,
)

from holoview.engine.experiment import MAX_PEAKS


@pytest.mark.gui
def test_a_stop_signal_while_the_window_is_built_stops_it(tmp_path: Path) -> None:
    """SIGTERM while the main window is being built (sent from its constructor): exit 130
    and one line. Before: no handler yet, the process was killed (status -15, no word)."""
    script = (
        "import os, signal, sys\n"
        "from holoview.ui import main_window\n"
        "built = main_window.MainWindow.__init__\n"
        "def building(self, *args, **kwargs):\n"
        "    os.kill(os.getpid(), signal.SIGTERM)\n"
        "    built(self, *args, **kwargs)\n"
        "main_window.MainWindow.__init__ = building\n"
        "from holoview.cli import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    experiment = tmp_path / "experiment.json"
    done = subprocess.run(
        [sys.executable, "-c", script, "live", "--experiment", str(experiment)],
        capture_output=True,
        text=True,
        timeout=60,
        env=child_env(),
        check=False,
    )
    assert done.returncode == 130, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert lines == ["holoview live: interrupted by SIGTERM"], done.stderr


@pytest.fixture
def x_server(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[bytes], str]]:
    """A real X server (Xvfb) of this test's own, and its display name; skipped without one."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("losing the display needs an X server to lose: Xvfb is not installed")
    read, write = os.pipe()
    server = subprocess.Popen(
        [xvfb, "-displayfd", str(write), "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
        pass_fds=(write,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(write)
    with os.fdopen(read) as ready:
        number = ready.readline().strip()  # written once the server accepts connections
    try:
        if not number:
            pytest.skip("Xvfb did not start here")
        yield server, f":{number}"
    finally:
        if server.poll() is None:
            server.kill()
        server.wait()


@pytest.mark.gui
@pytest.mark.slow
def test_losing_the_display_stops_the_window_cleanly(
    x_server: tuple[subprocess.Popen[bytes], str], tmp_path: Path
) -> None:
    """The X server ends under an open window: its work stopped, one line, exit 130, no
    process left. Before: Qt's warning and exit 1, with the window's threads cut off
    (a worker's traceback at times)."""
    server, display = x_server
    experiment = tmp_path / "experiment.json"  # saved once the simulated camera is open
    child = start_holoview_to_files(
        tmp_path,
        "live",
        "--quit-after",
        "120",
        "--experiment",
        str(experiment),
        env={"DISPLAY": display, "QT_QPA_PLATFORM": "xcb"},
    )
    wait_for(experiment.exists, timeout=60, what="the window on the simulated camera")
    below = descendants(child.pid)
    server.terminate()
    done = output_of(tmp_path, child, timeout=60)
    line = one_line_error(done, 130, "the display is gone", "X11")
    assert "files closed" in line
    # the resource tracker of the maps' shared frames ends just after the window
    wait_for(lambda: not any(alive(p) for p in below), timeout=10, what="no process left")


def _experiment(path: Path, peaks: int) -> Path:
    """An experiment file of ``peaks`` labelled peaks spread over the half-plane."""
    rng = np.random.default_rng(0)
    carriers = np.column_stack([rng.uniform(-0.45, 0.45, peaks), rng.uniform(0.02, 0.45, peaks)])
    document = {
        "format": "holoview-experiment",
        "version": 2,
        "peaks": [
            {"label": f"P{i}", "carrier": [round(fx, 5), round(fy, 5)]}
            for i, (fx, fy) in enumerate(carriers.tolist())
        ],
    }
    path.write_text(json.dumps(document))
    return path


@pytest.mark.gui
def test_an_experiment_of_ten_thousand_peaks_is_refused_in_one_line(
    tmp_path: Path, sim_recording: Path
) -> None:
    """10 000 peaks: the window opens at once, says why it ignored the file and keeps it;
    ``process`` refuses it in one line. Before: no window after 40 s, 4.7 GB and growing."""
    experiment = _experiment(tmp_path / "many.json", 10_000)
    before = experiment.read_bytes()
    child = start_holoview("live", "--quit-after", "2", "--experiment", str(experiment))
    done = finish(child, timeout=60)
    assert done.status == 0, done.err
    assert "Traceback" not in done.err
    assert f"10000 peaks; an experiment holds at most {MAX_PEAKS}" in done.err
    assert experiment.read_bytes() == before  # the user's file is kept as it was
    out = tmp_path / "results"
    refused = run_holoview(
        "process", str(sim_recording), "--out", str(out), "--experiment", str(experiment)
    )
    one_line_error(refused, 2, str(experiment), f"at most {MAX_PEAKS}")
    assert not out.exists()


@pytest.mark.gui
def test_the_most_peaks_an_experiment_may_hold_open_in_the_window(tmp_path: Path) -> None:
    """:data:`MAX_PEAKS` peaks (overlapping windows, most of them): the window opens on them
    and stops on SIGTERM with exit 130."""
    experiment = _experiment(tmp_path / "most.json", MAX_PEAKS)
    child = start_holoview_to_files(
        tmp_path, "-v", "live", "--quit-after", "120", "--experiment", str(experiment)
    )
    log = tmp_path / "stderr.txt"
    wait_for(lambda: "main window open" in log.read_text(), timeout=60, what="the window")
    child.send_signal(signal.SIGTERM)
    done = output_of(tmp_path, child, timeout=60)
    assert done.status == 130, done.err
    assert "Traceback" not in done.err
    assert "experiment settings ignored" not in done.err
