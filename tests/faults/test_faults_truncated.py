"""Truncated recordings (interrupted copies and downloads) are refused at once, never waited on."""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from faults_helpers import REPO, child_env, one_line_error, run_holoview

from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.replay_files import open_frame_file
from holoview.errors import InputError

WRITER_CHILD = REPO / "tests" / "helpers" / "recording_writer_child.py"


def truncated_copy(source: Path, target: Path, fraction: float) -> Path:
    data = source.read_bytes()
    target.write_bytes(data[: int(len(data) * fraction)])
    return target


@pytest.fixture(scope="module")
def truncated(sim_recording: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return truncated_copy(sim_recording, tmp_path_factory.mktemp("cut") / "cut.h5", 0.4)


def test_the_reader_refuses_a_truncated_recording_at_once(truncated: Path) -> None:
    start = time.monotonic()
    with pytest.raises(InputError, match="truncated: the file has"):
        RecordingReader(truncated)
    with pytest.raises(InputError, match="truncated"):
        open_frame_file(truncated)
    assert time.monotonic() - start < 1.0


@pytest.mark.parametrize(
    "command",
    [
        lambda path, tmp: ["process", str(path), "--out", str(tmp / "out")],
        lambda path, tmp: ["peaks", str(path)],
        lambda path, tmp: ["record", str(tmp / "copy.h5"), "--source", f"replay:{path}"],
    ],
    ids=["process", "peaks", "record-replay"],
)
def test_commands_refuse_a_truncated_recording(truncated: Path, tmp_path: Path, command) -> None:
    done = run_holoview(*command(truncated, tmp_path), timeout=60)
    one_line_error(done, 2, "truncated", str(truncated))
    assert done.seconds < 20  # python's start included; it hung for ten minutes before
    assert not (tmp_path / "copy.h5").exists() and not (tmp_path / "out").exists()


def killed_recording(path: Path, flushed: int = 110) -> Path:
    """A recording whose writer was killed (SIGKILL), still marked open.

    The writer flushes at an append a second or more after its last flush: the child is
    killed at its first append 1.3 s after its ``flushed``-th, so at least ``flushed``
    frames are on disk however slowly a loaded machine runs it.
    """
    child = subprocess.Popen(
        [sys.executable, str(WRITER_CHILD), str(path), "400"],
        stdout=subprocess.PIPE,
        text=True,
        env=child_env(),
    )
    try:
        assert child.stdout is not None
        since: float | None = None
        while since is None or time.monotonic() - since < 1.3:
            line = child.stdout.readline()
            assert line.startswith("appended"), "the writer child stopped early"
            if since is None and int(line.split()[1]) >= flushed:
                since = time.monotonic()
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(10)
        if child.stdout is not None:
            child.stdout.close()
    return path


READ_ALL = """
import sys
from holoview.acquire.recording_reader import RecordingReader
from holoview.errors import InputError
try:
    with RecordingReader(sys.argv[1]) as reader:
        frames = reader[:]
        ids = reader.frame_ids
        print("read", len(frames), int((frames[:, 0, 0] == ids % 65536).all()))
except InputError as exc:
    print("refused", exc)
"""


@pytest.mark.parametrize("fraction", [0.3, 0.6, 0.9])
def test_a_truncated_copy_of_a_killed_recording_never_hangs(
    tmp_path: Path, fraction: float
) -> None:
    """SWMR reading (the writer's flag is still set) with bounded retries: answer within seconds."""
    source = killed_recording(tmp_path / "killed.h5")
    cut = truncated_copy(source, tmp_path / "cut.h5", fraction)
    start = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-c", READ_ALL, str(cut)],
        capture_output=True,
        text=True,
        timeout=60,
        env=child_env(),
        check=False,
    )
    assert time.monotonic() - start < 20, "the reader waited on the damaged file"
    assert done.returncode == 0, done.stderr
    outcome = done.stdout.split()
    assert outcome[0] in ("read", "refused"), done.stdout
    if outcome[0] == "read":
        assert outcome[2] == "1", "frames readable but not the ones written"


def test_a_killed_recording_still_opens_with_its_flushed_frames(tmp_path: Path) -> None:
    source = killed_recording(tmp_path / "killed.h5")
    copy = shutil.copy(source, tmp_path / "copy.h5")
    with RecordingReader(copy) as reader:
        frames = reader[:]
        assert len(frames) > 100
        np.testing.assert_array_equal(frames[:, 0, 0], reader.frame_ids % 65536)
