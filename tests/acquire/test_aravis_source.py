"""The Aravis source against real GigE Vision on loopback and Aravis's in-process Fake camera.

A separate Python process serves ``Aravis.GvFakeCamera`` on 127.0.0.1 with known
frames (``tests/helpers/fake_gv_camera.py``); the source discovers and streams it
over GVCP/GVSP sockets as it would a lab camera. The whole module skips, with the
reason, where PyGObject or Aravis 0.8 cannot be imported.
"""

from __future__ import annotations

import fcntl
import itertools
import os
import select
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from holoview.acquire.recording_reader import RecordingReader

try:
    from holoview.acquire.aravis import AravisSource, FrameIdUnwrapper, import_aravis, list_cameras

    import_aravis()
except Exception as exc:  # any reason Aravis is unusable here is a reason to skip
    pytest.skip(f"Aravis 0.8 through PyGObject is not usable: {exc}", allow_module_level=True)

from holoview.acquire.camera_thread import CameraThread
from holoview.acquire.recorder import Recorder
from holoview.acquire.ring import FrameRing
from holoview.acquire.source import (
    CameraDisconnectedError,
    CameraNotFoundError,
    FeatureLockedError,
)

pytestmark = pytest.mark.aravis

SERVER = Path(__file__).resolve().parents[1] / "helpers" / "fake_gv_camera.py"
_serials = itertools.count()


def raw_id(frame_id: int) -> int:
    """The 16-bit GigE Vision id (1..65535) of an unwrapped frame id."""
    return (frame_id - 1) % 65535 + 1


class Served:
    """A GigE Vision camera served by a child process, with the frames it serves."""

    def __init__(self, process: subprocess.Popen, serial: str, frames: np.ndarray) -> None:
        self.process = process
        self.serial = serial
        self.camera_id = f"Aravis-Fake-{serial}"
        self.frames = frames

    def expected(self, frame_id: int) -> np.ndarray:
        return self.frames[(raw_id(frame_id) - 1) % len(self.frames)]


#: Held while a test serves fake cameras: they all answer on 127.0.0.1's GVCP port, and
#: two tests serving at once (``pytest -n 2`` without ``--dist loadfile``) read each
#: other's frames and lost register writes.
LOOPBACK_LOCK = Path(tempfile.gettempdir()) / "holoview-fake-gige.lock"


