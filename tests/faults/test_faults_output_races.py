"""Outputs that something else writes meanwhile: one run per folder, no-replace renames.

A run is held still with SIGSTOP at the moment that matters (its lock taken, its
temporary file created), the other writer goes, and the run is let go with SIGCONT:
no test depends on how fast either is.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import h5py
import pytest
from faults_helpers import finish, one_line_error, run_holoview, start_holoview, wait_for

from holoview import atomic
from holoview.atomic import TargetExistsError, atomic_path, rename_no_replace, temporary_path
from holoview.headless.results.output_folder import LOCK_NAME
from holoview.headless.run import process_file
from holoview.headless.settings import PeakChoice, ProcessOptions, ProcessSettings

#: Options that make the long numpy stack a recording holoview can process.
STACK_OPTIONS = ("--fps", "20", "--wavelength-nm", "532", "--fluid", "water", "--jobs", "1")


def lock_holder(out: Path) -> str:
    try:
        return (out / LOCK_NAME).read_text().strip()
    except OSError:
        return ""


def results_of(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.fixture
def held(long_stack: Path, tmp_path: Path) -> Iterator[tuple[subprocess.Popen[str], Path]]:
    """A run into a new folder, stopped (SIGSTOP) once it holds the folder's lock."""
    out = tmp_path / "new"
    child = start_holoview("-q", "process", str(long_stack), "--out", str(out), *STACK_OPTIONS)
    wait_for(lambda: lock_holder(out) == str(child.pid), timeout=60, what="the lock")
    child.send_signal(signal.SIGSTOP)
    try:
        yield child, out
    finally:
        if child.poll() is None:
            child.send_signal(signal.SIGCONT)


def test_a_second_run_into_a_folder_in_use_stops_at_once(
    held: tuple[subprocess.Popen[str], Path], sim_recording: Path
) -> None:
    first, out = held
    second = run_holoview("process", str(sim_recording), "--out", str(out))
    line = one_line_error(second, 2, str(out), "in use by another holoview run")
    assert f"pid {first.pid}" in line
    first.send_signal(signal.SIGCONT)
    done = finish(first, timeout=120)
    assert done.status == 0, done.err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["input"]["frames"] == [0, 3000]  # the first run's results, whole
    assert sorted(p.name for p in out.iterdir()) == [
        "report.png",
        "results.h5",
        "summary.json",
        "trends.csv",
    ]  # the lock file goes with the run


def test_a_lock_left_by_a_killed_run_blocks_nothing(
    held: tuple[subprocess.Popen[str], Path], sim_recording: Path
) -> None:
    first, out = held
    first.kill()
    first.wait(timeout=30)
    assert lock_holder(out) == str(first.pid)  # its file stays, its lock went with it
    done = run_holoview("-q", "process", str(sim_recording), "--out", str(out))
    assert done.status == 0, done.err
    assert json.loads((out / "summary.json").read_text())["input"]["frames"] == [0, 40]
    assert not (out / LOCK_NAME).exists()


def test_two_runs_started_together_into_one_new_folder_never_both_write(
    sim_recording: Path, tmp_path: Path
) -> None:
    """Whichever gets the folder first, the other stops: in use, or holding its results."""
    out = tmp_path / "new"
    runs = [
        start_holoview("-q", "process", str(sim_recording), "--out", str(out)) for _ in range(2)
    ]
    done = [finish(child, timeout=120) for child in runs]
    assert sorted(d.status for d in done) == [0, 2], [d.err for d in done]
    refused = next(d for d in done if d.status == 2)
    assert "in use by another holoview run" in refused.err or "earlier run" in refused.err
    assert json.loads((out / "summary.json").read_text())["input"]["frames"] == [0, 40]


