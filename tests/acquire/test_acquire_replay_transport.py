"""Steering a replay: pause, step, seek, speed, loop, hold at the end; files that go away."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from holoview.acquire import camera_thread
from holoview.acquire.camera_thread import CameraThread
from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.recording_writer import RecordingWriter
from holoview.acquire.replay import ReplaySource
from holoview.acquire.ring import FrameRing
from holoview.acquire.source import EndOfStream, Frame
from holoview.errors import InputError

SHAPE = (16, 24)


def write_h5(path: Path, n: int = 10, dt: float = 0.01) -> Path:
    """A recording whose frame ``i`` is filled with ``i`` (ids 100 + i, device time i dt)."""
    with RecordingWriter(path, SHAPE, np.uint16, source="test") as writer:
        for i in range(n):
            writer.append(np.full(SHAPE, i, np.uint16), 100 + i, i * dt, 1e9 + i * dt)
    return path


def fetch(source: ReplaySource, timeout: float = 2.0) -> Frame:
    frame = source.fetch(timeout=timeout)
    assert frame is not None
    return frame


def test_frames_carry_their_index_and_one_segment_while_played_in_order(tmp_path: Path) -> None:
    with ReplaySource(write_h5(tmp_path / "r.h5", 5), speed="fast") as source:
        source.start()
        frames = [fetch(source) for _ in range(5)]
        source.stop()
    assert [f.meta.file_index for f in frames] == [0, 1, 2, 3, 4]
    assert [int(f.data[0, 0]) for f in frames] == [0, 1, 2, 3, 4]
    assert {f.meta.segment for f in frames} == {0}


def test_pause_stops_frames_and_resume_plays_on_from_the_next(tmp_path: Path) -> None:
    with ReplaySource(write_h5(tmp_path / "r.h5"), speed="fast") as source:
        source.start()
        assert fetch(source).meta.file_index == 0
        source.pause()
        assert source.paused
        assert source.fetch(timeout=0.1) is None
        source.resume()
        assert not source.paused
        assert fetch(source).meta.file_index == 1
        source.stop()


def test_steps_move_one_frame_either_way_and_pause(tmp_path: Path) -> None:
    with ReplaySource(write_h5(tmp_path / "r.h5"), speed="fast") as source:
        source.start()
        for _ in range(4):
            fetch(source)
        assert source.shown == 3
        assert source.step(-1) == 2
        assert source.paused
        back = fetch(source)
        assert (back.meta.file_index, int(back.data[0, 0])) == (2, 2)
        assert source.fetch(timeout=0.1) is None  # paused after a step
        assert source.step(1) == 3
        forward = fetch(source)
        assert forward.meta.file_index == 3
        assert source.step(-10) == 0  # clamped to the first frame
        assert fetch(source).meta.file_index == 0
        source.stop()


def test_a_jump_starts_a_new_segment_a_step_forward_does_not(tmp_path: Path) -> None:
    with ReplaySource(write_h5(tmp_path / "r.h5"), speed="fast") as source:
        source.start()
        first = [fetch(source) for _ in range(3)]  # 0, 1, 2
        source.pause()
        source.seek(7)
        sought = fetch(source)
        source.step(1)
        after = fetch(source)
        source.step(-1)
        back = fetch(source)
        source.stop()
    assert [f.meta.segment for f in first] == [0, 0, 0]
    assert (sought.meta.file_index, sought.meta.segment) == (7, 1)
    assert (after.meta.file_index, after.meta.segment) == (8, 1)
    assert (back.meta.file_index, back.meta.segment) == (7, 2)


def test_a_seek_opens_a_segment_even_to_the_frame_after_the_one_shown(tmp_path: Path) -> None:
    # a window paused where play had stopped (frame 3 here) and sought the next frame: its
    # maps must start from it as after any seek, whatever frame play had reached
    with ReplaySource(write_h5(tmp_path / "r.h5"), speed="fast") as source:
        source.start()
        played = [fetch(source) for _ in range(4)]  # 0 to 3
        source.pause()
        assert source.shown == 3 and source.segment == 0
        source.seek(4)
        sought = fetch(source)
        source.step(1)
        after = fetch(source)
        source.seek(5)  # the frame shown, again (a window's new settings)
        again = fetch(source)
        source.seek(9)
        source.step(-3)  # from the frame sought, before it came: frame 6, after 5
        stepped = fetch(source)
        source.stop()
    assert {f.meta.segment for f in played} == {0}
    assert (sought.meta.file_index, sought.meta.segment) == (4, 1)
    assert (after.meta.file_index, after.meta.segment) == (5, 1)
    assert (again.meta.file_index, again.meta.segment) == (5, 2)
    assert (stepped.meta.file_index, stepped.meta.segment) == (6, 2)


def test_seek_while_playing_goes_on_from_the_frame_sought(tmp_path: Path) -> None:
    with ReplaySource(write_h5(tmp_path / "r.h5"), speed="fast") as source:
        source.start()
        fetch(source)
        assert source.seek(6) == 6
        assert [fetch(source).meta.file_index for _ in range(3)] == [6, 7, 8]
        source.stop()


@pytest.mark.parametrize("index", [10, 500, -1])
def test_seek_outside_the_file_is_a_one_line_error(tmp_path: Path, index: int) -> None:
    with ReplaySource(write_h5(tmp_path / "r.h5"), speed="fast") as source:
        source.start()
        fetch(source)
        with pytest.raises(
            InputError, match=r"frame -?\d+ is outside r\.h5: it has 10 frames, 0 to 9"
        ):
            source.seek(index)
        assert fetch(source).meta.file_index == 1  # the replay goes on untouched
        source.stop()


def test_speed_factor_scales_the_recorded_pace(tmp_path: Path) -> None:
    path = write_h5(tmp_path / "r.h5", n=9, dt=0.04)
    timings = {}
    for factor in (1.0, 4.0):
        with ReplaySource(path, speed_factor=factor) as source:
            source.start()
            t0 = time.monotonic()
            for _ in range(9):
                fetch(source)
            timings[factor] = time.monotonic() - t0
            source.stop()
    assert timings[1.0] >= 8 * 0.04 * 0.9
    assert timings[4.0] < timings[1.0] / 2
    with ReplaySource(path) as source:
        assert source.set("speed_factor", 0.5) == 0.5
        with pytest.raises(InputError, match="outside"):
            source.set("speed_factor", 100.0)


def test_hold_pauses_on_the_last_frame_and_resume_starts_over(tmp_path: Path) -> None:
    with ReplaySource(write_h5(tmp_path / "r.h5", 3), speed="fast", hold=True) as source:
        source.start()
        assert [fetch(source).meta.file_index for _ in range(3)] == [0, 1, 2]
        assert source.fetch(timeout=0.1) is None  # held, not ended
        assert source.held and source.paused and source.shown == 2
        source.resume()
        again = fetch(source)
        assert (again.meta.file_index, again.meta.segment) == (0, 1)
        source.stop()


def test_a_second_pass_shows_each_frame_while_another_reader_has_the_file_open(
    tmp_path: Path,
) -> None:
    """The replay's end refreshes its file; with the window's whole-run measurement reading
    the same file meanwhile, HDF5 then gave every frame of the next pass the first one's
    pixels (the Waves panel's flaky real-window test)."""
    path = write_h5(tmp_path / "r.h5", 6)
    with (
        RecordingReader(path) as measurement,
        ReplaySource(path, speed="fast", hold=True) as source,
    ):
        source.start()
        first = [int(fetch(source).data[0, 0]) for _ in range(6)]
        assert source.fetch(timeout=0.1) is None and source.held  # its end: the file refreshed
        source.resume()
        second = [fetch(source) for _ in range(6)]
        source.stop()
        assert [int(measurement.frame(i)[0, 0]) for i in range(6)] == list(range(6))
    assert first == list(range(6))
    assert [int(f.data[0, 0]) for f in second] == list(range(6))
    assert [f.meta.file_index for f in second] == list(range(6))


def test_without_hold_or_loop_the_stream_ends(tmp_path: Path) -> None:
    with ReplaySource(write_h5(tmp_path / "r.h5", 2), speed="fast") as source:
        source.start()
        fetch(source), fetch(source)
        with pytest.raises(EndOfStream):
            source.fetch(timeout=0.5)
        source.stop()


def test_loop_starts_a_new_segment_at_the_start(tmp_path: Path) -> None:
    with ReplaySource(write_h5(tmp_path / "r.h5", 3), speed="fast", loop=True) as source:
        source.start()
        frames = [fetch(source) for _ in range(5)]
        source.set("loop", False)
        source.stop()
    assert [f.meta.file_index for f in frames] == [0, 1, 2, 0, 1]
    assert [f.meta.segment for f in frames] == [0, 0, 0, 1, 1]


def test_recording_time_of_a_frame(tmp_path: Path) -> None:
    with ReplaySource(write_h5(tmp_path / "r.h5", 5, dt=0.25)) as source:
        assert source.frame_time_s(4) == pytest.approx(1.0)
    np.save(tmp_path / "s.npy", np.zeros((4, *SHAPE), np.uint16))
    with ReplaySource(tmp_path / "s.npy", rate_hz=10.0) as source:  # no timestamps: the rate
        assert source.frame_time_s(3) == pytest.approx(0.3)


def _camera_until_error(source: ReplaySource, damage) -> CameraThread:
    """Play ``source`` paced on a camera thread, call ``damage`` after a few frames."""
    ring = FrameRing(8, source.frame_shape, source.dtype)
    camera = CameraThread(source, ring)
    camera.start()
    deadline = time.monotonic() + 5
    while camera.frames < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert camera.frames >= 3
    damage()
    assert camera.join(5)
    return camera


def test_a_file_that_disappears_while_replayed_ends_with_a_message(tmp_path: Path) -> None:
    path = write_h5(tmp_path / "gone.h5", 200, dt=0.02)
    with ReplaySource(path, loop=True) as source:
        camera = _camera_until_error(source, path.unlink)
    assert isinstance(camera.error, InputError)
    text = str(camera.error)
    assert "gone.h5: the file disappeared while it was replayed (at frame" in text
    assert "\n" not in text
    assert camera.ring.closed  # the stream ended cleanly; the caller keeps running


def test_a_file_that_shrinks_while_replayed_ends_with_a_message(tmp_path: Path) -> None:
    path = tmp_path / "stack.npy"
    np.save(path, np.arange(200 * 16 * 24, dtype=np.uint16).reshape(200, *SHAPE))
    size = path.stat().st_size

    def cut() -> None:
        with open(path, "r+b") as f:
            f.truncate(size // 2)

    with ReplaySource(path, rate_hz=50.0) as source:
        camera = _camera_until_error(source, cut)
    assert isinstance(camera.error, InputError)
    assert f"stack.npy: the file shrank from {size} to {size // 2} bytes" in str(camera.error)


def test_an_image_of_a_folder_removed_while_replayed_is_named(tmp_path: Path) -> None:
    import cv2

    folder = tmp_path / "imgs"
    folder.mkdir()
    for i in range(40):
        cv2.imwrite(str(folder / f"f{i:02d}.png"), np.full(SHAPE, i, np.uint8))
    with ReplaySource(folder, rate_hz=50.0) as source:
        camera = _camera_until_error(source, (folder / "f30.png").unlink)
    assert isinstance(camera.error, InputError)
    assert "f30.png: the image of frame 30 disappeared" in str(camera.error)


def test_a_paused_replay_reads_as_no_frames_per_second(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(camera_thread, "RATE_STALE_S", 0.2)
    with ReplaySource(write_h5(tmp_path / "r.h5", 200), loop=True) as source:
        camera = CameraThread(source, FrameRing(8, source.frame_shape, source.dtype))
        camera.start()
        deadline = time.monotonic() + 5
        while camera.frames < 5 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert camera.rate_hz() > 0
        source.pause()
        deadline = time.monotonic() + 10
        while camera.rate_hz() != 0.0 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert camera.rate_hz() == 0.0
        camera.stop()
