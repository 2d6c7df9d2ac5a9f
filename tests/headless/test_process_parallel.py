"""``holoview process`` on many processes and on Dask: the same results as one (issue 16).

Parity is byte for byte on ``trends.csv`` and exact on the rates: the workers measure
only what depends on one frame, and the series are stitched in order in the parent.
The recordings are small (128 x 128, 256 x 256 for the aliasing one) and the workers
are started once per module, so that the module stays within seconds of CPU.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from headless_sim import Simulated, run_cli

from holoview.acquire.recording_writer import RecordingWriter
from holoview.cli import main
from holoview.errors import InputError
from holoview.headless.batch import INDEX_CSV
from holoview.headless.parallel import chunk_maps, stitch
from holoview.headless.parallel.chunks import (
    ChunkTask,
    make_tasks,
    measure_chunk,
    plan_jobs,
    split_frames,
)
from holoview.headless.parallel.runners import (
    TRACKER_QUIET,
    ChunkRunner,
    DaskRunner,
    ProcessRunner,
    open_runner,
)
from holoview.headless.run import ProcessOutcome, process_file
from holoview.headless.settings import ProcessOptions, ProcessSettings


@pytest.fixture(scope="module")
def runners() -> Iterator[dict[str, ChunkRunner]]:
    """Two and seven local processes, and a Dask LocalCluster of two worker processes."""
    started: dict[str, ChunkRunner] = {}
    try:
        started["jobs 2"] = ProcessRunner(2)
        started["jobs 7"] = ProcessRunner(7)
        started["dask local"] = DaskRunner("local", 2)
        yield started
    finally:
        for runner in started.values():
            runner.close()


#: The runners each parity case runs beside one process: every runner in the cases where
#: chunks meet the most state (relative maps, lost frames), one each elsewhere, every
#: runner in at least three cases (the chunk's work is the same whatever carries it).
ALL_RUNNERS = ("jobs 2", "jobs 7", "dask local")


def _some(runners: dict[str, ChunkRunner], names: tuple[str, ...]) -> dict[str, ChunkRunner]:
    return {name: runners[name] for name in names}


@pytest.fixture(scope="module")
def injection(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """25 frames/s at 1.74 um/s: RB3 and FB2 alias in time (the joint estimate's case)."""
    path = tmp_path_factory.mktemp("sim") / "injection.h5"
    argv = ["-q", "simulate", str(path), "--scenario", "injection", "--size", "256"]
    argv += ["--frames", "60", "--fps", "25", "--seed", "2", "--injection-ul-per-s", "12.3"]
    argv += ["--basin-area-cm2", "70.6"]
    assert main(argv) == 0
    return path


def _lose_frames(source: Path, target: Path) -> Path:
    """``source`` with frames lost: a gap of five (ids and times skip), two damaged in transfer."""
    with h5py.File(source, "r") as f:
        frames = f["frames"][:]
        ids, t_device, t_host = f["frame_id"][:], f["t_device_s"][:], f["t_host_s"][:]
        setup = dict(f["setup"].attrs)
    keep = np.r_[0:40, 45 : len(frames)]
    setup = {k: v for k, v in setup.items() if isinstance(v, float | int | np.floating)}
    with RecordingWriter(target, frames.shape[1:], frames.dtype, setup=setup) as writer:
        for i in keep:
            frame = frames[i].copy()
            if i in (17, 71):
                frame[30:60] = 0  # rows lost in transfer
            writer.append(frame, int(ids[i]), float(t_device[i]), float(t_host[i]))
    return target


def _run(
    path: Path,
    out: Path,
    runner: ChunkRunner | None,
    reference: str | None = None,
    settings: ProcessSettings | None = None,
    *,
    frames: str | None = None,
    **kwargs: object,
) -> ProcessOutcome:
    options = ProcessOptions(
        settings=settings or ProcessSettings(reference=reference), frames=frames, report=False
    )
    return process_file(path, out, options, runner=runner, **kwargs)  # type: ignore[arg-type]


def _assert_same_series(serial: ProcessOutcome, other: ProcessOutcome, what: str) -> None:
    """trends.csv byte for byte; each peak's rate, the flags and counts exactly."""
    assert (serial.out / "trends.csv").read_bytes() == (other.out / "trends.csv").read_bytes()
    fits = [(p.rate, p.rate_stderr) for p in serial.analysis.peaks]
    assert fits == [(p.rate, p.rate_stderr) for p in other.analysis.peaks], what
    assert serial.data.frame_flags == other.data.frame_flags, what
    assert serial.data.peak_flags == other.data.peak_flags, what
    assert serial.data.demodulated == other.data.demodulated, what
    assert serial.data.last_frame == other.data.last_frame, what


def _assert_same(serial: ProcessOutcome, other: ProcessOutcome, what: str) -> None:
    _assert_same_series(serial, other, what)
    assert serial.analysis.fit == other.analysis.fit, what
    for m, n in zip(serial.data.last_maps, other.data.last_maps, strict=True):
        np.testing.assert_array_equal(m, n)
    shifts = [d.shift for d in serial.data.displacements]
    assert shifts == [d.shift for d in other.data.displacements], what


@pytest.mark.slow
@pytest.mark.parametrize(
    ("case", "names"),
    [
        ("relative", ALL_RUNNERS),
        ("absolute", ("jobs 7",)),
        ("aliasing", ("dask local",)),
        ("lost frames", ALL_RUNNERS),
    ],
    ids=["relative", "absolute", "aliasing", "lost frames"],
)
def test_jobs_and_dask_give_the_results_of_one_process(
    case: str,
    names: tuple[str, ...],
    *,
    evaporation: Simulated,
    injection: Path,
    runners: dict[str, ChunkRunner],
    tmp_path: Path,
) -> None:
    """--jobs 2, 7 and a Dask LocalCluster (``names``): the trends.csv, rates, flags and maps
    of one process."""
    path = {"aliasing": injection, "lost frames": tmp_path / "lost.h5"}.get(case, evaporation.path)
    if case == "lost frames":
        _lose_frames(evaporation.path, path)
    reference = case if case in ("relative", "absolute") else None
    serial = _run(path, tmp_path / "serial", None, reference)
    if case == "aliasing":
        assert any("aliased_in_time" in p.flags for p in serial.analysis.peaks)
        assert serial.analysis.margins is not None  # the joint estimate ran
    if case == "lost frames":
        assert serial.data.frame_flags["damaged"] == 2
        assert len(serial.data.frames) == evaporation.frames - 5
    for name, runner in _some(runners, names).items():
        other = _run(path, tmp_path / name.replace(" ", "_"), runner, reference)
        assert other.data.workers == runner.name
        _assert_same(serial, other, f"{case}: {name}")


def _maps(out: Path) -> dict[str, np.ndarray]:
    """Every map dataset of a run's results.h5 (the fused one included; not the coordinates)."""
    with h5py.File(out / "results.h5", "r") as f:
        return {name: f["maps"][name][:] for name in f["maps"] if f["maps"][name].ndim == 3}


def _assert_same_maps(serial: ProcessOutcome, other: ProcessOutcome, what: str) -> None:
    """The series, rates and flags exactly; the maps, fused ones included, to the last bit.

    The workers plan their FFTs from the parent's wisdom and start each chunk from the
    serial run's state: nothing differs, not even a rounding.
    """
    _assert_same_series(serial, other, what)
    np.testing.assert_array_equal(other.data.noise_rad, serial.data.noise_rad, what)
    a, b = _maps(serial.out), _maps(other.out)
    assert a.keys() == b.keys(), what
    assert "fused" in a, what
    for name, maps in a.items():
        assert np.isfinite(maps).any(), f"{what}: {name}"
        np.testing.assert_array_equal(b[name], maps, f"{what}: {name}")
    for m, n in zip(serial.data.last_maps, other.data.last_maps, strict=True):
        np.testing.assert_array_equal(n, m)
    shifts = [d.shift for d in serial.data.displacements]
    assert shifts, what
    assert [d.shift for d in other.data.displacements] == shifts, what


@pytest.mark.slow
@pytest.mark.parametrize(
    ("case", "names"),
    [
        ("relative", ALL_RUNNERS),
        ("absolute", ("jobs 2",)),
        ("synthetic", ("dask local",)),
        ("background", ("jobs 7",)),
        ("aliasing", ("dask local",)),
        ("lost frames", ALL_RUNNERS),
        ("lost, absolute", ("jobs 7",)),
        ("frame grid", ("jobs 2", "dask local")),
    ],
    ids=[
        "relative",
        "absolute",
        "synthetic",
        "background",
        "aliasing",
        "lost frames",
        "lost, absolute",
        "frame grid",
    ],
)
def test_maps_from_the_workers_are_those_of_one_process(
    case: str,
    names: tuple[str, ...],
    *,
    evaporation: Simulated,
    injection: Path,
    runners: dict[str, ChunkRunner],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """--maps with --jobs 2, 7 or Dask (``names``): every frame's maps (demodulated in the
    workers) those of one process."""
    monkeypatch.setattr(chunk_maps, "MAPS_CHUNK_FRAMES", 9)  # many chunks, some of one worker
    lost = case.startswith("lost")
    path = injection if case == "aliasing" else tmp_path / "lost.h5" if lost else evaporation.path
    if lost:
        _lose_frames(evaporation.path, path)  # a chunk starts after a damaged frame
    reference = {
        "background": "absolute",
        "lost frames": "relative",
        "lost, absolute": "absolute",
        "aliasing": "absolute",
        "frame grid": "absolute",
    }
    settings = ProcessSettings(
        reference=reference.get(case, case),
        maps=True,
        maps_grid="frame" if case == "frame grid" else "box",
        background="3" if case == "background" else None,
    )
    frames = "0:20" if case == "frame grid" else None  # maps 64 times larger: 3 chunks
    serial = _run(path, tmp_path / "serial", None, settings=settings, frames=frames)
    assert serial.data.demodulated == len(serial.data.frames) - (2 if lost else 0)
    for name, runner in _some(runners, names).items():
        out = tmp_path / name.replace(" ", "_")
        other = _run(path, out, runner, settings=settings, frames=frames)
        assert other.data.workers == runner.name
        _assert_same_maps(serial, other, f"{case}: {name}")


@pytest.mark.slow
def test_maps_handed_over_in_files_are_those_of_one_process(
    evaporation: Simulated,
    runners: dict[str, ChunkRunner],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Local workers write each chunk's maps into a file the parent writes from, then deletes.

    A folder the workers cannot write into (gone): the maps come back pickled, the same.
    """
    monkeypatch.setattr(chunk_maps, "MAPS_CHUNK_FRAMES", 9)
    root = tmp_path / "spill"
    root.mkdir()
    monkeypatch.setattr(stitch, "SPILL_ROOT", str(root))
    monkeypatch.setattr(stitch, "SPILL_FREE_BYTES", 0)
    handed: list[bool] = []
    opened = chunk_maps.ChunkMaps.opened

    def spy(self: chunk_maps.ChunkMaps) -> chunk_maps.ChunkMaps:
        handed.append(self.spilled is not None)
        if self.spilled is not None:
            assert Path(self.spilled).parent.parent == root
        return opened(self)

    monkeypatch.setattr(chunk_maps.ChunkMaps, "opened", spy)
    settings = ProcessSettings(reference="relative", maps=True)
    serial = _run(evaporation.path, tmp_path / "serial", None, settings=settings)
    chunks = len(split_frames(evaporation.frames, 2, maps=True))
    other = _run(evaporation.path, tmp_path / "there", runners["jobs 2"], settings=settings)
    _assert_same_maps(serial, other, "maps in files")
    assert handed == [True] * chunks
    assert list(root.iterdir()) == []  # every file and the folder removed
    real = stitch.spill_folder

    @contextlib.contextmanager
    def missing(runner: ChunkRunner, maps: bool) -> Iterator[str | None]:
        with real(runner, maps) as made:
            yield None if made is None else os.path.join(made, "missing")

    monkeypatch.setattr(stitch, "spill_folder", missing)
    handed.clear()
    other = _run(evaporation.path, tmp_path / "gone", runners["jobs 2"], settings=settings)
    _assert_same_maps(serial, other, "maps pickled, the folder gone")
    assert handed == [False] * chunks
    assert list(root.iterdir()) == []


@pytest.mark.slow
def test_an_interrupted_maps_run_keeps_the_maps_of_the_chunks_done(
    evaporation: Simulated,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Ctrl-C after the first chunks of maps: the frames of the chunks done, maps those of one.

    Absolute maps in the workers follow the series (their mean phases at each chunk's
    start): the series pass comes first, then the maps pass; the progress counts both.
    """
    monkeypatch.setattr(chunk_maps, "MAPS_CHUNK_FRAMES", 9)
    settings = ProcessSettings(reference="absolute", maps=True)
    serial = _run(evaporation.path, tmp_path / "serial", None, settings=settings)

    def stop(done: int, total: int) -> None:
        assert total == 2 * evaporation.frames
        if done >= evaporation.frames + 30:
            raise KeyboardInterrupt

    with ProcessRunner(2) as runner:
        other = _run(evaporation.path, tmp_path / "cut", runner, settings=settings, progress=stop)
    n = len(other.data.frames)
    assert other.data.interrupted and 0 < n < evaporation.frames
    assert n in {c.stop for c in split_frames(evaporation.frames, 2, maps=True)}
    a, b = _maps(serial.out), _maps(other.out)
    assert a.keys() == b.keys()
    for name, maps in b.items():
        assert maps.shape[0] == n, name
        np.testing.assert_array_equal(maps, a[name][:n], name)


@pytest.mark.slow
def test_the_command_line_jobs_option(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """``--jobs 2`` through the command line: the trends of ``--jobs 1``, the workers noted."""
    for jobs in ("1", "2"):
        out = tmp_path / jobs
        status, _, err = run_cli(
            ["-q", "process", str(evaporation.path), "--out", str(out), "--jobs", jobs], capsys
        )
        assert status == 0, err
    assert (tmp_path / "1" / "trends.csv").read_bytes() == (
        tmp_path / "2" / "trends.csv"
    ).read_bytes()
    summary = json.loads((tmp_path / "2" / "summary.json").read_text())
    assert summary["timing"]["workers"] == "2 processes"


def _chunks_started(dask_scheduler: Any) -> int:
    """On the scheduler: how many times a chunk task went to a worker."""
    return sum(
        1
        for key, _, finish, *_ in dask_scheduler.transition_log
        if str(key).startswith("measure_chunk") and finish == "processing"
    )


@pytest.mark.slow
def test_a_dask_worker_killed_mid_run_is_replaced_and_the_result_unchanged(
    evaporation: Simulated, tmp_path: Path
) -> None:
    """SIGKILL to a worker process after the first chunk: Dask measures its chunks again."""
    serial = _run(evaporation.path, tmp_path / "serial", None)
    with DaskRunner("local", 2) as runner:
        client = runner.client
        pids = client.run(os.getpid)
        killed: list[int] = []

        def kill_one(done: int, total: int) -> None:
            if not killed:
                victim = max(pids.values())
                os.kill(victim, signal.SIGKILL)
                killed.append(victim)

        other = _run(evaporation.path, tmp_path / "dask", runner, progress=kill_one)
        assert killed
        with pytest.raises(ProcessLookupError):
            os.kill(killed[0], 0)
        client.wait_for_workers(2, timeout=60)
        assert killed[0] not in client.run(os.getpid).values()  # the nanny started another
        chunks = len(split_frames(evaporation.frames, 2))
        assert client.run_on_scheduler(_chunks_started) > chunks  # some measured again
    _assert_same(serial, other, "a worker killed")


def test_jobs_are_planned_from_the_cores_and_the_frames(caplog: pytest.LogCaptureFixture) -> None:
    """Default: every core but one when long enough; never more jobs than frames or usable
    cores; video: one."""
    assert plan_jobs(None, 10_000, "hdf5", cores=8) == 7
    assert plan_jobs(None, 300, "hdf5", cores=8) == 1
    assert plan_jobs(None, 10_000, "hdf5", cores=1) == 1
    assert plan_jobs(3, 10, "tiff", cores=8) == 3
    assert plan_jobs(7, 5, "hdf5", cores=8) == 5
    assert "the run has 5 frames" in caplog.text
    assert plan_jobs(24, 10_000, "hdf5", cores=4) == 4
    assert "--jobs 24: this machine has 4 usable cores; using 4" in caplog.text
    assert plan_jobs(9, 3, "hdf5", cores=4) == 3  # the tighter of the two
    assert plan_jobs(4, 1000, "video") == 1
    assert "one process" in caplog.text
    with pytest.raises(InputError, match="--jobs must be at least 1"):
        plan_jobs(0, 100, "hdf5")
    chunks = split_frames(1000, 7)
    assert [c.start for c in chunks] == sorted(c.start for c in chunks)
    assert sum(len(c) for c in chunks) == 1000 and chunks[-1].stop == 1000
    assert split_frames(3, 7) == [range(0, 1), range(1, 2), range(2, 3)]
    # a chunk's maps are held whole: frame-grid maps of 1024^2 and six peaks (29 MB a
    # frame) come four frames a chunk, box maps (0.9 MB) 32
    frame_grid = chunk_maps.map_bytes((1024, 1024), 6)
    assert max(len(c) for c in split_frames(100, 1, maps=True, map_bytes=frame_grid)) <= 4
    assert frame_grid * 4 <= chunk_maps.MAPS_CHUNK_BYTES
    box = chunk_maps.map_bytes((180, 180), 6)
    assert [len(c) for c in split_frames(64, 1, maps=True, map_bytes=box)] == [32, 32]


@pytest.mark.parametrize("jobs", ["0", "-2"])
def test_jobs_below_one_is_one_line_and_exit_2(
    jobs: str, evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """``--jobs 0``: one line naming the option, status 2, no output folder."""
    out = tmp_path / "o"
    status, _, err = run_cli(
        ["process", str(evaporation.path), "--out", str(out), "--jobs", jobs], capsys
    )
    assert status == 2
    assert err.strip().count("\n") == 0 and "--jobs must be at least 1" in err
    assert not out.exists()


def test_more_jobs_than_frames_warns_and_uses_fewer(
    evaporation: Simulated,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    caplog: pytest.LogCaptureFixture,
) -> None:
    """``--jobs 9`` on 2 frames: a warning, 2 jobs (no fewer cores here), the results of one."""
    argv = ["process", str(evaporation.path), "--out", str(tmp_path / "o")]
    status, _, err = run_cli([*argv, "--jobs", "9", "--frames", "0:2"], capsys)
    assert status == 0, err
    assert "--jobs 9: the run has 2 frames; using 2" in caplog.text
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["timing"]["workers"] == "2 processes"


def test_a_scheduler_that_does_not_answer_is_one_line_and_exit_2(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """``--scheduler`` at a closed port: one line naming the address, status 2, nothing written."""
    out = tmp_path / "o"
    status, _, err = run_cli(
        ["process", str(evaporation.path), "--out", str(out), "--scheduler", "127.0.0.1:9"],
        capsys,
    )
    assert status == 2
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "--scheduler 127.0.0.1:9" in lines[0], err
    assert not out.exists()


def test_a_worker_that_cannot_see_the_file_is_named(
    tmp_path: Path, runners: dict[str, ChunkRunner]
) -> None:
    """A task on a path the workers do not have: an InputError naming the worker's host."""
    task = make_tasks(
        tmp_path / "elsewhere.h5",
        range(4),
        [range(0, 4)],
        peaks=(),
        frame_shape=(128, 128),
        saturation=None,
    )[0]
    with pytest.raises(InputError, match=r"a worker on .* cannot read the input: .*elsewhere"):
        measure_chunk(task)
    with open_runner(1) as runner, pytest.raises(InputError, match="cannot read the input"):
        list(runner.run([task]))
    with pytest.raises(InputError, match="cannot read the input"):
        list(runners["dask local"].run([task]))


def test_what_fails_on_the_clients_loop_after_it_closes_is_no_error(
    runners: dict[str, ChunkRunner], caplog: pytest.LogCaptureFixture
) -> None:
    """The client's loop reports a future dropped at its close at debug level: asyncio's
    own handler printed "ERROR asyncio: Future exception was never retrieved" after an
    interrupted Dask run's last line (CI, stop 31)."""
    runner = runners["dask local"]
    assert isinstance(runner, DaskRunner)
    context = {"message": "Future exception was never retrieved"}
    with caplog.at_level(logging.DEBUG):
        runner.client.loop.asyncio_loop.call_exception_handler(context)
    said = [(r.name, r.levelno) for r in caplog.records if "never retrieved" in r.getMessage()]
    assert said == [("holoview.headless.parallel.dask_cluster", logging.DEBUG)], said


def test_a_worker_that_sees_another_file_is_refused(evaporation: Simulated) -> None:
    """Frames of another shape at the task's path: refused, not measured wrongly."""
    task = ChunkTask(str(evaporation.path), 0, (0, 1), (), (256, 256), None)
    with pytest.raises(InputError, match="another file by that name"):
        measure_chunk(task)


@pytest.mark.slow
def test_a_folder_and_a_glob_of_recordings(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """A folder of recordings: one folder each and index.csv of their rates; a glob likewise."""
    runs = tmp_path / "runs"
    runs.mkdir()
    for name in ("day2.h5", "day10.h5"):
        (runs / name).write_bytes(evaporation.path.read_bytes())
    (runs / "broken.h5").write_bytes(b"not a recording")
    status, _, err = run_cli(
        ["-q", "process", str(runs), "--out", str(tmp_path / "out"), "--jobs", "2"], capsys
    )
    assert status == 2  # one recording failed: the others are processed
    assert "broken.h5" in err
    index = (tmp_path / "out" / INDEX_CSV).read_text().splitlines()
    header, rows = index[0].split(","), [line.split(",") for line in index[1:]]
    assert [Path(r[0]).name for r in rows] == ["broken.h5", "day2.h5", "day10.h5"]
    assert [r[header.index("status")] for r in rows] == ["failed", "ok", "ok"]
    rate = header.index("fused_rate_m_per_s")
    assert float(rows[1][rate]) == float(rows[2][rate])
    assert float(rows[1][rate]) == pytest.approx(-1e-6, rel=0.01)
    assert "rate_RB1_m_per_s" in header
    for name in ("day2", "day10"):
        assert (tmp_path / "out" / name / "trends.csv").is_file()
    assert not (tmp_path / "out" / "broken" / "trends.csv").exists()
    status, _, err = run_cli(
        ["-q", "process", str(runs / "day*.h5"), "--out", str(tmp_path / "glob")], capsys
    )
    assert status == 0, err
    lines = (tmp_path / "glob" / INDEX_CSV).read_text().splitlines()
    assert len(lines) == 3
    again, _, err = run_cli(
        ["-q", "process", str(runs / "day*.h5"), "--out", str(tmp_path / "glob")], capsys
    )
    assert again == 2 and "--overwrite" in err


def test_the_pools_resource_tracker_starts_with_its_warnings_off() -> None:
    """A run refused as its pool started once ended with the resource tracker's 'leaked
    semaphore' warnings after holoview's one line (CPython's bookkeeping of stopped
    workers). The tracker, started by a pool in a fresh process, carries the -W option
    that keeps them off; the process's own warning options are left as they were."""
    code = (
        "import sys\n"
        "from multiprocessing import resource_tracker as t\n"
        "from holoview.headless.parallel.runners import ProcessRunner\n"
        "runner = ProcessRunner(1)\n"
        "print(open(f'/proc/{t._resource_tracker._pid}/cmdline').read().split(chr(0)))\n"
        "print(sys.warnoptions)\n"
        "runner.close()\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    tracker, options = done.stdout.splitlines()
    assert f"-W{TRACKER_QUIET}" in tracker
    assert options == "[]"
