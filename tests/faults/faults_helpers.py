"""Helpers of the fault tests: holoview in a child process, a real small disk, small inputs.

A module of its own (not ``conftest``) so that test modules import it by a unique name.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import pytest

from holoview.acquire.recording_writer import RecordingWriter

#: The repository root: children import this checkout's holoview.
REPO = Path(__file__).resolve().parents[2]


def child_env(**extra: str) -> dict[str, str]:
    """The environment of a child holoview: this checkout first, Qt offscreen."""
    path = os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH", "")) if p)
    return {**os.environ, "PYTHONPATH": path, "QT_QPA_PLATFORM": "offscreen", **extra}


@dataclass(frozen=True)
class Done:
    """What a finished child holoview gave: exit status, stdout, stderr, wall seconds."""

    status: int
    out: str
    err: str
    seconds: float

    @property
    def err_lines(self) -> list[str]:
        """The non-empty lines of stderr."""
        return [line for line in self.err.splitlines() if line.strip()]


def run_holoview(*args: str, timeout: float = 120.0, cwd: Path | None = None) -> Done:
    """Run ``python -m holoview ARGS`` to its end (killed after ``timeout`` s: a hang)."""
    start = time.monotonic()
    child = subprocess.run(
        [sys.executable, "-m", "holoview", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=child_env(),
        cwd=cwd,
        check=False,
    )
    return Done(child.returncode, child.stdout, child.stderr, time.monotonic() - start)


#: Children started by :func:`start_holoview` that may still run.
_children: list[subprocess.Popen[str]] = []


def start_holoview(*args: str) -> subprocess.Popen[str]:
    """Start ``python -m holoview ARGS``; stdout and stderr are pipes."""
    child = subprocess.Popen(
        [sys.executable, "-m", "holoview", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=child_env(),
    )
    _children.append(child)
    return child


def reap_children() -> None:
    """Kill the started children a failed test left running, and close their pipes."""
    while _children:
        child = _children.pop()
        if child.poll() is None:
            child.kill()
        child.communicate()


def finish(child: subprocess.Popen[str], timeout: float = 60.0) -> Done:
    """Wait for a started child (killed after ``timeout`` s, which fails the test)."""
    start = time.monotonic()
    try:
        out, err = child.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        child.kill()
        out, err = child.communicate()
        pytest.fail(f"holoview did not end within {timeout} s: {err[-2000:]}")
    return Done(child.returncode, out, err, time.monotonic() - start)


def wait_for(condition, timeout: float = 30.0, what: str = "a condition") -> None:
    """Poll ``condition()`` every 20 ms until true; fail after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting for {what}")
        time.sleep(0.02)


def cpu_seconds(*pids: int) -> float:
    """CPU time (user and system, s) the processes ``pids`` have used so far (0 once gone).

    A condition on work done, not on the wall clock: it holds the same on a loaded machine.
    """
    tick = os.sysconf("SC_CLK_TCK")
    total = 0.0
    for pid in pids:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += (int(fields[11]) + int(fields[12])) / tick  # utime, stime
    return total


def one_line_error(done: Done, status: int, *words: str) -> str:
    """Assert exit ``status``, one stderr line of holoview's own, no traceback; return it."""
    assert done.status == status, done.err
    assert "Traceback" not in done.err, done.err
    lines = done.err_lines
    assert len(lines) == 1, done.err
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


@contextmanager
def mounted_tmpfs(where: Path, size_mb: int = 20) -> Iterator[Path]:
    """Mount a real tmpfs of ``size_mb`` MB at ``where``; skip where mounting is refused."""
    where.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0:
        pytest.skip("a full disk needs a tmpfs, and mounting one needs root")
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size_mb}m", "tmpfs", str(where)],
        capture_output=True,
        text=True,
        check=False,
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.strip() or mounted.returncode}")
    try:
        yield where
    finally:
        reap_children()  # a child still writing there would keep the disk busy
        if subprocess.run(["umount", str(where)], check=False).returncode != 0:
            subprocess.run(["umount", "-l", str(where)], check=False)