@pytest.fixture
def loopback() -> Iterator[None]:
    """The machine's loopback for this test's fake cameras alone (:data:`LOOPBACK_LOCK`)."""
    with open(LOOPBACK_LOCK, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


@pytest.fixture
def serve(tmp_path: Path, loopback: None) -> Iterator[Callable[..., Served]]:
    """Start fake GigE cameras in child processes; always stop them afterwards."""
    children: list[subprocess.Popen] = []

    def start(frames: np.ndarray, lost_ratio: float = 0.0) -> Served:
        serial = f"HV{os.getpid() % 100000}{next(_serials)}"
        np.save(tmp_path / f"{serial}.npy", frames)
        command = [sys.executable, str(SERVER), serial, str(tmp_path / f"{serial}.npy")]
        if lost_ratio:
            command += ["--lost-ratio", str(lost_ratio)]
        process = subprocess.Popen(
            command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )
        children.append(process)
        assert process.stdout is not None
        ready, _, _ = select.select([process.stdout], [], [], 30)
        line = process.stdout.readline().strip() if ready else "(nothing in 30 s)"
        assert line == "ready", f"fake camera did not start: {line}"
        return Served(process, serial, frames)

    yield start
    for process in children:
        if process.poll() is None:
            assert process.stdin is not None
            process.stdin.close()  # asks it to restore the fill and stop cleanly
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(timeout=10)
        for stream in (process.stdin, process.stdout):
            if stream is not None and not stream.closed:
                stream.close()


def holograms(n: int, shape: tuple[int, int], dtype: type = np.uint16) -> np.ndarray:
    """Distinct fringe patterns, one per frame, with noise: what a hologram camera sends."""
    rows, cols = np.mgrid[: shape[0], : shape[1]]
    rng = np.random.default_rng(7)
    top = 4095 if dtype == np.uint16 else 255
    out = []
    for k in range(n):
        fringes = 0.5 + 0.4 * np.cos(2 * np.pi * (0.21 * cols + 0.13 * rows) + 0.7 * k)
        out.append(np.clip(fringes * top + rng.normal(0, 0.02 * top, shape), 0, top))
    return np.stack(out).astype(dtype)


def configure(source: AravisSource, shape: tuple[int, int], fmt: str, rate: float) -> None:
    source.set("roi", (0, 0, shape[1], shape[0]))
    source.set("pixel_format", fmt)
    source.set("frame_rate_hz", rate)


def test_discovered_and_recorded_frames_equal_the_frames_served(
    serve: Callable[..., Served], tmp_path: Path
) -> None:
    served = serve(holograms(7, (96, 128)))
    found = {c["id"]: c for c in list_cameras()}
    assert found[served.camera_id]["address"] == "127.0.0.1"
    assert found[served.camera_id]["serial"] == served.serial
    with AravisSource(served.serial) as source:  # by serial, as a user would
        assert source.name == f"aravis:{served.camera_id}"
        configure(source, (96, 128), "Mono16", 100.0)
        assert source.get("roi") == (0, 0, 128, 96)
        assert source.frame_shape == (96, 128)
        ring = FrameRing(32, source.frame_shape, source.dtype)
        recorder = Recorder.for_source(ring, tmp_path / "gige.h5", source)
        camera = CameraThread(source, ring, max_frames=40)
        recorder.start()
        camera.start()
        assert camera.join(30) and recorder.join(30)
        assert camera.error is None, camera.error
        stats = source.stats()
    with RecordingReader(tmp_path / "gige.h5") as reader:
        assert len(reader) == 40
        assert reader.settings["pixel_format"] == "Mono16"
        assert reader.settings_units["exposure_s"] == "s"
        ids = reader.frame_ids
        assert (np.diff(ids) > 0).all()  # unwrapped past 65535 where the camera wrapped
        for frame_id, frame in zip(ids, reader, strict=True):
            np.testing.assert_array_equal(frame, served.expected(int(frame_id)))
        assert np.isfinite(reader.t_device).all()
    assert stats["aravis_n_completed_buffers"] >= 40
    assert stats["incomplete"] == 0


def test_mono8_settings_read_back_and_locks(serve: Callable[..., Served]) -> None:
    served = serve(holograms(3, (64, 80), np.uint8))
    with AravisSource(served.camera_id) as source:
        configure(source, (64, 80), "Mono8", 50.0)
        info = source.describe_settings()
        assert info["exposure_s"].unit == "s"
        assert {"off", "software"} <= set(info["trigger"].choices)
        exposure = source.set("exposure_s", 0.0123456789)
        assert exposure == pytest.approx(0.012346, abs=1e-6)  # snapped to 1 us, read back
        source.start()
        with pytest.raises(FeatureLockedError):
            source.set("roi", (0, 0, 32, 32))
        frame = None
        while frame is None:
            frame = source.fetch(2)
        assert frame.data.dtype == np.uint8
        assert frame.meta.exposure_s == pytest.approx(exposure)
        np.testing.assert_array_equal(frame.data, served.expected(frame.meta.frame_id))
        source.stop()


def test_software_trigger_delivers_one_frame_per_trigger(serve: Callable[..., Served]) -> None:
    served = serve(holograms(2, (32, 48)))
    with AravisSource(served.camera_id) as source:
        configure(source, (32, 48), "Mono16", 50.0)
        source.set("trigger", "software")
        source.start()
        assert source.fetch(0.4) is None
        source.software_trigger()
        frame = source.fetch(5)
        assert frame is not None
        np.testing.assert_array_equal(frame.data, served.expected(frame.meta.frame_id))
        source.stop()


def test_packet_loss_counts_incomplete_buffers_and_never_hands_them_on(
    serve: Callable[..., Served],
) -> None:
    served = serve(holograms(5, (256, 256)), lost_ratio=0.002)
    with AravisSource(served.camera_id) as source:
        configure(source, (256, 256), "Mono16", 50.0)
        source.start()
        frames = []
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and (
            len(frames) < 30 or source.stats()["incomplete"] < 3
        ):
            frame = source.fetch(1)
            if frame is not None:
                frames.append(frame)
        source.stop()
        stats = source.stats()
    assert stats["incomplete"] >= 3
    assert stats["aravis_n_missing_packets"] > 0
    for frame in frames:  # every frame handed on is complete and right
        np.testing.assert_array_equal(frame.data, served.expected(frame.meta.frame_id))
    span = frames[-1].meta.frame_id - frames[0].meta.frame_id + 1
    assert len(frames) + stats["lost"] >= span  # every id accounted for
    assert stats["lost"] >= 1


def test_camera_killed_mid_stream_is_a_clear_error_keeping_the_recording(
    serve: Callable[..., Served], tmp_path: Path
) -> None:
    served = serve(holograms(4, (64, 64)))
    with AravisSource(served.camera_id) as source:
        configure(source, (64, 64), "Mono16", 50.0)
        ring = FrameRing(16, source.frame_shape, source.dtype)
        consumer = ring.consumer("watch", "every")
        recorder = Recorder.for_source(ring, tmp_path / "cut.h5", source)
        camera = CameraThread(source, ring)
        recorder.start()
        camera.start()
        while consumer.status().acquired < 10:
            time.sleep(0.05)
        served.process.send_signal(signal.SIGKILL)
        served.process.wait(timeout=10)
        assert camera.join(60), "the camera thread did not notice the camera was gone"
        assert recorder.join(30)
    assert isinstance(camera.error, CameraDisconnectedError)
    assert "\n" not in str(camera.error)
    assert served.camera_id in str(camera.error)
    with RecordingReader(tmp_path / "cut.h5") as reader:
        assert len(reader) >= 10
        for frame_id, frame in zip(reader.frame_ids, reader, strict=True):
            np.testing.assert_array_equal(frame, served.expected(int(frame_id)))


def test_camera_id_that_does_not_exist(serve: Callable[..., Served]) -> None:
    served = serve(holograms(1, (16, 16)))
    with pytest.raises(CameraNotFoundError, match="no GenICam camera 'NoSuchCam'") as info:
        AravisSource("NoSuchCam").open()
    assert served.camera_id in str(info.value)  # the message lists what was found
    assert "\n" not in str(info.value)


def test_in_process_fake_camera_streams_across_the_frame_id_wrap() -> None:
    with AravisSource("Fake_1") as source:
        configure(source, (48, 64), "Mono16", 1000.0)
        source.set("exposure_s", 0.02)  # the Fake camera is black under 10 ms with no gain
        source.start()
        frames = []
        while len(frames) < 150:
            frame = source.fetch(2)
            assert frame is not None
            frames.append(frame)
        source.stop()
        stats = source.stats()
    ids = [f.meta.frame_id for f in frames]
    assert ids == list(range(ids[0], ids[0] + 150))  # consecutive, no false loss at the wrap
    assert stats["lost"] == 0
    assert frames[-1].data.shape == (48, 64)
    assert frames[-1].data.max() > 0


def test_frame_id_unwrapper_counts_gaps_across_the_wrap() -> None:
    unwrap = FrameIdUnwrapper()
    assert [unwrap(i) for i in (65533, 65534, 65535, 1, 3)] == [65533, 65534, 65535, 65536, 65538]
    assert unwrap.skipped == 1


def test_find_camera_by_id_serial_or_address() -> None:
    from holoview.acquire.aravis import find_camera_id

    cameras = [
        {"id": "Basler-1", "serial": "111", "address": "10.0.0.2"},
        {"id": "Aravis-Fake-X", "serial": "X", "address": "127.0.0.1"},
    ]
    assert find_camera_id(cameras, None) == "Basler-1"
    assert find_camera_id(cameras, "X") == "Aravis-Fake-X"
    assert find_camera_id(cameras, "127.0.0.1") == "Aravis-Fake-X"
    assert find_camera_id(cameras, "Basler-1") == "Basler-1"
    with pytest.raises(CameraNotFoundError, match=r"found: Basler-1 \(10\.0\.0\.2\)"):
        find_camera_id(cameras, "10.0.0.9")
    with pytest.raises(CameraNotFoundError, match="no GenICam camera found"):
        find_camera_id([], None)
