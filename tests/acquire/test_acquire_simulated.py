"""The simulated camera: optics-simulator frames, pacing, render modes, faults, overload."""

from __future__ import annotations

import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from holoview.acquire import open_source
from holoview.acquire.camera_thread import CameraThread
from holoview.acquire.recorder import Recorder
from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.ring import CLOSED, FrameRing
from holoview.acquire.simulated import SimulatedSource
from holoview.errors import InputError

SMALL = (96, 128)


def fetch(source: SimulatedSource, n: int) -> list:
    frames = []
    while len(frames) < n:
        frame = source.fetch(timeout=5)
        if frame is not None:
            frames.append(frame)
    return frames


def test_default_spec_gives_raw_12_bit_holograms_of_a_moving_surface() -> None:
    with open_source("sim", shape=SMALL, render="live", seed=1, frame_rate_hz=200) as source:
        assert source.frame_shape == SMALL
        assert source.dtype == np.uint16
        assert source.get("pixel_format") == "Mono12"
        assert source.get("render_mode") == "live"
        assert source.setup["wavelength_m"] == pytest.approx(532e-9)
        source.start()
        frames = fetch(source, 3)
        source.stop()
    data = np.stack([f.data for f in frames])
    assert data.max() <= 4095
    assert data.std() > 10  # fringes, not a flat image
    assert not np.array_equal(data[0], data[2])  # the surface and the noise move
    assert [f.meta.frame_id for f in frames] == [0, 1, 2]


def test_frames_come_at_the_set_rate_on_the_simulated_clock() -> None:
    with SimulatedSource(shape=SMALL, render="live", frame_rate_hz=50.0, seed=2) as source:
        source.start()
        t0 = time.monotonic()
        frames = fetch(source, 11)
        elapsed = time.monotonic() - t0
        source.stop()
    assert elapsed >= 10 / 50.0 * 0.9
    assert np.diff([f.meta.t_device for f in frames]) == pytest.approx(np.full(10, 0.02))


def test_cycle_mode_renders_in_the_background_and_repeats() -> None:
    with SimulatedSource(
        shape=SMALL, render="cycle", cycle_frames=4, frame_rate_hz=500.0, seed=3
    ) as source:
        assert source.get("render_mode") == "cycle of 4 frames"
        deadline = time.monotonic() + 10
        while source._rendered < 4 and time.monotonic() < deadline:
            time.sleep(0.01)
        source.start()
        frames = fetch(source, 12)
        source.stop()
    for k in range(4, 12):
        np.testing.assert_array_equal(frames[k].data, frames[k - 4].data)
    assert not np.array_equal(frames[0].data, frames[1].data)


def test_scenarios_render_with_their_own_surfaces() -> None:
    for scenario in ("evaporation", "injection"):
        with open_source(f"sim:{scenario}", shape=SMALL, render="live", seed=4) as source:
            assert source.name == f"sim:{scenario}"
            assert source.get("scenario") == scenario
    with pytest.raises(InputError, match="unknown scenario 'tsunami'"):
        open_source("sim:tsunami")


def test_injected_drops_are_counted_as_transport_losses() -> None:
    with SimulatedSource(
        shape=SMALL, render="live", frame_rate_hz=400.0, seed=5, drop_rate=0.3
    ) as source:
        ring = FrameRing(256, source.frame_shape, source.dtype)
        consumer = ring.consumer("test", "every")
        camera = CameraThread(source, ring, max_frames=60)
        camera.start()
        assert camera.join(30)
        lost = source.stats()["lost"]
    ids = []
    while (item := consumer.get(timeout=0)) not in (None, CLOSED):
        ids.append(item[1].frame_id)
    assert len(ids) == 60
    assert lost > 5
    assert ids[-1] - ids[0] + 1 == 60 + lost  # each missing id is a counted loss
    assert consumer.status().transport_lost == lost


def test_injected_corrupt_and_late_frames() -> None:
    with SimulatedSource(
        shape=SMALL, render="live", frame_rate_hz=100.0, seed=6, corrupt_rate=1.0
    ) as source:
        source.start()
        frames = fetch(source, 3)
        source.stop()
        assert source.stats()["injected_corrupt"] == 3
    band = SMALL[0] // 8
    for frame in frames:
        zero_rows = int((frame.data == 0).all(axis=1).sum())
        assert zero_rows >= band
    with SimulatedSource(
        shape=SMALL, render="live", frame_rate_hz=100.0, seed=7, late_rate=1.0, late_s=0.05
    ) as source:
        source.start()
        fetch(source, 3)
        source.stop()
        stats = source.stats()
    assert stats["injected_late"] == 3
    assert stats["late"] >= 2  # 50 ms late at 100 frames/s is more than one interval


def test_overload_memory_flat_drops_exact_camera_never_blocks() -> None:
    """A recorder-like consumer 10x slower than the camera, for one second."""
    rate = 300.0
    with SimulatedSource(
        shape=SMALL, render="cycle", cycle_frames=2, frame_rate_hz=rate, seed=8
    ) as source:
        ring = FrameRing(8, source.frame_shape, source.dtype)
        slow = ring.consumer("slow", "every")
        camera = CameraThread(source, ring)
        tracemalloc.start()
        camera.start()
        baseline = None
        read = 0
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.0:
            item = slow.get(timeout=1)
            assert item is not None and item is not CLOSED
            read += 1
            if baseline is None:
                baseline = tracemalloc.get_traced_memory()[0]
            time.sleep(10 / rate)
        camera.stop()
        grown = tracemalloc.get_traced_memory()[0] - baseline
        tracemalloc.stop()
        while (item := slow.get(timeout=0)) is not CLOSED:
            read += 1
    status = slow.status()
    assert status.read == read
    assert status.read + status.dropped == status.acquired  # every frame accounted for
    assert status.dropped > status.read  # the consumer really was overloaded
    assert camera.frames >= 0.6 * rate * 1.0  # the camera kept its pace regardless
    assert grown < 4 * ring.nbytes / ring.capacity  # less than a few frames' worth


def test_recording_the_simulator_keeps_its_setup(tmp_path: Path) -> None:
    with SimulatedSource(shape=SMALL, render="live", frame_rate_hz=200.0, seed=9) as source:
        ring = FrameRing(16, source.frame_shape, source.dtype)
        recorder = Recorder.for_source(ring, tmp_path / "sim.h5", source)
        camera = CameraThread(source, ring, max_frames=20)
        recorder.start()
        camera.start()
        assert camera.join(30) and recorder.join(30)
    with RecordingReader(tmp_path / "sim.h5") as reader:
        assert len(reader) == 20
        assert reader.setup["n2"] == pytest.approx(1.333, abs=0.01)
        assert reader.setup_units["wavelength_m"] == "m"
        assert reader.pixel_format == "Mono12"
        assert reader.significant_bits == 12
        assert reader.settings["frame_rate_hz"] == pytest.approx(200.0)
        assert reader.settings_units["frame_rate_hz"] == "Hz"
        assert reader.source == "sim:waves"
