"""The live waves worker and its window (no Qt): every frame of a full-speed replay, the fit
against the simulator's truth, lost frames left as gaps, and one line for each bad input."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

from holoview.acquire.recording import RecordingReader
from holoview.cli import main
from holoview.engine.experiment import Experiment
from holoview.errors import InputError
from holoview.live.session import LiveSession
from holoview.live.wave_window import FUSED, WaveHistory, WaveSettings, analyse_window
from holoview.optics.surfaces import WATER_SURFACE_TENSION
from holoview.optics.wave_fields import random_travelling_waves

#: A simulated bench with carriers far apart, and travelling waves on 1 mm of water with a
#: flow (the waves feel the bottom: k d from 0.15 to 1.5, so the depth is fitted too).
TRAVELLING = [
    "--size",
    "256",
    "--pixel-pitch-um",
    "160",
    "--m-r-mrad",
    "0.4",
    "0.025",
    "--m-b-mrad",
    "0.025",
    "0.3",
    "--reflectivity",
    "0.1",
    "--depth-mm",
    "1",
    "--scenario",
    "travelling",
    "--frames",
    "300",
    "--fps",
    "250",
    "--seed",
    "5",
    "--wave-k",
    "150",
    "1500",
    "--wave-components",
    "120",
    "--flow-mm-per-s",
    "20",
    "10",
    "--wave-start-s",
    "0.002",
    "--wave-rise-s",
    "0.01",
    "--no-truth-maps",
]


@pytest.fixture(scope="module")
def travelling(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """300 frames of 256 x 256 at 250 frames/s of travelling waves, with their truth."""
    path = tmp_path_factory.mktemp("waves") / "travelling.h5"
    assert main(["-q", "simulate", str(path), *TRAVELLING]) == 0
    return path


def truth_of(path: Path) -> dict:
    with h5py.File(path, "r") as f:
        return dict(f["truth/waves"].attrs)


def stored_experiment(path: Path) -> Experiment:
    with RecordingReader(path) as reader:
        return Experiment.from_json(reader.experiments()[-1][1], where=path.name)


def wait_for(condition, timeout: float = 180.0) -> None:
    """Wait until ``condition()`` is true (polling; no fixed sleep before asserting)."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)


def assert_close_to_truth(fit, truth: dict) -> None:
    assert fit.surface_tension == pytest.approx(truth["sigma_n_per_m"], rel=0.05)
    assert fit.depth == pytest.approx(truth["depth_m"], rel=0.10)
    assert fit.surface_tension_stderr > 0 and fit.depth_stderr > 0  # no number without error
    for axis in (0, 1):
        assert fit.flow_stderr[axis] > 0
        error = abs(fit.flow[axis] - truth["flow_m_per_s"][axis])
        assert error < max(3 * fit.flow_stderr[axis], 2e-3)


@pytest.mark.slow
@pytest.mark.parametrize("label", ["RB1", FUSED])
def test_a_full_speed_replay_gives_every_frame_and_the_truth(travelling: Path, label: str) -> None:
    experiment = stored_experiment(travelling)
    assert experiment.reference == "relative"  # steps between frames, summed by the history
    session = LiveSession(
        f"replay:{travelling}", experiment, source_options={"loop": False, "speed": "fast"}
    )
    try:
        session.open_waves(WaveSettings(label=label, length=512, segment=128))
        session.start()
        wait_for(
            lambda: (w := session.waves()) is not None and w.frames == 300 and w.fit is not None
        )
        waves = session.waves()
        assert session.waves_worker is not None
        status = session.waves_worker.status()
    finally:
        session.close()
    assert waves is not None and waves.fit is not None
    assert waves.label == label and waves.stride == 1 and waves.gaps == 0
    assert status.read == 300 and status.dropped == 0  # the replay waited for the worker
    assert waves.rate == pytest.approx(250.0) and waves.nyquist == pytest.approx(125.0)
    assert waves.spectrum is not None and waves.spectrum.segments == 3
    assert waves.problems == ()
    assert_close_to_truth(waves.fit, truth_of(travelling))


def test_a_window_shorter_than_a_segment_is_refused() -> None:
    with pytest.raises(InputError, match="shorter than a segment"):
        WaveSettings(length=32, segment=64)


# ---- the window on maps made here -------------------------------------------------
PIXEL = 5e-4  # m
RATE = 500.0  # maps/s


def wave_maps(times: np.ndarray, *, size: int = 64, depth: float = 1e-3) -> list[np.ndarray]:
    """Maps (m, float32) of broadband waves on ``depth`` of water with a flow, at ``times``."""
    waves = random_travelling_waves(
        np.random.default_rng(3),
        k_range=(800.0, 2500.0),
        components=150,
        rms=20e-9,
        depth=depth,
        flow=(0.02, -0.01),
    )
    axis = np.arange(size) * PIXEL
    x, y = axis[np.newaxis, :], axis[:, np.newaxis]
    return [np.asarray(waves(float(t), x, y), dtype=np.float32) for t in times]


def history_of(maps, times, ids, *, pixel_size=(PIXEL, PIXEL)) -> WaveHistory:
    history = WaveHistory(len(maps))
    history.label = "RB1"
    history.pixel_size = pixel_size
    history.k_cut = math.pi / PIXEL
    for frame, t, i in zip(maps, times, ids, strict=True):
        history.push(frame, float(t), int(i))
    return history


