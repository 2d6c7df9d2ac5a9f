"""Inputs that are not what they seem: FIFOs, broken links, a cut ImageJ stack, a bad background.

Before: a FIFO or broken symbolic link in a folder or glob of recordings was dropped
("1 of 1 recordings processed"), and a FIFO given as an input waited for a writer; a
truncated ImageJ TIFF (100 frames cut to 6 MB) read as one frame; an all-zero or
negative ``--background`` gave maps of garbage. Each is now named, one line, exit 2
(a failed row of a batch); a FIFO is never opened.
"""

from __future__ import annotations

import csv
import logging
import os
from pathlib import Path

import h5py
import numpy as np
import pytest
import tifffile
from faults_helpers import one_line_error, run_holoview, run_main

OPTICS = ["--wavelength-nm", "532", "--fluid", "water"]


@pytest.fixture(scope="module")
def frames(sim_recording: Path) -> np.ndarray:
    with h5py.File(sim_recording, "r") as f:
        return f["frames"][:]


@pytest.fixture
def batch_folder(tmp_path: Path, sim_recording: Path) -> Path:
    """A folder of one recording, a broken symbolic link and two FIFOs, all named as inputs."""
    folder = tmp_path / "runs"
    folder.mkdir()
    (folder / "good.h5").write_bytes(sim_recording.read_bytes())
    (folder / "broken.h5").symlink_to(tmp_path / "moved" / "run.h5")
    os.mkfifo(folder / "pipe.h5")
    os.mkfifo(folder / "stack.npy")  # opened as a numpy file, it would wait for a writer
    return folder


def index_rows(out: Path) -> dict[str, dict[str, str]]:
    with open(out / "index.csv", newline="") as f:
        return {Path(row["input"]).name: row for row in csv.DictReader(f)}


@pytest.mark.parametrize("how", ["folder", "glob"])
def test_fifos_and_broken_links_in_a_batch_are_named_and_counted(
    batch_folder: Path, tmp_path: Path, how: str
) -> None:
    spec = str(batch_folder) if how == "folder" else str(batch_folder / "*.*")
    out = tmp_path / "out"
    done = run_holoview("process", spec, "--out", str(out), timeout=120)  # a FIFO opened: a hang
    assert done.status == 2, done.err
    assert "Traceback" not in done.err
    assert "index.csv: 1 of 4 recordings processed, 3 failed" in done.out
    said = [line for line in done.err_lines if line.startswith("holoview process: ")]
    assert any("broken.h5" in s and "a broken symbolic link to" in s for s in said), done.err
    assert any("pipe.h5" in s and "a FIFO (named pipe)" in s for s in said), done.err
    assert any("stack.npy" in s and "a FIFO (named pipe)" in s for s in said), done.err
    rows = index_rows(out)
    assert rows["good.h5"]["status"] == "ok"
    assert {rows[n]["status"] for n in ("broken.h5", "pipe.h5", "stack.npy")} == {"failed"}
    assert "a FIFO" in rows["pipe.h5"]["message"]


@pytest.mark.parametrize("name", ["pipe.npy", "pipe.tif", "pipe.h5"])
def test_a_fifo_as_the_input_is_one_line_without_waiting(tmp_path: Path, name: str) -> None:
    fifo = tmp_path / name
    os.mkfifo(fifo)
    for argv in (
        ["process", str(fifo), "--out", str(tmp_path / "o"), "--fps", "20", *OPTICS],
        ["peaks", str(fifo)],
        ["record", str(tmp_path / "copy.h5"), "--source", f"replay:{fifo}"],
    ):
        done = run_holoview("-q", *argv, timeout=60)
        one_line_error(done, 2, str(fifo), "a FIFO (named pipe), not a file or folder of frames")
    assert not (tmp_path / "copy.h5").exists()


