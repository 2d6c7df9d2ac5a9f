"""The HDF5 recording format: round trip, self-description, SWMR following, SIGKILL."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from holoview.acquire.recording import FORMAT_NAME, FORMAT_VERSION
from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.recording_writer import RecordingWriter
from holoview.errors import InputError

HELPERS = Path(__file__).resolve().parents[1] / "helpers"

SETUP = {"wavelength_m": 632.8e-9, "pixel_pitch_m": 5.5e-6, "n1": 1.0, "n2": 1.333}
SETTINGS = {"exposure_s": 2e-3, "gain_db": 1.5, "roi": ((0, 0, 40, 30), "pixel"), "note": None}


def frames(n: int, shape: tuple[int, int] = (30, 40), seed: int = 0) -> np.ndarray:
    """Random 12-bit frames in uint16, as a Mono12 camera gives them."""
    return np.random.default_rng(seed).integers(0, 4096, (n, *shape), dtype=np.uint16)


def write(path: Path, data: np.ndarray, **kwargs: object) -> None:
    with RecordingWriter(
        path, data.shape[1:], data.dtype, setup=SETUP, settings=SETTINGS, source="test", **kwargs
    ) as writer:
        for i, frame in enumerate(data):
            writer.append(frame, 10 + 2 * i, 0.5 * i, 1000.0 + i)


def test_the_frame_rate_is_the_cameras_where_it_timed_every_frame(tmp_path: Path) -> None:
    with RecordingWriter(tmp_path / "r.h5", (30, 40), np.uint16, setup=SETUP, source="t") as w:
        for i, frame in enumerate(frames(5)):
            w.append(frame, i, math.nan if i == 2 else 0.25 * i, 100.0 + 0.5 * i)
    with RecordingReader(tmp_path / "r.h5") as reader:
        assert reader.fps == pytest.approx(2.0)  # one frame without the camera's time: host's


def test_round_trip_keeps_frames_ids_timestamps_and_raw_values(tmp_path: Path) -> None:
    data = frames(7)
    before = data.copy()
    write(tmp_path / "r.h5", data, pixel_format="Mono12", significant_bits=12)
    np.testing.assert_array_equal(data, before)  # the writer did not touch its input
    with RecordingReader(tmp_path / "r.h5") as reader:
        assert len(reader) == 7
        assert reader.frame_shape == (30, 40)
        assert reader.dtype == np.uint16
        np.testing.assert_array_equal(reader[:], data)
        np.testing.assert_array_equal(np.stack(list(reader)), data)
        np.testing.assert_array_equal(reader.frame(-1), data[-1])
        np.testing.assert_array_equal(reader[5:1:-2], data[5:1:-2])
        np.testing.assert_array_equal(reader[::3], data[::3])
        assert reader[7:].shape == (0, 30, 40)
        np.testing.assert_array_equal(reader.frame_ids, 10 + 2 * np.arange(7))
        np.testing.assert_allclose(reader.t_device, 0.5 * np.arange(7))
        np.testing.assert_allclose(reader.t_host, 1000.0 + np.arange(7))
        assert reader.fps == pytest.approx(2.0)  # the camera's clock (the host's says 1)
        assert reader.pixel_format == "Mono12"
        assert reader.significant_bits == 12
        with pytest.raises(IndexError):
            reader.frame(7)


def test_file_describes_itself(tmp_path: Path) -> None:
    write(tmp_path / "r.h5", frames(2))
    with RecordingReader(tmp_path / "r.h5") as reader:
        assert reader.format_version == FORMAT_VERSION
        assert reader.setup == pytest.approx(SETUP)
        assert reader.setup_units == {"wavelength_m": "m", "pixel_pitch_m": "m", "n1": "", "n2": ""}
        assert reader.settings["exposure_s"] == pytest.approx(2e-3)
        assert list(reader.settings["roi"]) == [0, 0, 40, 30]
        assert "note" not in reader.settings
        assert reader.settings_units == {"exposure_s": "s", "gain_db": "dB", "roi": "pixel"}
        assert reader.source == "test"
        assert len(reader.uuid) == 36
        assert reader.created_utc.endswith("+00:00")
    with h5py.File(tmp_path / "r.h5", "r") as f:
        assert f.attrs["format"] == FORMAT_NAME
        assert f["frames"].chunks == (1, 30, 40)
        assert f["t_host_s"].attrs["unit"] == "s"


def test_every_recording_has_its_own_uuid(tmp_path: Path) -> None:
    write(tmp_path / "a.h5", frames(1))
    write(tmp_path / "b.h5", frames(1))
    with RecordingReader(tmp_path / "a.h5") as a, RecordingReader(tmp_path / "b.h5") as b:
        assert a.uuid != b.uuid


def test_groups_added_after_closing_are_ignored_by_readers(tmp_path: Path) -> None:
    data = frames(3)
    write(tmp_path / "r.h5", data)
    with h5py.File(tmp_path / "r.h5", "a") as f:
        truth = f.create_group("truth")
        truth.create_dataset("height_m", data=np.zeros((3, 30, 40)))
    with RecordingReader(tmp_path / "r.h5") as reader:
        assert len(reader) == 3
        np.testing.assert_array_equal(reader[:], data)


def test_reader_follows_a_live_writer(tmp_path: Path) -> None:
    data = frames(6)
    path = tmp_path / "live.h5"
    with RecordingWriter(path, (30, 40), np.uint16) as writer:
        writer.append(data[0], 0, 0.0, 0.0)
        writer.flush()
        with RecordingReader(path) as reader:
            assert len(reader) == 1
            for i in range(1, 6):
                writer.append(data[i], i, float(i), float(i))
            writer.flush()
            assert len(reader) == 1  # not until refresh
            assert reader.refresh() == 6
            np.testing.assert_array_equal(reader[:], data)


def test_experiment_and_its_changes_are_stored_with_the_frame_they_hold_from(
    tmp_path: Path,
) -> None:
    data = frames(5)
    path = tmp_path / "exp.h5"
    first, later = '{"format": "holoview-experiment", "n": "\u00b5"}', '{"changed": 1}'
    with RecordingWriter(path, (30, 40), np.uint16, experiment=first) as writer:
        writer.append(data[0], 0, 0.0, 0.0)
        writer.flush()
        with RecordingReader(path) as reader:  # a reader following the live file sees them
            writer.append(data[1], 1, 1.0, 1.0)
            writer.note_experiment(later)  # holds from frame 2
            for i in range(2, 5):
                writer.append(data[i], i, float(i), float(i))
            writer.flush()
            assert reader.experiments() == [(0, first), (2, later)]
    with h5py.File(path, "r") as f:  # plain h5py reads it too
        size = len(first.encode())  # the micro sign takes two bytes
        assert f["experiment/changes"][:].tolist() == [[0, 0, size], [2, size, len(later)]]


def test_format_1_0_recordings_without_an_experiment_still_open(tmp_path: Path) -> None:
    path = tmp_path / "old.h5"
    write(path, frames(3))
    with h5py.File(path, "a") as f:
        del f["experiment"]
        f.attrs["format_version"] = "1.0"
    with RecordingReader(path) as reader:
        assert reader.format_version == "1.0" and len(reader) == 3
        assert reader.experiments() == []


def test_flush_if_due_flushes_after_the_interval(tmp_path: Path) -> None:
    with RecordingWriter(tmp_path / "r.h5", (4, 4), np.uint8, flush_interval_s=0.05) as writer:
        assert not writer.flush_if_due()  # nothing appended
        writer.append(np.zeros((4, 4), np.uint8), 0, 0.0, 0.0)
        assert not writer.flush_if_due()
        time.sleep(0.06)
        assert writer.flush_if_due()
        assert not writer.flush_if_due()


@pytest.mark.parametrize(
    ("frame", "match"),
    [
        (np.zeros((30, 41), np.uint16), "shape"),
        (np.zeros((30, 40), np.uint8), "dtype"),
    ],
)
def test_append_rejects_a_mismatched_frame(tmp_path: Path, frame: np.ndarray, match: str) -> None:
    with RecordingWriter(tmp_path / "r.h5", (30, 40), np.uint16) as writer:
        with pytest.raises(InputError, match=match):
            writer.append(frame, 0, 0.0, 0.0)
        assert len(writer) == 0


def test_writer_never_overwrites(tmp_path: Path) -> None:
    write(tmp_path / "r.h5", frames(2))
    with pytest.raises(InputError, match="exists"):
        RecordingWriter(tmp_path / "r.h5", (30, 40), np.uint16)
    with RecordingReader(tmp_path / "r.h5") as reader:
        assert len(reader) == 2


def test_writer_rejects_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="does not exist"):
        RecordingWriter(tmp_path / "no" / "r.h5", (4, 4), np.uint8)
    with pytest.raises(InputError, match="shape"):
        RecordingWriter(tmp_path / "r.h5", (4,), np.uint8)
    with pytest.raises(InputError, match="dtype"):
        RecordingWriter(tmp_path / "r.h5", (4, 4), np.complex64)
    with pytest.raises(InputError, match="cannot store"):
        RecordingWriter(tmp_path / "r.h5", (4, 4), np.uint8, settings={"x": object()})
    assert not (tmp_path / "r.h5").exists()


def test_reader_rejects_files_that_are_not_recordings(tmp_path: Path) -> None:
    (tmp_path / "text.h5").write_text("not hdf5")
    with pytest.raises(InputError, match="not a readable HDF5"):
        RecordingReader(tmp_path / "text.h5")
    with pytest.raises(InputError, match="no such file"):
        RecordingReader(tmp_path / "missing.h5")
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["frames"] = np.zeros((2, 3, 3))
    with pytest.raises(InputError, match="not a holoview recording"):
        RecordingReader(tmp_path / "other.h5")
    write(tmp_path / "noframes.h5", frames(1))
    with h5py.File(tmp_path / "noframes.h5", "a") as f:
        del f["frames"]
    with pytest.raises(InputError, match="no frames"):
        RecordingReader(tmp_path / "noframes.h5")
    write(tmp_path / "future.h5", frames(1))
    with h5py.File(tmp_path / "future.h5", "a") as f:
        f.attrs["format_version"] = "2.0"
    with pytest.raises(InputError, match=r"version '2\.0'"):
        RecordingReader(tmp_path / "future.h5")


@pytest.mark.slow
def test_recording_survives_sigkill_losing_at_most_one_second(tmp_path: Path) -> None:
    path = tmp_path / "killed.h5"
    rate = 100.0
    child = subprocess.Popen(
        [sys.executable, str(HELPERS / "recording_writer_child.py"), str(path), str(rate)],
        stdout=subprocess.PIPE,
        text=True,
    )
    appended_at: list[float] = []
    try:
        assert child.stdout is not None
        while len(appended_at) < 150:
            line = child.stdout.readline()
            assert line.startswith("appended"), "the writer child stopped early"
            appended_at.append(time.monotonic())
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=10)
        if child.stdout is not None:
            child.stdout.close()
        killed_at = time.monotonic()
    # read times lag append times, so this undercounts what was more than 1 s old
    older_than_a_second = sum(t < killed_at - 1.0 for t in appended_at)
    with RecordingReader(path) as reader:
        n = len(reader)
        assert older_than_a_second <= n
        assert n >= 1
        ids = reader.frame_ids
        np.testing.assert_array_equal(ids, np.arange(n))
        np.testing.assert_array_equal(reader[:][:, 0, 0], np.arange(n))
