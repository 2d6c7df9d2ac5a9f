"""Camera thread and recorder thread: every frame recorded, errors end cleanly, settings."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest
from counting_source import CountingSource

from holoview.acquire.camera_thread import CameraThread
from holoview.acquire.recorder import Recorder
from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.recording_writer import RecordingWriter
from holoview.acquire.ring import CLOSED, FrameRing
from holoview.acquire.source import (
    AcquisitionError,
    CameraDisconnectedError,
    FeatureLockedError,
    UnsupportedFeatureError,
)
from holoview.errors import InputError


def record(source: CountingSource, path: Path, capacity: int = 64, **camera: object) -> Recorder:
    ring = FrameRing(capacity, source.frame_shape, source.dtype)
    writer = RecordingWriter(path, source.frame_shape, source.dtype, source=source.name)
    recorder = Recorder(ring, writer)
    camera_thread = CameraThread(source, ring, **camera)
    recorder.start()
    camera_thread.start()
    assert camera_thread.join(timeout=30)
    assert recorder.join(timeout=30)
    recorder.camera = camera_thread  # type: ignore[attr-defined]
    return recorder


def test_every_frame_reaches_the_file_in_order(tmp_path: Path) -> None:
    with CountingSource(rate_hz=500.0) as source:
        recorder = record(source, tmp_path / "r.h5", max_frames=60)
    assert recorder.error is None
    assert recorder.camera.error is None  # type: ignore[attr-defined]
    assert recorder.status().dropped == 0
    with RecordingReader(tmp_path / "r.h5") as reader:
        assert len(reader) == 60
        np.testing.assert_array_equal(reader.frame_ids, np.arange(60))
        np.testing.assert_array_equal(reader[:][:, 3, 5], np.arange(60))
        assert reader.source == "counting"


def test_end_of_stream_closes_the_ring_and_the_recording(tmp_path: Path) -> None:
    with CountingSource(n_frames=25) as source:
        record(source, tmp_path / "r.h5")
        assert not source.streaming
    with RecordingReader(tmp_path / "r.h5") as reader:
        assert len(reader) == 25


def test_unplugged_camera_ends_cleanly_keeping_what_was_recorded(tmp_path: Path) -> None:
    with CountingSource(fail_after=30) as source:
        recorder = record(source, tmp_path / "r.h5")
    camera_error = recorder.camera.error  # type: ignore[attr-defined]
    assert isinstance(camera_error, CameraDisconnectedError)
    assert "unplugged" in str(camera_error)
    assert recorder.error is None
    with RecordingReader(tmp_path / "r.h5") as reader:
        assert len(reader) == 30


def test_transport_losses_reach_the_ring_status(tmp_path: Path) -> None:
    with CountingSource(lose_every=10, n_frames=45) as source:
        recorder = record(source, tmp_path / "r.h5")
        assert source.stats()["lost"] == recorder.status().transport_lost == 4
    with RecordingReader(tmp_path / "r.h5") as reader:
        ids = reader.frame_ids
        assert len(ids) == 45
        assert int(np.diff(ids).max()) == 2  # the gaps show in the file too


def test_stop_ends_a_free_running_camera(tmp_path: Path) -> None:
    with CountingSource(rate_hz=200.0) as source:
        ring = FrameRing(4, source.frame_shape, source.dtype)
        consumer = ring.consumer("display", "newest")
        camera = CameraThread(source, ring)
        camera.start()
        assert consumer.get(timeout=5) is not None
        camera.stop()
        assert not camera.running
        assert camera.rate_hz() > 0
        while (item := consumer.get(timeout=0)) is not CLOSED:
            assert item is not None


def test_camera_thread_rejects_a_ring_of_another_shape() -> None:
    with CountingSource() as source, pytest.raises(InputError, match="does not fit"):
        CameraThread(source, FrameRing(4, (3, 3), np.uint16))


def test_a_camera_that_changes_its_frame_size_ends_the_stream_keeping_what_was_recorded(
    tmp_path: Path,
) -> None:
    """A device delivering frames of another size mid-stream is its error, not a bug."""

    class Resizing(CountingSource):
        def _do_fetch(self, timeout: float | None):  # type: ignore[no-untyped-def]
            frame = super()._do_fetch(timeout)
            if frame is not None and self._sent > 12:
                return frame._replace(data=np.zeros((8, 8), np.uint16))
            return frame

    with Resizing() as source:
        recorder = record(source, tmp_path / "r.h5")
    error = recorder.camera.error  # type: ignore[attr-defined]
    assert isinstance(error, AcquisitionError), error
    assert "(8, 8)" in str(error) and "restart the stream" in str(error)
    with RecordingReader(tmp_path / "r.h5") as reader:
        assert len(reader) == 12


def test_recorder_stops_itself_after_max_seconds_counting_only_what_was_asked(
    tmp_path: Path,
) -> None:
    """The duration is the recorder's: the camera goes on, nobody polls, it stops."""
    with CountingSource(rate_hz=200.0) as source:
        ring = FrameRing(64, source.frame_shape, source.dtype)
        writer = RecordingWriter(tmp_path / "r.h5", source.frame_shape, source.dtype)
        recorder = Recorder(ring, writer, max_seconds=0.5)
        camera = CameraThread(source, ring)
        recorder.start()
        camera.start()
        try:
            assert recorder.join(timeout=30)  # ended by itself while the camera streams
            assert camera.running
            count = recorder.accounting()
        finally:
            camera.stop()
    assert 0.5 <= recorder.elapsed_s < 30
    assert count.recorded > 0 and count.lost_to_disk == 0
    assert count.acquired == count.recorded + count.dropped  # later frames not counted
    with RecordingReader(tmp_path / "r.h5") as reader:
        assert len(reader) == count.recorded
        assert float(reader.t_host[-1] - reader.t_host[0]) < 0.5  # frames within the time


