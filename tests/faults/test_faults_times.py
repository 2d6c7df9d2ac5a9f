"""Time stamps that cannot be trusted, and recordings read while they are written.

The clock rule (:mod:`holoview.acquire.frame_times`): the camera's clock where every
time is finite, runs forward and jumps nowhere; else the host's arrival times; else
``--fps``. Before, a 1e6 s jump in the camera's clock gave a rate of -0.0 um/min in
silence, a partly NaN, reversed or standing camera clock switched to the host's in
silence, a ``t_device_s`` of 10 rows processed 10 of the frames in silence, and a 2-D or
string column was a TypeError traceback. Now the rule used is in a warning and in
``summary.json``'s notes, and where no clock is usable the line says to give ``--fps``.
"""

from __future__ import annotations

import csv
import json
import logging
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
from faults_helpers import one_line_error, run_holoview, run_main

from holoview.acquire.frame_times import clock_problem
from holoview.acquire.recording_writer import RecordingWriter


def _jump(f: h5py.File) -> None:
    t = f["t_device_s"][:]
    t[20:] += 1e6
    f["t_device_s"][:] = t


def _part_nan(f: h5py.File) -> None:
    t = f["t_device_s"][:]
    t[10:14] = np.nan
    f["t_device_s"][:] = t


def _reversed(f: h5py.File) -> None:
    f["t_device_s"][:] = f["t_device_s"][:][::-1]


def _zero(f: h5py.File) -> None:
    f["t_device_s"][:] = 0.0


def _two_d(f: h5py.File) -> None:
    t = f["t_device_s"][:]
    del f["t_device_s"]
    f["t_device_s"] = np.stack([t, t], axis=1)


def _strings(f: h5py.File) -> None:
    t = f["t_device_s"][:]
    del f["t_device_s"]
    f["t_device_s"] = np.array([repr(v).encode() for v in t])


CAMERA_DAMAGE: dict[str, tuple[Callable[[h5py.File], None], str]] = {
    "jump-1e6-s": (_jump, "it jumps by 1e+06 s at frame 20 (the median step is 0.05 s)"),
    "partly-nan": (_part_nan, "4 of its 40 times are not finite (the first at frame 10)"),
    "reversed": (_reversed, "it runs backwards"),
    "all-zero": (_zero, "it stands still"),
    "2-d": (_two_d, "/t_device_s is float64 of shape (40, 2), not one number per frame"),
    "strings": (_strings, "/t_device_s is |S"),
}


def damaged(sim_recording: Path, tmp_path: Path, change: Callable[[h5py.File], None]) -> Path:
    path = tmp_path / "run.h5"
    path.write_bytes(sim_recording.read_bytes())
    with h5py.File(path, "a") as f:
        change(f)
    return path


def trend_times(out: Path) -> np.ndarray:
    with open(out / "trends.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    first = rows[0]["label"]
    return np.array([float(r["time_s"]) for r in rows if r["label"] == first])


@pytest.mark.parametrize("damage", list(CAMERA_DAMAGE))
def test_a_damaged_camera_clock_gives_the_hosts_with_the_reason(
    sim_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture, caplog, damage: str
) -> None:
    change, reason = CAMERA_DAMAGE[damage]
    path = damaged(sim_recording, tmp_path, change)
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING):
        done = run_main(["-q", "process", str(path), "--out", str(out)], capsys)
    assert done.status == 0, done.err
    assert "Traceback" not in done.err
    warned = [r.getMessage() for r in caplog.records if "frame times" in r.getMessage()]
    assert len(warned) == 1 and reason in warned[0], caplog.text
    assert "host's arrival times" in warned[0] and str(path) in warned[0]
    summary = json.loads((out / "summary.json").read_text())
    notes = [n for n in summary["notes"] if n.startswith("frame times of frames 0..39")]
    assert len(notes) == 1 and reason in notes[0], summary["notes"]
    with h5py.File(sim_recording, "r") as f:
        host = f["t_host_s"][:]
    np.testing.assert_allclose(trend_times(out), host - host[0], atol=1e-9)


