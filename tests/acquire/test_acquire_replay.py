"""Replay of recordings, TIFF stacks, image folders and videos; bad files give one-line errors."""

from __future__ import annotations

import itertools
import time
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
import tifffile

from holoview.acquire import open_source, parse_source_spec
from holoview.acquire.camera_thread import CameraThread
from holoview.acquire.recorder import Recorder
from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.recording_writer import RecordingWriter
from holoview.acquire.replay import ReplaySource
from holoview.acquire.ring import FrameRing
from holoview.acquire.source import CameraNotFoundError, EndOfStream
from holoview.errors import InputError

SHAPE = (24, 32)


def stack(n: int = 5, dtype: type = np.uint16, top: int = 4096, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, top, (n, *SHAPE)).astype(dtype)


def write_h5(path: Path, data: np.ndarray, dt: float = 0.01) -> Path:
    with RecordingWriter(
        path, SHAPE, data.dtype, setup={"wavelength_m": 633e-9, "n1": 1.0}, source="test"
    ) as w:
        for i, frame in enumerate(data):
            w.append(frame, 100 + i, i * dt, 1e9 + i * dt)
    return path


def play_all(source: ReplaySource, limit: int = 1000) -> list:
    frames = []
    source.start()
    try:
        while len(frames) < limit:
            frame = source.fetch(timeout=5)
            assert frame is not None
            frames.append(frame)
    except EndOfStream:
        pass
    finally:
        source.stop()
    return frames


def test_hdf5_replay_gives_recorded_frames_ids_times_and_setup(tmp_path: Path) -> None:
    data = stack()
    path = write_h5(tmp_path / "r.h5", data)
    with open_source(f"replay:{path}", speed="fast") as source:
        assert source.kind == "hdf5"
        assert source.setup["wavelength_m"] == pytest.approx(633e-9)
        assert source.frame_shape == SHAPE
        assert source.dtype == np.uint16
        frames = play_all(source)
    np.testing.assert_array_equal(np.stack([f.data for f in frames]), data)
    assert [f.meta.frame_id for f in frames] == list(range(100, 105))
    assert [f.meta.t_device for f in frames] == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.04])


def test_recorded_speed_follows_the_timestamps(tmp_path: Path) -> None:
    path = write_h5(tmp_path / "r.h5", stack(6), dt=0.05)
    with ReplaySource(path) as source:
        t0 = time.monotonic()
        frames = play_all(source)
        elapsed = time.monotonic() - t0
    assert len(frames) == 6
    assert elapsed >= 5 * 0.05 * 0.9  # 5 intervals of 50 ms; slower is allowed under load


def test_loop_keeps_ids_and_device_times_growing(tmp_path: Path) -> None:
    path = write_h5(tmp_path / "r.h5", stack(3))
    with ReplaySource(path, speed="fast", loop=True) as source:
        frames = play_all(source, limit=7)
    ids = [f.meta.frame_id for f in frames]
    times = [f.meta.t_device for f in frames]
    assert ids == [100, 101, 102, 203, 204, 205, 306]
    assert all(b > a for a, b in itertools.pairwise(times))
    np.testing.assert_array_equal(frames[3].data, frames[0].data)


def test_step_speed_releases_one_frame_per_step(tmp_path: Path) -> None:
    path = write_h5(tmp_path / "r.h5", stack(4))
    with ReplaySource(path, speed="step") as source:
        source.start()
        assert source.fetch(timeout=0.05) is None
        assert source.step() == 0
        assert source.fetch(timeout=1).meta.frame_id == 100
        assert source.fetch(timeout=0.05) is None
        source.seek(3)
        assert source.fetch(timeout=1).meta.frame_id == 103
        source.stop()


def test_tiff_stack_and_real_single_page_tiff(tmp_path: Path, real_data: Path) -> None:
    data = stack(4)
    tifffile.imwrite(tmp_path / "s.tif", data, photometric="minisblack")
    with open_source(f"replay:{tmp_path / 's.tif'}", speed="fast") as source:
        assert source.get("n_frames") == 4
        frames = play_all(source)
    np.testing.assert_array_equal(np.stack([f.data for f in frames]), data)
    real = real_data / "paramecium_oa_oof.tif"
    with open_source(f"replay:{real}", speed="fast") as source:
        assert source.frame_shape == (1024, 1280)
        (frame,) = play_all(source)
    assert frame.data.dtype == np.uint16
    assert 0 < int(frame.data.max()) <= 1023  # 10-bit values kept raw