def test_the_recording_time_counts_from_the_first_frame(tmp_path: Path) -> None:
    """A camera that starts streaming late (a GigE camera takes seconds) still gives the
    seconds asked for: the clock starts with the first frame, not with the recorder."""
    with CountingSource(rate_hz=100.0) as source:
        ring = FrameRing(64, source.frame_shape, source.dtype)
        writer = RecordingWriter(tmp_path / "r.h5", source.frame_shape, source.dtype)
        recorder = Recorder(ring, writer, max_seconds=0.4)
        camera = CameraThread(source, ring)
        recorder.start()
        time.sleep(0.6)  # longer than the duration: nothing has arrived yet
        assert recorder.running
        camera.start()
        try:
            assert recorder.join(timeout=30)
        finally:
            camera.stop()
    with RecordingReader(tmp_path / "r.h5") as reader:
        span = float(reader.t_host[-1] - reader.t_host[0])
        assert len(reader) >= 10  # about 40 at 100 frames/s
    assert 0.2 < span < 0.4


def test_recorder_refuses_a_duration_that_is_not_positive(tmp_path: Path) -> None:
    ring = FrameRing(4, (4, 4), np.uint16)
    for bad in (0.0, -1.0, math.nan, math.inf):
        writer = RecordingWriter(tmp_path / f"{bad}.h5", (4, 4), np.uint16)
        with pytest.raises(InputError, match="max_seconds"):
            Recorder(ring, writer, max_seconds=bad)


def test_settings_describe_themselves_snap_and_read_back() -> None:
    source = CountingSource()
    with pytest.raises(AcquisitionError, match="not open"):
        source.set("exposure_s", 1e-3)
    with source:
        info = source.describe_settings()
        assert info["exposure_s"].unit == "s"
        assert info["exposure_s"].limits == (1e-5, 1.0)
        assert info["roi"].locked_while_streaming
        assert info["sensor_temperature_k"].read_only
        value = source.set("exposure_s", 2.0000037e-3)
        assert math.isclose(value, 2e-3, rel_tol=1e-9)
        assert math.isclose(source.get("exposure_s"), value)
        with pytest.raises(InputError, match="outside"):
            source.set("exposure_s", 5.0)
        with pytest.raises(InputError, match="number"):
            source.set("exposure_s", "fast")
        with pytest.raises(UnsupportedFeatureError, match="no setting 'gamma'"):
            source.set("gamma", 1.0)
        with pytest.raises(FeatureLockedError, match="read-only"):
            source.set("sensor_temperature_k", 290.0)
        source.start()
        with pytest.raises(FeatureLockedError, match="while streaming"):
            source.set("roi", (0, 0, 8, 8))
        assert source.set("exposure_s", 3e-3) == pytest.approx(3e-3)
        source.stop()
        assert source.set("roi", (0, 0, 24, 16)) == (0, 0, 24, 16)
        with pytest.raises(InputError, match="left, top"):
            source.set("roi", (-1, 0, 8, 8))
        assert set(source.get_all()) == {"exposure_s", "roi", "sensor_temperature_k"}


def test_recorder_overrun_is_counted_exactly(tmp_path: Path) -> None:
    with CountingSource(n_frames=400, shape=(64, 64)) as source:
        recorder = record(source, tmp_path / "r.h5", capacity=2)
    status = recorder.status()
    with RecordingReader(tmp_path / "r.h5") as reader:
        ids = reader.frame_ids
        assert len(ids) == status.read == recorder.written
        assert status.read + status.dropped == status.acquired == 400
        assert (np.diff(ids) > 0).all()


def test_recorder_stops_itself_after_max_frames(tmp_path: Path) -> None:
    ring = FrameRing(64, (16, 24), np.uint16)
    writer = RecordingWriter(tmp_path / "r.h5", (16, 24), np.uint16)
    recorder = Recorder(ring, writer, max_frames=7)
    recorder.start()
    with CountingSource(n_frames=20) as source:
        camera = CameraThread(source, ring)
        camera.start()
        assert camera.join(timeout=30)
    assert recorder.join(timeout=30)
    assert recorder.error is None
    with RecordingReader(tmp_path / "r.h5") as reader:
        np.testing.assert_array_equal(reader.frame_ids, np.arange(7))  # not the 20 acquired
    with pytest.raises(InputError, match="max_frames"):
        Recorder(ring, RecordingWriter(tmp_path / "bad.h5", (16, 24), np.uint16), max_frames=0)


def test_stop_drains_what_the_ring_had_acquired(tmp_path: Path) -> None:
    ring = FrameRing(16, (16, 24), np.uint16)
    recorder = Recorder(ring, RecordingWriter(tmp_path / "r.h5", (16, 24), np.uint16))
    with CountingSource(n_frames=10) as source:
        source.start()
        for _ in range(10):
            frame = source.fetch()
            ring.put(frame.data, frame.meta)
        source.stop()
    recorder.start()
    recorder.stop(drain=True)  # the ring is still open: only the drain ends it
    assert not recorder.running
    with RecordingReader(tmp_path / "r.h5") as reader:
        np.testing.assert_array_equal(reader.frame_ids, np.arange(10))