def test_a_broken_link_as_the_input_says_where_it_points(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    link = tmp_path / "run.h5"
    link.symlink_to(tmp_path / "gone" / "run.h5")
    done = run_main(["peaks", str(link)], capsys)
    one_line_error(done, 2, str(link), f"a broken symbolic link to {tmp_path / 'gone' / 'run.h5'}")


def test_an_image_folder_names_the_entries_it_cannot_read(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture, caplog
) -> None:
    folder = tmp_path / "images"
    folder.mkdir()
    for i, frame in enumerate(frames[:8]):
        tifffile.imwrite(folder / f"f{i:02d}.tif", frame)
    os.mkfifo(folder / "f08.tif")
    (folder / "f09.tif").symlink_to(tmp_path / "nowhere.tif")
    with caplog.at_level(logging.WARNING):
        done = run_main(
            ["-q", "process", str(folder), "--out", str(tmp_path / "o"), "--fps", "20", *OPTICS],
            capsys,
        )
    assert done.status == 0, done.err
    assert "2 entries that are not image files skipped" in caplog.text
    assert "f08.tif (a FIFO (named pipe))" in caplog.text
    assert "f09.tif (a broken symbolic link to" in caplog.text


def test_a_truncated_imagej_stack_is_refused_naming_the_whole_frames(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """100 frames of 256 x 256 cut to 6 MB: 45 whole frames left; it was read as one.

    Refused, not read to the 45th: like every other truncated input (HDF5, numpy, a TIFF
    page past the end), a cut file is an interrupted copy to be made again, and a result
    from part of a run must not pass for the run's.
    """
    stack = _frames_256(tmp_path)
    path = tmp_path / "stack.tif"
    tifffile.imwrite(path, stack, imagej=True, metadata={"axes": "TYX"})
    whole = path.read_bytes()
    cut = tmp_path / "cut.tif"
    cut.write_bytes(whole[:6_000_000])
    for argv in (
        ["process", str(cut), "--out", str(tmp_path / "o"), "--fps", "20", *OPTICS],
        ["peaks", str(cut)],
    ):
        done = run_main(["-q", *argv], capsys)
        one_line_error(
            done, 2, str(cut), "truncated TIFF: it declares 100 frames", "after 45 whole ones"
        )
    done = run_main(
        ["-q", "process", str(path), "--out", str(tmp_path / "o"), "--fps", "20", *OPTICS], capsys
    )
    assert done.status == 0, done.err


def _frames_256(tmp_path: Path) -> np.ndarray:
    """100 frames of 256 x 256 (the issue's case), from the simulator."""
    path = tmp_path / "sim256.h5"
    from holoview.cli import main

    argv = ["-q", "simulate", str(path), "--size", "256", "--frames", "100", "--seed", "2"]
    assert main(argv) == 0
    with h5py.File(path, "r") as f:
        return f["frames"][:]


@pytest.mark.parametrize(
    "case",
    [
        (np.zeros_like, "constant (every pixel = 0"),
        (lambda f: -f.astype(np.float32), "the frame's mean intensity is -"),
        (lambda f: np.where(f > np.median(f), np.nan, f.astype(np.float32)), "NaN or infinite"),
    ],
    ids=["all-zero", "negative", "nan"],
)
def test_a_background_that_is_no_hologram_is_refused(
    frames: np.ndarray,
    sim_recording: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    case: tuple,
) -> None:
    make, reason = case
    background = tmp_path / "background.npy"
    np.save(background, make(frames[0]))
    out = tmp_path / "o"
    argv = ["-q", "process", str(sim_recording), "--out", str(out), "--background"]
    done = run_main([*argv, str(background)], capsys)
    one_line_error(done, 2, f"--background {background}", reason, "object-free hologram")
    assert not out.exists()
    np.save(background, frames[0])  # a hologram: accepted
    assert run_main([*argv, str(background)], capsys).status == 0
    stack = frames.astype(np.float32)
    stack[5] = make(frames[5])
    np.save(tmp_path / "in.npy", stack)
    argv = ["-q", "process", str(tmp_path / "in.npy"), "--out", str(tmp_path / "o2"), "--fps", "20"]
    argv += OPTICS
    done = run_main([*argv, "--background", "5"], capsys)  # a frame of the input: the same check
    one_line_error(done, 2, "--background 5", reason)