def test_folder_plays_in_natural_order_png_and_tiff(tmp_path: Path) -> None:
    data = stack(3, top=65536)
    cv2.imwrite(str(tmp_path / "img2.png"), data[0])
    tifffile.imwrite(tmp_path / "img10.tif", data[1])
    cv2.imwrite(str(tmp_path / "img11.png"), data[2])
    (tmp_path / "notes.txt").write_text("ignored")
    with open_source(f"replay:{tmp_path}", speed="fast") as source:
        assert source.kind == "folder"
        frames = play_all(source)
    np.testing.assert_array_equal(np.stack([f.data for f in frames]), data)


def write_video(path: Path, data: np.ndarray, fourcc: str) -> None:
    params = [cv2.VIDEOWRITER_PROP_IS_COLOR, 0]
    if data.dtype == np.uint16:
        params += [cv2.VIDEOWRITER_PROP_DEPTH, cv2.CV_16U]
    writer = cv2.VideoWriter(
        str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*fourcc), 25.0, SHAPE[::-1], params
    )
    assert writer.isOpened()
    for frame in data:
        writer.write(frame)
    writer.release()


def test_ffv1_16_bit_video_is_lossless(tmp_path: Path) -> None:
    data = stack(5)
    write_video(tmp_path / "v.mkv", data, "FFV1")
    with open_source(f"replay:{tmp_path / 'v.mkv'}", speed="fast") as source:
        assert source.get("rate_hz") == pytest.approx(25.0)
        frames = play_all(source)
    np.testing.assert_array_equal(np.stack([f.data for f in frames]), data)
    assert frames[2].meta.t_device == pytest.approx(2 / 25.0)


def test_mjpg_video_plays_as_grey(tmp_path: Path) -> None:
    data = np.repeat(np.linspace(0, 255, SHAPE[1], dtype=np.uint8)[None, :], SHAPE[0], 0)
    write_video(tmp_path / "v.avi", np.stack([data] * 3), "MJPG")
    with open_source(f"replay:{tmp_path / 'v.avi'}", speed="fast") as source:
        frames = play_all(source)
    assert len(frames) == 3
    assert frames[0].data.shape == SHAPE
    assert frames[0].data.dtype == np.uint8
    assert np.abs(frames[0].data.astype(int) - data).mean() < 8  # lossy, but the same image


def test_replay_records_back_to_identical_frames(tmp_path: Path) -> None:
    data = stack(20)
    path = write_h5(tmp_path / "in.h5", data)
    with open_source(f"replay:{path}", speed="fast") as source:
        ring = FrameRing(32, source.frame_shape, source.dtype)
        recorder = Recorder(ring, RecordingWriter(tmp_path / "out.h5", SHAPE, np.uint16))
        camera = CameraThread(source, ring)
        recorder.start()
        camera.start()
        assert camera.join(10) and recorder.join(10)
    with RecordingReader(tmp_path / "out.h5") as reader:
        np.testing.assert_array_equal(reader[:], data)
        np.testing.assert_array_equal(reader.frame_ids, 100 + np.arange(20))


def test_truncated_tiff_is_a_one_line_error(tmp_path: Path) -> None:
    tifffile.imwrite(tmp_path / "s.tif", stack(5), photometric="minisblack")
    whole = (tmp_path / "s.tif").read_bytes()
    for cut in (len(whole) // 2, len(whole) - 100, 6):
        (tmp_path / "t.tif").write_bytes(whole[:cut])
        with pytest.raises(InputError, match=r"t\.tif: (truncated|not a readable) TIFF") as info:
            open_source(f"replay:{tmp_path / 't.tif'}")
        assert "\n" not in str(info.value)


def test_hdf5_without_frames_is_a_one_line_error(tmp_path: Path) -> None:
    with RecordingWriter(tmp_path / "empty.h5", SHAPE, np.uint16):
        pass
    with pytest.raises(InputError, match="holds no frames"):
        open_source(f"replay:{tmp_path / 'empty.h5'}")
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["data"] = np.zeros(3)
    with pytest.raises(InputError, match="not a holoview recording"):
        open_source(f"replay:{tmp_path / 'other.h5'}")


def test_folder_of_mixed_sizes_names_the_odd_file(tmp_path: Path) -> None:
    cv2.imwrite(str(tmp_path / "a1.png"), np.zeros(SHAPE, np.uint8))
    cv2.imwrite(str(tmp_path / "a2.png"), np.zeros((10, 10), np.uint8))
    with pytest.raises(InputError, match=r"mixed sizes: a2\.png is \(10, 10\)"):
        open_source(f"replay:{tmp_path}")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="no TIFF or PNG"):
        open_source(f"replay:{empty}")


