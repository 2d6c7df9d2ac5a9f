"""Results are written whole or not at all; earlier results are replaced only on request."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import h5py
import pytest
from faults_helpers import child_env, one_line_error, run_holoview

from holoview.atomic import OutputSet, atomic_path
from holoview.headless.run import process_file
from holoview.headless.settings import PeakChoice, ProcessOptions, ProcessSettings

PARTIAL = "*.partial*"


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir()}


@pytest.fixture(scope="module")
def complete_run(sim_recording: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The results of a complete run, made once by the command in a child process."""
    out = tmp_path_factory.mktemp("complete") / "results"
    done = run_holoview("-q", "process", str(sim_recording), "--out", str(out), "--frames", ":20")
    assert done.status == 0, done.err
    return out


@pytest.fixture
def earlier(complete_run: Path, tmp_path: Path) -> Path:
    """A folder holding the results of a complete run (a copy of ``complete_run``)."""
    return Path(shutil.copytree(complete_run, tmp_path / "results"))


def test_a_folder_with_earlier_results_is_refused_without_overwrite(
    sim_recording: Path, earlier: Path
) -> None:
    before = snapshot(earlier)
    done = run_holoview("process", str(sim_recording), "--out", str(earlier))
    line = one_line_error(done, 2, "holds the results of an earlier run", "--overwrite")
    assert "trends.csv, summary.json, results.h5, report.png" in line
    assert "evaporation.h5" in line  # whose run it was
    assert snapshot(earlier) == before


def test_overwrite_says_what_it_replaces_and_replaces_it(
    sim_recording: Path, earlier: Path
) -> None:
    old = json.loads((earlier / "summary.json").read_text())
    done = run_holoview("process", str(sim_recording), "--out", str(earlier), "--overwrite")
    assert done.status == 0, done.err
    assert "replacing trends.csv, summary.json, results.h5, report.png" in done.err
    new = json.loads((earlier / "summary.json").read_text())
    assert old["input"]["frames"] == [0, 20] and new["input"]["frames"] == [0, 40]
    assert not list(earlier.glob(PARTIAL))


def test_an_earlier_output_this_run_does_not_write_is_removed(
    sim_recording: Path, earlier: Path
) -> None:
    options = ProcessOptions(choice=PeakChoice(auto=4), report=False, overwrite=True)
    outcome = process_file(sim_recording, earlier, options)
    assert (
        sorted(p.name for p in outcome.files)
        == sorted(earlier / n for n in ("trends.csv", "summary.json", "results.h5"))
        or len(outcome.files) == 3
    )
    assert not (earlier / "report.png").exists()  # the folder never mixes two runs


def test_an_interruption_keeps_the_earlier_results(sim_recording: Path, earlier: Path) -> None:
    before = snapshot(earlier)

    def stop_after_10(done: int, total: int) -> None:
        if done == 10:
            raise KeyboardInterrupt

    options = ProcessOptions(
        choice=PeakChoice(auto=4), settings=ProcessSettings(maps=True), overwrite=True
    )
    outcome = process_file(sim_recording, earlier, options, progress=stop_after_10)
    assert outcome.data.interrupted and outcome.files == ()
    assert snapshot(earlier) == before


def test_an_unreadable_frame_mid_run_keeps_the_earlier_results(
    sim_recording: Path, earlier: Path, tmp_path: Path
) -> None:
    folder = tmp_path / "pngs"
    folder.mkdir()
    with h5py.File(sim_recording, "r") as f:
        for i, frame in enumerate(f["frames"][:30]):
            cv2.imwrite(str(folder / f"f{i:03d}.png"), frame)
    damaged = folder / "f020.png"
    damaged.write_bytes(damaged.read_bytes()[:300])
    before = snapshot(earlier)
    done = run_holoview(
        "-q",
        "process",
        str(folder),
        "--out",
        str(earlier),
        "--overwrite",
        "--fps",
        "20",
        "--wavelength-nm",
        "532",
        "--fluid",
        "water",
    )
    one_line_error(done, 2, "f020.png")
    assert snapshot(earlier) == before