def test_lost_frames_are_gaps_no_segment_spans() -> None:
    ids = np.concatenate([np.arange(0, 100), np.arange(105, 180)])  # 5 frames lost
    times = ids / RATE
    history = history_of(wave_maps(times), times, ids)
    window = history.snapshot()
    assert window is not None
    assert window.gaps == 1 and history.lost == 5
    assert window.interval == pytest.approx(1 / RATE)
    waves = analyse_window(window, WaveSettings(label="RB1", length=256, segment=32, depth=1e-3))
    assert waves.spectrum is not None
    # Welch by hand: segments of 32 with a hop of 16 inside each run (100 and 75 maps)
    expected = sum((run - 32) // 16 + 1 for run in (100, 75))
    assert waves.spectrum.segments == expected
    assert waves.spectrum.frames == 100 + 75 - (75 - 32) % 16 - (100 - 32) % 16


def test_relative_steps_are_summed_and_a_new_grid_starts_over() -> None:
    history = WaveHistory(8)
    steps = [np.full((8, 8), v, np.float32) for v in (1.0, 2.0, 3.0)]
    for i, step in enumerate(steps):
        history.push(step, i * 0.01, i, relative=True)
    window = history.snapshot()
    assert window is not None
    assert [float(m[0, 0]) for m in window.maps] == [1.0, 3.0, 6.0]
    history.push(np.zeros((4, 4), np.float32), 0.03, 3)
    assert len(history) == 1  # maps of another shape: a new record


def test_a_full_window_keeps_the_newest_maps_only() -> None:
    history = WaveHistory(16)
    for i in range(40):
        history.push(np.full((8, 8), i, np.float32), i * 0.01, i)
    window = history.snapshot()
    assert window is not None and len(window.maps) == 16
    assert float(window.maps[0][0, 0]) == 24 and window.times[-1] == pytest.approx(0.39)


def test_the_fit_of_maps_made_here_against_their_truth() -> None:
    times = np.arange(256) / RATE
    history = history_of(wave_maps(times), times, np.arange(256))
    window = history.snapshot()
    assert window is not None
    waves = analyse_window(window, WaveSettings(label="RB1", length=256, segment=64, depth=2e-3))
    assert waves.problems == () and waves.fit is not None
    truth = {"sigma_n_per_m": WATER_SURFACE_TENSION, "depth_m": 1e-3, "flow_m_per_s": (0.02, -0.01)}
    assert_close_to_truth(waves.fit, truth)


# ---- bad input: one line each, never a number without its error ------------------
def _window(**changes):
    times = np.arange(96) / RATE
    history = history_of(wave_maps(times), times, np.arange(96))
    window = history.snapshot()
    assert window is not None
    return replace(window, **changes)


SETTINGS = WaveSettings(label="RB1", length=96, segment=32, depth=1e-3)


def test_no_pixel_size_is_one_line() -> None:
    waves = analyse_window(_window(pixel_size=None), SETTINGS)
    assert waves.spectrum is None and waves.fit is None
    assert len(waves.problems) == 1 and "pixel size is not known" in waves.problems[0]


def test_fewer_frames_than_a_segment_is_one_line() -> None:
    window = _window()
    short = replace(window, maps=window.maps[:20], times=window.times[:20])
    waves = analyse_window(short, SETTINGS)
    assert waves.spectrum is None and waves.fit is None
    assert waves.problems == ("no omega-k spectrum yet: 20 maps without a gap, a segment needs 32",)


def test_all_nan_maps_are_one_line() -> None:
    window = _window()
    nan = tuple(np.full_like(m, np.nan) for m in window.maps)
    waves = analyse_window(replace(window, maps=nan), SETTINGS)
    assert waves.spectrum is None and waves.fit is None
    assert waves.problems == ("no omega-k spectrum: the RB1 maps are all NaN (untrusted)",)


def test_a_fit_that_does_not_converge_is_one_line_and_no_number() -> None:
    times = np.arange(96) / RATE
    deep = history_of(wave_maps(times, depth=0.05), times, np.arange(96)).snapshot()
    assert deep is not None
    waves = analyse_window(deep, replace(SETTINGS, depth=5e-3))  # k d > 3: depth undetermined
    assert waves.spectrum is not None and waves.fit is None
    assert len(waves.problems) == 1 and "did not converge" in waves.problems[0]
    held = analyse_window(deep, replace(SETTINGS, depth=0.05, hold=("depth",)))
    assert held.fit is not None and held.problems == ()  # held at a known depth: it fits
    assert held.fit.depth == 0.05 and held.fit.depth_stderr == 0.0 and "depth" in held.fit.held


def test_a_centre_outside_the_field_is_one_line() -> None:
    window = _window()
    outside = analyse_window(window, replace(SETTINGS, centre=(0.5, 0.5)))
    assert outside.mf is None and outside.spectrum is not None
    assert len(outside.problems) == 1 and "is outside the maps" in outside.problems[0]
    inside = analyse_window(window, replace(SETTINGS, centre=(32 * PIXEL, 32 * PIXEL)))
    assert inside.mf is not None and inside.centre == (32 * PIXEL, 32 * PIXEL)
    assert inside.mf.power.shape == (17, 17)  # m from -8 to 8, f from 0 to Nyquist