def test_fps_replaces_a_damaged_clock_and_is_named(
    sim_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    path = damaged(sim_recording, tmp_path, _jump)
    out = tmp_path / "out"
    done = run_main(["-q", "process", str(path), "--out", str(out), "--fps", "20"], capsys)
    assert done.status == 0, done.err
    summary = json.loads((out / "summary.json").read_text())
    assert (
        "frame times of frames 0..39: --fps 20 (the file's own times not used)" in summary["notes"]
    )
    np.testing.assert_allclose(trend_times(out), np.arange(40) / 20.0)
    with h5py.File(sim_recording, "r") as f:  # the simulator's truth, fitted here
        t, h = f["truth/time_s"][:], f["truth/mean_height_m"][:]
    true_rate = np.polyfit(t, h, 1)[0]
    assert summary["fused"]["rate_m_per_s"] == pytest.approx(true_rate, rel=0.05)


def test_a_sound_camera_clock_is_named_without_a_warning(
    sim_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture, caplog
) -> None:
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING):
        done = run_main(["-q", "process", str(sim_recording), "--out", str(out)], capsys)
    assert done.status == 0, done.err
    assert "frame times" not in caplog.text
    summary = json.loads((out / "summary.json").read_text())
    assert "frame times of frames 0..39: the camera's clock (t_device_s)" in summary["notes"]
    np.testing.assert_allclose(trend_times(out), np.arange(40) / 20.0)


def test_no_usable_clock_is_one_line_asking_for_fps(
    sim_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    def both(f: h5py.File) -> None:
        f["t_device_s"][:] = np.nan
        host = f["t_host_s"][:]
        host[30] = host[29] - 5.0  # the host's clock set back (NTP)
        f["t_host_s"][:] = host

    path = damaged(sim_recording, tmp_path, both)
    done = run_main(["-q", "process", str(path), "--out", str(tmp_path / "o")], capsys)
    one_line_error(
        done,
        2,
        str(path),
        "frames 0..39 have no usable times",
        "it holds no time",
        "steps by -5 s at frame 30",
        "give --fps",
    )
    done = run_main(
        ["-q", "process", str(path), "--out", str(tmp_path / "o"), "--fps", "20"], capsys
    )
    assert done.status == 0, done.err


def test_a_short_time_column_is_said_with_the_frames_left_out(
    sim_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture, caplog
) -> None:
    path = damaged(sim_recording, tmp_path, lambda f: f["t_device_s"].resize((10,)))
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING):
        done = run_main(["-q", "process", str(path), "--out", str(out)], capsys)
    assert done.status == 0, done.err
    said = "only the first 10 of the 40 frames stored are complete (/t_device_s holds 10 rows)"
    assert said in caplog.text
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"]["processed"] == 10
    assert any(said in note for note in summary["notes"]), summary["notes"]