@pytest.fixture(scope="module")
def complete(sim_recording: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The complete results of a run, to be copied in by 'another program' (read only)."""
    out = tmp_path_factory.mktemp("complete") / "complete"
    done = run_holoview("-q", "process", str(sim_recording), "--out", str(out))
    assert done.status == 0, done.err
    return out


def copy_in(source: Path, out: Path) -> dict[str, bytes]:
    """Copy the files of ``source`` into ``out``, as another program would; return them."""
    for path in source.iterdir():
        shutil.copy2(path, out / path.name)
    return results_of(source)


@pytest.mark.parametrize("overwrite", [False, True])
def test_results_written_meanwhile_are_replaced_only_with_overwrite(
    sim_recording: Path, complete: Path, tmp_path: Path, overwrite: bool
) -> None:
    out = tmp_path / "out"
    meanwhile: dict[str, bytes] = {}

    def another_program(done: int, total: int) -> None:
        if done == 10 and not meanwhile:
            meanwhile.update(copy_in(complete, out))

    options = ProcessOptions(choice=PeakChoice(auto=4), overwrite=overwrite)
    if not overwrite:
        with pytest.raises(TargetExistsError, match="appeared while this run was writing"):
            process_file(sim_recording, out, options, progress=another_program)
        assert results_of(out) == meanwhile  # not replaced, no file of this run left
        return
    outcome = process_file(sim_recording, out, options, progress=another_program)
    assert len(outcome.files) == 4
    assert results_of(out) != meanwhile
    assert not list(out.glob(".*"))


def test_an_interrupted_run_keeps_complete_results_written_meanwhile(
    sim_recording: Path, complete: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    meanwhile: dict[str, bytes] = {}

    def write_then_stop(done: int, total: int) -> None:
        if done == 10:
            meanwhile.update(copy_in(complete, out))
            raise KeyboardInterrupt

    options = ProcessOptions(choice=PeakChoice(auto=4), settings=ProcessSettings(maps=True))
    outcome = process_file(sim_recording, out, options, progress=write_then_stop)
    assert outcome.data.interrupted and outcome.files == ()
    assert results_of(out) == meanwhile


def partial_of(target: Path) -> list[Path]:
    return list(target.parent.glob(f".{target.stem}.*.partial{target.suffix}"))


@pytest.fixture
def simulating(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[str], Path]]:
    """``simulate X.h5`` stopped once its temporary file exists (X.h5 was free when it checked)."""
    target = tmp_path / "X.h5"
    child = start_holoview(
        "-q", "simulate", str(target), "--scenario", "evaporation", "--size", "128",
        "--frames", "300", "--seed", "1",
    )  # fmt: skip
    wait_for(lambda: bool(partial_of(target)), timeout=60, what="the temporary recording")
    child.send_signal(signal.SIGSTOP)
    try:
        yield child, target
    finally:
        if child.poll() is None:
            child.send_signal(signal.SIGCONT)


def test_simulate_never_replaces_a_recording_made_meanwhile(
    simulating: tuple[subprocess.Popen[str], Path],
) -> None:
    child, target = simulating
    recorded = run_holoview("record", str(target), "--source", "sim:evaporation", "--frames", "5")
    assert recorded.status == 0, recorded.err
    assert "recorded 5" in recorded.out
    before = target.read_bytes()
    child.send_signal(signal.SIGCONT)
    done = finish(child, timeout=120)
    line = one_line_error(done, 3, str(target), "appeared while it was being written", "kept")
    assert target.read_bytes() == before  # the recording said "recorded 5", and keeps them
    kept = partial_of(target)
    assert len(kept) == 1 and str(kept[0]) in line
    with h5py.File(kept[0], "r") as f:  # the simulation is complete under its temporary name
        assert f["frames"].shape[0] == 300 and f["truth"].attrs["seed"] == 1


def test_two_simulations_to_one_name_keep_the_first_finished(
    simulating: tuple[subprocess.Popen[str], Path],
) -> None:
    child, target = simulating
    other = run_holoview("-q", "simulate", str(target), "--size", "64", "--frames", "3")
    assert other.status == 0, other.err
    child.send_signal(signal.SIGCONT)
    done = finish(child, timeout=120)
    one_line_error(done, 3, str(target), "is not replaced")
    with h5py.File(target, "r") as f:
        assert f["frames"].shape[0] == 3


@pytest.mark.parametrize("fallback", [False, True], ids=["renameat2", "link"])
def test_rename_no_replace(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fallback: bool) -> None:
    if fallback:
        monkeypatch.setattr(atomic, "_renameat2", None)  # the hard-link way, as without it
    elif atomic._renameat2 is None:
        pytest.skip("this C library has no renameat2")
    source, target = tmp_path / "a", tmp_path / "b"
    source.write_text("new")
    target.write_text("old")
    with pytest.raises(FileExistsError):
        rename_no_replace(source, target)
    target.unlink()
    target.symlink_to(tmp_path / "nowhere")  # a broken link is taken too
    with pytest.raises(FileExistsError):
        rename_no_replace(source, target)
    assert source.read_text() == "new"
    target.unlink()
    rename_no_replace(source, target)
    assert target.read_text() == "new" and not source.exists()


def test_atomic_path_without_replace_keeps_or_removes_the_file(tmp_path: Path) -> None:
    target = tmp_path / "figure.png"
    for keep in (False, True):
        with (
            pytest.raises(TargetExistsError) as caught,
            atomic_path(target, replace=False, keep=keep) as partial,
        ):
            partial.write_bytes(b"mine")
            target.write_bytes(b"theirs")  # another program, while this one writes
        assert target.read_bytes() == b"theirs"
        if keep:
            assert caught.value.kept is not None and caught.value.kept.read_bytes() == b"mine"
            assert str(caught.value.kept) in str(caught.value)
        else:
            assert caught.value.kept is None and not partial.exists()
            assert "removed" in str(caught.value)
        target.unlink()


@pytest.mark.parametrize(
    "name",
    ["a" * 252 + ".h5", "é" * 125 + ".h5", "b" * 255, "c." + "d" * 253],
    ids=["255 bytes", "multibyte", "no suffix", "long suffix"],
)
def test_temporary_names_fit_for_any_valid_name(tmp_path: Path, name: str) -> None:
    target = tmp_path / name
    names = {temporary_path(target).name for _ in range(50)}
    assert len(names) == 50  # unique
    for partial in names:
        assert len(os.fsencode(partial)) <= 255
        (tmp_path / partial).write_bytes(b"")  # the file system takes it
    with atomic_path(target) as partial:
        partial.write_bytes(b"x")
    assert target.read_bytes() == b"x"


def test_simulate_and_record_take_a_long_valid_name(tmp_path: Path) -> None:
    target = tmp_path / ("s" * 248 + ".h5")
    done = run_holoview("-q", "simulate", str(target), "--size", "32", "--frames", "2")
    assert done.status == 0, done.err
    assert target.is_file()
    copy = tmp_path / ("r" * 252 + ".h5")
    done = run_holoview("-q", "record", str(copy), "--source", f"replay:{target}", "--frames", "2")
    assert done.status == 0, done.err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([target.name, copy.name])