def test_a_truncated_video_keeps_the_earlier_results(
    sim_recording: Path, earlier: Path, tmp_path: Path
) -> None:
    video = tmp_path / "v.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"FFV1"), 20, (128, 128), False)
    with h5py.File(sim_recording, "r") as f:
        for frame in f["frames"][:]:
            writer.write((frame >> 4).astype("uint8"))
    writer.release()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(video.read_bytes()[: video.stat().st_size * 6 // 10])
    before = snapshot(earlier)
    done = run_holoview(
        "-q",
        "process",
        str(cut),
        "--out",
        str(earlier),
        "--overwrite",
        "--wavelength-nm",
        "532",
        "--fluid",
        "water",
    )
    one_line_error(done, 2, "cut.avi", "cannot be decoded")
    assert snapshot(earlier) == before


def test_an_empty_output_folder_name_is_refused(sim_recording: Path, tmp_path: Path) -> None:
    done = run_holoview("process", str(sim_recording), "--out", "", cwd=tmp_path)
    one_line_error(done, 2, "--out", "empty")
    assert list(tmp_path.iterdir()) == []


def test_a_closed_standard_output_is_one_line(sim_recording: Path, tmp_path: Path) -> None:
    """``holoview process ... | true``: the reader is gone before the result line."""
    reader, writer = os.pipe()
    os.close(reader)
    child = subprocess.run(
        [
            sys.executable,
            "-m",
            "holoview",
            "process",
            str(sim_recording),
            "--out",
            str(tmp_path / "o"),
            "--frames",
            ":10",
        ],
        stdout=writer,
        stderr=subprocess.PIPE,
        text=True,
        env=child_env(),
        timeout=120,
        check=False,
    )
    os.close(writer)
    assert child.returncode == 3, child.stderr
    assert child.stderr.strip().splitlines() == [
        "holoview process: error: cannot write to standard output: the reader closed the pipe "
        "(Broken pipe)"
    ]
    assert (tmp_path / "o" / "summary.json").is_file()  # the results were written before


def test_standard_output_on_a_full_disk_is_one_line(sim_recording: Path) -> None:
    with open("/dev/full", "w") as full:
        child = subprocess.run(
            [sys.executable, "-m", "holoview", "peaks", str(sim_recording), "--json"],
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            env=child_env(),
            timeout=120,
            check=False,
        )
    assert child.returncode == 3, child.stderr
    assert child.stderr.strip().splitlines() == [
        "holoview peaks: error: cannot write to standard output: the disk is full "
        "(No space left on device)"
    ]


def test_atomic_path_replaces_only_a_complete_file(tmp_path: Path) -> None:
    target = tmp_path / "figure.png"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), atomic_path(target) as partial:
        partial.write_bytes(b"half")
        raise RuntimeError("the writer failed")
    with pytest.raises(KeyboardInterrupt), atomic_path(target) as partial:
        partial.write_bytes(b"half")
        raise KeyboardInterrupt
    assert target.read_bytes() == b"old"
    with atomic_path(target) as partial:
        assert partial.parent == tmp_path and partial.name.startswith(".figure.")
        assert partial.suffix == ".png"  # writers that choose the format by the suffix
        partial.write_bytes(b"new")
    assert target.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figure.png"]


def test_an_output_set_renames_only_on_commit(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text("old a")
    with OutputSet(tmp_path) as outputs:
        outputs.path("a.csv").write_text("new a")
        outputs.path("b.json").write_text("new b")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv"]  # no commit: discarded
    assert (tmp_path / "a.csv").read_text() == "old a"
    with OutputSet(tmp_path) as outputs:
        outputs.path("a.csv").write_text("new a")
        outputs.path("never.txt")  # asked for, never written: skipped
        written = outputs.commit()
    assert written == [tmp_path / "a.csv"]
    assert (tmp_path / "a.csv").read_text() == "new a"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv"]