def fill_disk(folder: Path, leave_bytes: int) -> Path:
    """Fill the file system of ``folder`` up to ``leave_bytes`` free; return the filler file.

    Another program may be writing there meanwhile (a recording): the room it takes
    between measuring and allocating is measured again, until the filler has what
    is left.
    """
    filler = folder / "filler"
    with open(filler, "wb") as f:
        for _ in range(100):
            stats = os.statvfs(folder)
            room = stats.f_bavail * stats.f_frsize - leave_bytes
            if room <= 0:
                break
            try:
                os.posix_fallocate(f.fileno(), os.fstat(f.fileno()).st_size, room)
            except OSError as exc:
                if exc.errno != errno.ENOSPC:
                    raise
    return filler


def write_recording(path: Path, frames: np.ndarray, **kwargs: object) -> Path:
    """A holoview recording of ``frames`` (ids 0.., 50 frames/s, the default setup)."""
    setup = {"wavelength_m": 532e-9, "pixel_pitch_m": 20e-6, "n1": 1.0, "n2": 1.333}
    with RecordingWriter(path, frames.shape[1:], frames.dtype, setup=setup, **kwargs) as w:
        for i, frame in enumerate(frames):
            w.append(frame, i, i / 50.0, 1e9 + i / 50.0)
    return path


def plain_h5py_frames(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(frames, frame_id, t_device_s)`` read with plain h5py (not SWMR): a cleanly closed file."""
    with h5py.File(path, "r") as f:
        return f["frames"][:], f["frame_id"][:], f["t_device_s"][:]


def stop_signal(child: subprocess.Popen[str], name: str) -> None:
    """Send the signal called ``name`` (``SIGTERM``, ...) to ``child``."""
    child.send_signal(getattr(signal, name))


def descendants(pid: int) -> set[int]:
    """Every process below ``pid`` now (from /proc)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    found: set[int] = set()
    todo = [pid]
    while todo:
        parent = todo.pop()
        children = {p for p, pp in parents.items() if pp == parent}
        todo += list(children - found)
        found |= children
    return found


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, ended but not reaped, does not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def command_line(pid: int) -> str:
    """Process ``pid``'s command line, its words joined by spaces ("" once it ended)."""
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def start_holoview_to_files(
    folder: Path, *args: str, env: dict[str, str] | None = None
) -> subprocess.Popen[str]:
    """Start ``python -m holoview ARGS`` with stdout and stderr in files of ``folder``.

    For children whose own children may outlive them: a pipe would stay open as long
    as they do. ``env`` is added to :func:`child_env`'s. Read the output with
    :func:`output_of`.
    """
    with open(folder / "stdout.txt", "w") as out, open(folder / "stderr.txt", "w") as err:
        child = subprocess.Popen(
            [sys.executable, "-m", "holoview", *args],
            stdout=out,
            stderr=err,
            text=True,
            env=child_env(**(env or {})),
        )
    _children.append(child)
    return child


def output_of(folder: Path, child: subprocess.Popen[str], timeout: float = 60.0) -> Done:
    """Wait for a child of :func:`start_holoview_to_files` (killed after ``timeout`` s, which
    fails the test); its exit status and output."""
    start = time.monotonic()
    try:
        child.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        child.kill()
        child.wait()
        pytest.fail(f"holoview did not end within {timeout} s")
    out = (folder / "stdout.txt").read_text()
    err = (folder / "stderr.txt").read_text()
    return Done(child.returncode, out, err, time.monotonic() - start)


def run_main(args: list[str], capsys: pytest.CaptureFixture) -> Done:
    """Run holoview's ``main`` in this process (faster than a child) and capture its output."""
    from holoview.cli import main

    start = time.monotonic()
    status = main(args)
    captured = capsys.readouterr()
    return Done(status, captured.out, captured.err, time.monotonic() - start)
