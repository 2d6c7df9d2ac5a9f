"""Where outputs go: never over an input, never out of their folder; what index.csv says."""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import h5py
import pytest
from faults_helpers import child_env, fill_disk, one_line_error, run_holoview, run_main

from holoview.headless.batch import INDEX_CSV, output_names, process_batch, text_cell
from holoview.headless.settings import PeakChoice, ProcessOptions
from holoview.paths import MAX_NAME_BYTES, confined_name


def read_index(out: Path) -> list[dict[str, str]]:
    with open(out / INDEX_CSV, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_a_recording_named_results_h5_is_never_replaced_by_its_results(
    sim_recording: Path, tmp_path: Path
) -> None:
    recording = tmp_path / "results.h5"
    shutil.copy(sim_recording, recording)
    before = recording.read_bytes()
    done = run_holoview("process", str(recording), "--out", str(tmp_path), "--overwrite")
    one_line_error(done, 2, "results.h5", "would replace the input")
    assert recording.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.h5"]


def test_an_output_that_is_a_link_to_the_input_is_refused(
    sim_recording: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    os.link(sim_recording, out / "summary.json")  # the same file under an output's name
    done = run_holoview("process", str(sim_recording), "--out", str(out), "--overwrite")
    one_line_error(done, 2, "summary.json", "would replace the input")


def test_outputs_into_the_folder_of_images_read_are_refused(
    sim_recording: Path, tmp_path: Path
) -> None:
    images = tmp_path / "images"
    images.mkdir()
    with h5py.File(sim_recording, "r") as f:
        for i, frame in enumerate(f["frames"][:10]):
            cv2.imwrite(str(images / f"f{i:03d}.png"), frame)
    before = sorted(p.name for p in images.iterdir())
    done = run_holoview(
        "process", str(images), "--out", str(images), "--fps", "20", "--wavelength-nm", "532",
        "--fluid", "water",
    )  # fmt: skip
    one_line_error(done, 2, "is the input folder", "would join the files read from it")
    assert sorted(p.name for p in images.iterdir()) == before  # no report.png among the frames


@pytest.mark.parametrize(
    ("stem", "expected"),
    [
        ("..", "__"),
        (".", "_"),
        ("...", "___"),
        (".hidden", "_hidden"),
        ("a/b\\c", "a_b_c"),
        ("line\nbreak\x00", "line_break_"),
        ("right\u202eto-left", "right_to-left"),
        ("bad\udcffbytes", "bad_bytes"),
        ("", "unnamed"),
        ("run 3 (ok)", "run 3 (ok)"),
    ],
)
def test_confined_names(stem: str, expected: str) -> None:
    assert confined_name(stem) == expected


def test_long_names_are_cut_and_kept_apart() -> None:
    a, b = "x" * 300 + "a", "x" * 300 + "b"
    assert confined_name(a) != confined_name(b)
    assert all(len(os.fsencode(confined_name(n))) <= MAX_NAME_BYTES for n in (a, b))


def test_batch_folder_names_are_unique_whatever_the_case() -> None:
    names = output_names([Path("r/Run.h5"), Path("s/run.npy"), Path("run_2.h5"), Path("...h5")])
    assert names == ["Run", "run_2", "run_2_2", "__"]


def test_batch_outputs_stay_inside_out(sim_recording: Path, tmp_path: Path, capsys) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    for name in ("...h5", "..h5"):
        shutil.copy(sim_recording, runs / name)
    parent = tmp_path / "parent"
    out = parent / "out"
    done = run_main(
        ["-q", "process", str(runs / ".*h5"), "--out", str(out), "--frames", ":10"], capsys
    )
    assert done.status == 0, done.err
    assert sorted(p.name for p in parent.iterdir()) == ["out"]  # nothing beside --out
    assert sorted(p.name for p in out.iterdir()) == ["_", "__", INDEX_CSV]
    for folder in ("_", "__"):
        assert (out / folder / "summary.json").is_file()
    rows = {Path(r["input"]).name: Path(r["out"]).name for r in read_index(out)}
    assert rows == {"...h5": "__", "..h5": "_"}


def test_index_cells_are_never_spreadsheet_formulas(
    sim_recording: Path, tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    names = ["=1+2.h5", "+3.h5", "-4.h5", "@SUM(A1).h5"]
    for name in names:
        shutil.copy(sim_recording, runs / name)
    out = tmp_path / "out"
    monkeypatch.chdir(runs)  # a glob of relative names: the input cells are the bare names
    done = run_main(["-q", "process", "*.h5", "--out", str(out), "--frames", ":10"], capsys)
    assert done.status == 0, done.err
    rows = read_index(out)
    assert sorted(r["input"] for r in rows) == sorted(f"'{name}" for name in names)
    for row in rows:
        for column in ("input", "out", "status", "message"):
            assert not row[column].startswith(("=", "+", "-", "@", "\t", "\r")), row
        assert float(row["fused_rate_m_per_s"]) < 0  # numbers as they are
    assert text_cell("-4.h5") == "'-4.h5" and text_cell("\tx") == "'\tx"
    assert text_cell("run.h5") == "run.h5"


def test_a_full_disk_during_a_batch_exits_3(
    small_disk: Path, sim_recording: Path, tmp_path: Path
) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    shutil.copy(sim_recording, runs / "one.h5")
    fill_disk(small_disk, leave_bytes=200_000)
    done = run_holoview("-q", "process", str(runs), "--out", str(small_disk / "out"))
    one_line_error(done, 3, "one.h5", "the disk is full")
    rows = read_index(small_disk / "out")
    assert [r["status"] for r in rows] == ["failed"]


def test_an_interrupted_batch_rerun_leaves_an_index_that_describes_the_folders(
    sim_recording: Path, tmp_path: Path
) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    for name in ("a.h5", "b.h5", "c.h5"):
        shutil.copy(sim_recording, runs / name)
    recordings = sorted(runs.iterdir())
    out = tmp_path / "out"
    first = ProcessOptions(choice=PeakChoice(auto=4), frames=":20", report=False)
    process_batch(recordings, out, first)
    finished: list[int] = []

    def stop_in_b(done: int, total: int) -> None:  # b: the second recording
        if done == total:
            finished.append(done)
        elif finished and done == 10:
            raise KeyboardInterrupt

    again = ProcessOptions(choice=PeakChoice(auto=4), report=False, overwrite=True)
    outcome = process_batch(recordings, out, again, progress=stop_in_b)
    assert outcome.interrupted
    rows = {Path(r["input"]).name: r for r in read_index(out)}
    assert [rows[n]["status"] for n in ("a.h5", "b.h5", "c.h5")] == ["ok", "interrupted", "not run"]
    summaries = {n: json.loads((out / n / "summary.json").read_text()) for n in "abc"}
    for name, summary in summaries.items():
        row = rows[f"{name}.h5"]
        assert int(row["frames"]) == summary["frames"]["processed"], name
        assert float(row["fused_rate_m_per_s"]) == pytest.approx(
            summary["fused"]["rate_m_per_s"], rel=1e-9
        )
    for name, summary in summaries.items():
        assert rows[f"{name}.h5"]["results_utc"] == summary["created_utc"]
    assert rows["a.h5"]["frames"] == "40"  # this batch's
    assert rows["b.h5"]["frames"] == rows["c.h5"]["frames"] == "20"  # the earlier batch's
    assert "kept" in rows["b.h5"]["message"]


def test_info_on_a_full_standard_output_is_one_line() -> None:
    with open("/dev/full", "w") as full:
        child = subprocess.run(
            [sys.executable, "-m", "holoview", "info"],
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            env=child_env(),
            timeout=120,
            check=False,
        )
    assert child.returncode == 3, child.stderr
    assert child.stderr.strip().splitlines() == [
        "holoview info: error: cannot write to standard output: the disk is full "
        "(No space left on device)"
    ]


def test_peaks_json_on_a_closed_standard_output_exits_3(sim_recording: Path) -> None:
    child = subprocess.run(
        f'exec "{sys.executable}" -m holoview peaks "{sim_recording}" --json >&-',
        shell=True,
        stderr=subprocess.PIPE,
        text=True,
        env=child_env(),
        timeout=120,
        check=False,
    )
    assert child.returncode == 3, child.stderr
    assert child.stderr.strip().splitlines() == [
        "holoview peaks: error: cannot write to standard output: it is closed"
    ]