def test_video_that_will_not_open_is_a_one_line_error(tmp_path: Path) -> None:
    (tmp_path / "bad.avi").write_bytes(b"RIFF\0\0\0\0AVI garbage" * 10)
    with pytest.raises(InputError, match=r"bad\.avi: (OpenCV cannot open|the video holds no)"):
        open_source(f"replay:{tmp_path / 'bad.avi'}")


def test_missing_path_and_unknown_type(tmp_path: Path) -> None:
    with pytest.raises(CameraNotFoundError, match="no such file"):
        open_source(f"replay:{tmp_path / 'nothing.h5'}")
    (tmp_path / "x.dat").write_bytes(b"\0")
    with pytest.raises(InputError, match=r"unknown file type \.dat"):
        open_source(f"replay:{tmp_path / 'x.dat'}")


def test_unreadable_frame_mid_stream_stops_cleanly_keeping_the_rest(tmp_path: Path) -> None:
    folder = tmp_path / "imgs"
    folder.mkdir()
    data = stack(4, dtype=np.uint8, top=256)
    for i, frame in enumerate(data):
        cv2.imwrite(str(folder / f"f{i}.png"), frame)
    with open_source(f"replay:{folder}", speed="fast") as source:
        (folder / "f2.png").write_bytes((folder / "f2.png").read_bytes()[:40])  # damaged later
        ring = FrameRing(8, source.frame_shape, source.dtype)
        recorder = Recorder(ring, RecordingWriter(tmp_path / "out.h5", SHAPE, np.uint8))
        camera = CameraThread(source, ring)
        recorder.start()
        camera.start()
        assert camera.join(10) and recorder.join(10)
    assert isinstance(camera.error, InputError)
    assert "f2.png" in str(camera.error)
    with RecordingReader(tmp_path / "out.h5") as reader:
        np.testing.assert_array_equal(reader[:], data[:2])


@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        ("sim", ("sim", "")),
        ("sim:waves", ("sim", "waves")),
        ("aravis", ("aravis", "")),
        ("aravis:Aravis-Fake-GV01", ("aravis", "Aravis-Fake-GV01")),
        ("aravis:192.168.0.7", ("aravis", "192.168.0.7")),
        ("v4l2:2", ("v4l2", "2")),
        ("replay:/a/b:c.h5", ("replay", "/a/b:c.h5")),
    ],
)
def test_source_specs_parse(spec: str, expected: tuple[str, str]) -> None:
    assert tuple(parse_source_spec(spec)) == expected


@pytest.mark.parametrize(
    ("spec", "match"),
    [("webcam", "unknown source"), ("replay", "needs a path"), ("v4l2:x", "index")],
)
def test_bad_source_specs_are_one_line_errors(spec: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        parse_source_spec(spec)


def test_replay_follows_a_recording_still_being_written(tmp_path: Path) -> None:
    data = stack(5)
    path = tmp_path / "live.h5"
    with RecordingWriter(path, SHAPE, np.uint16) as writer:
        for i in range(3):
            writer.append(data[i], i, float(i), float(i))
        writer.flush()
        with ReplaySource(path, speed="fast") as source:
            source.start()
            got = [source.fetch(timeout=1) for _ in range(3)]
            for i in range(3, 5):
                writer.append(data[i], i, float(i), float(i))
            writer.flush()
            got += [source.fetch(timeout=1) for _ in range(2)]
            with pytest.raises(EndOfStream):
                source.fetch(timeout=1)
            source.stop()
    np.testing.assert_array_equal(np.stack([f.data for f in got]), data)