def test_a_replay_paces_a_jumping_clock_by_the_hosts(
    sim_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """At the recorded pace, a 1e6 s jump would have held the replay for eleven days."""
    path = damaged(sim_recording, tmp_path, _jump)
    copy = tmp_path / "copy.h5"
    done = run_holoview("-q", "record", str(copy), "--source", f"replay:{path}", timeout=60)
    assert done.status == 0, done.err
    with h5py.File(copy, "r") as f:
        assert f["frames"].shape[0] == 40


def test_a_recording_being_written_is_a_snapshot_said_so(
    sim_recording: Path, tmp_path: Path
) -> None:
    """Processed while its writer holds it open (SWMR): the frames flushed, and a note."""
    with h5py.File(sim_recording, "r") as f:
        frames, setup = f["frames"][:], dict(f["setup"].attrs)
    path = tmp_path / "live.h5"
    out = tmp_path / "out"
    with RecordingWriter(path, frames.shape[1:], frames.dtype, setup=setup, swmr=True) as w:
        for i, frame in enumerate(frames[:30]):
            w.append(frame, i, i / 20.0, 1e9 + i / 20.0)
        w.flush()
        done = run_holoview("process", str(path), "--out", str(out), "--fluid", "water")
        for i, frame in enumerate(frames[30:], start=30):
            w.append(frame, i, i / 20.0, 1e9 + i / 20.0)
    assert done.status == 0, done.err
    said = "was open for writing when it was read"
    assert said in done.err and "the 30 frames flushed by then are read, as a snapshot" in done.err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"]["processed"] == 30
    assert any(said in note for note in summary["notes"]), summary["notes"]


def test_frames_the_camera_lost_are_no_jump() -> None:
    """A gap of 150 frames in the counter makes a step 150 times the median: honest."""
    ids = np.r_[0:20, 170:190]
    times = ids / 60.0
    frames = range(40)
    assert clock_problem(times, frames, ids) is None
    assert "jumps by 2.52 s at frame 20" in (clock_problem(times, frames) or "")
    bursts = np.repeat(np.arange(20) / 3.0, 2) + np.tile([0.0, 1e-5], 20)  # two per read
    assert clock_problem(bursts, frames) is None  # steps under a second are no jump


def _lose_frames(source: Path, path: Path, lost: slice) -> None:
    """Copy a recording as a camera that lost the frames ``lost`` would have written it
    (its frame counter and clocks stepping over them, the truth of the frames kept)."""
    with h5py.File(source, "r") as f:
        n = f["frames"].shape[0]
        keep = np.delete(np.arange(n), lost)
        per_frame = {"frames", "frame_id", "t_device_s", "t_host_s"}
        with h5py.File(path, "w") as out:
            for key, value in f.attrs.items():
                out.attrs[key] = value

            def copy(name: str, item: h5py.HLObject) -> None:
                if isinstance(item, h5py.Group):
                    group = out.require_group(name)
                    group.attrs.update(item.attrs)
                    return
                data = item[()]
                if name in per_frame or (name.startswith("truth/") and len(data) == n):
                    data = data[keep]
                out.create_dataset(name, data=data).attrs.update(item.attrs)

            f.visititems(copy)


@pytest.mark.parametrize("lost", [np.s_[15:25], np.s_[10:30]])
def test_frames_the_camera_lost_keep_the_height_across_the_gap(
    tmp_path: Path, capsys: pytest.CaptureFixture, lost: slice
) -> None:
    """Frames lost at 20 frames/s, the level falling 30 um/min (25 nm a frame): the
    fused height's step across the gap spans 11 or 21 intervals. Before, it was
    predicted as one, the peaks' phases were resolved turns off and every later height
    stood off: the rate 29 % low, or of the wrong sign, and nothing said of the loss."""
    full, path = tmp_path / "full.h5", tmp_path / "lost.h5"
    argv = ["-q", "simulate", str(full), "--scenario", "evaporation", "--size", "128"]
    argv += ["--frames", "40", "--fps", "20", "--seed", "5", "--evaporation-um-per-min", "30"]
    assert run_main(argv, capsys).status == 0
    _lose_frames(full, path, lost)
    out = tmp_path / "out"
    done = run_main(["-q", "process", str(path), "--out", str(out)], capsys)
    assert done.status == 0, done.err
    summary = json.loads((out / "summary.json").read_text())
    with h5py.File(path, "r") as f:  # the simulator's truth of the frames kept
        t, h = f["truth/time_s"][:], f["truth/mean_height_m"][:]
    assert summary["fused"]["rate_m_per_s"] == pytest.approx(np.polyfit(t, h, 1)[0], rel=0.01)
    with h5py.File(out / "results.h5", "r") as f:
        fused = f["trends/fused_height_m"][:]
    np.testing.assert_allclose(fused - fused[0], (h - h[0]), atol=2e-9)
    count = lost.stop - lost.start
    said = f"{count} frames lost in 1 gap (the longest, {count} frames, "
    said += f"after frame {lost.start - 1} at {(lost.start - 1) / 20:.4g} s)"
    assert said in " ".join(summary["notes"]), summary["notes"]
    assert summary["input"]["frames_lost"] == count  # the camera's rate, not the mean's
    assert summary["parameters"]["fps_hz"] == pytest.approx(20.0, rel=1e-9)
