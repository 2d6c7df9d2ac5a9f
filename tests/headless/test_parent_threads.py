"""The parent's own work in threads gives the numbers of one thread, to the bit.

The matched windows' many frames (transformed in threads, added in order) and the frames
spread over the run (demodulated in runs of consecutive frames, the displacement
estimate fed in order): each compared with the same work in one thread, on simulated
recordings, in every reference mode, with frames damaged in transfer.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest
from headless_sim import Simulated

from holoview.acquire.recording_writer import RecordingWriter
from holoview.headless.inputs import InputFile
from holoview.headless.parallel.threads import in_order
from holoview.headless.prepare import prepare_run
from holoview.headless.run_data import RunData
from holoview.headless.run_passes import run_passes
from holoview.headless.settings import PeakChoice, ProcessOptions, ProcessSettings
from holoview.processing.fourier.fftplans import usable_cpus


class _Maps:
    """Every frame's maps as the run gives them (a MapSink in memory)."""

    def __init__(self) -> None:
        self.frames: list[tuple[int, list[np.ndarray], np.ndarray | None]] = []

    def write_maps(
        self, position: int, maps: Sequence[np.ndarray], fused: np.ndarray | None
    ) -> None:
        self.frames.append((position, [m.copy() for m in maps], None if fused is None else fused))


def _damaged(source: Path, target: Path) -> Path:
    """``source`` with two frames damaged in transfer (rows lost), one of them spread."""
    with h5py.File(source, "r") as f:
        frames = f["frames"][:]
        ids, t_device, t_host = f["frame_id"][:], f["t_device_s"][:], f["t_host_s"][:]
        setup = {
            k: v for k, v in f["setup"].attrs.items() if isinstance(v, float | int | np.floating)
        }
    with RecordingWriter(target, frames.shape[1:], frames.dtype, setup=setup) as writer:
        for i, frame in enumerate(frames):
            kept = frame.copy()
            if i in (17, 60):
                kept[30:60] = 0
            writer.append(kept, int(ids[i]), float(t_device[i]), float(t_host[i]))
    return target


def _run(
    path: Path, settings: ProcessSettings, threads: int, *, auto: bool
) -> tuple[RunData, _Maps]:
    choice = PeakChoice(auto=4) if auto else PeakChoice()
    options = ProcessOptions(choice=choice, settings=settings, report=False, jobs=threads)
    sink = _Maps() if settings.maps else None
    with InputFile(path) as source:
        prepared = prepare_run(source, range(len(source)), options)
        assert prepared.frames.threads == min(threads, usable_cpus())
        run = replace(prepared.frames, threads=threads)  # this many whatever the machine
        data, _ = run_passes(run, runner=None, sink=sink)
    return data, sink or _Maps()


@pytest.mark.slow
@pytest.mark.parametrize(
    ("reference", "maps", "auto", "damaged"),
    [
        ("relative", True, False, False),  # the spread pass before the maps
        ("absolute", True, False, True),
        ("synthetic", True, False, False),
        ("absolute", False, True, False),  # after the series, the last frame fused
        ("relative", False, True, True),
    ],
)
def test_the_parents_threads_give_the_numbers_of_one(
    evaporation: Simulated,
    tmp_path: Path,
    *,
    reference: str,
    maps: bool,
    auto: bool,
    damaged: bool,
) -> None:
    """Displacements, the last maps, every frame's maps and counts: equal with 1 and 3 threads."""
    path = _damaged(evaporation.path, tmp_path / "damaged.h5") if damaged else evaporation.path
    settings = ProcessSettings(reference=reference, maps=maps)
    one, one_maps = _run(path, settings, 1, auto=auto)
    three, three_maps = _run(path, settings, 3, auto=auto)
    shifts = [d.shift for d in one.displacements]
    assert shifts and any(d.measured for d in one.displacements)
    assert [d.shift for d in three.displacements] == shifts
    assert three.fused_labels == one.fused_labels
    assert (three.demodulated, three.no_signal) == (one.demodulated, one.no_signal)
    assert three.map_flags == one.map_flags
    np.testing.assert_array_equal(three.map_noise_rad, one.map_noise_rad)
    assert three.last_frame == one.last_frame
    assert len(three.last_maps) == len(one.last_maps) > 0
    for a, b in zip(one.last_maps, three.last_maps, strict=True):
        np.testing.assert_array_equal(b, a)
    assert one.last_fused is not None  # without --maps, the spread pass's last frame's
    assert three.last_fused is not None
    np.testing.assert_array_equal(three.last_fused, one.last_fused)
    if damaged:
        assert one.frame_flags["damaged"] == 2
    assert len(three_maps.frames) == len(one_maps.frames)
    for (p, m, f), (q, n, g) in zip(one_maps.frames, three_maps.frames, strict=True):
        assert p == q
        for a, b in zip(m, n, strict=True):
            np.testing.assert_array_equal(b, a)
        assert (f is None) == (g is None)
        if f is not None:
            np.testing.assert_array_equal(g, f)


def test_matched_windows_many_frames_in_threads_are_those_of_one(evaporation: Simulated) -> None:
    """The windows matched to the change over many frames: the same radii and spectrum."""
    got = {}
    for threads in (1, 3):
        options = ProcessOptions(report=False, jobs=threads)
        with InputFile(evaporation.path) as source:
            prepared = prepare_run(source, range(len(source)), replace(options, jobs=threads))
        got[threads] = prepared.frames.spec.windows
    assert got[1] and got[3] == got[1]


def test_in_order_gives_the_items_order_and_raises_where_a_task_failed() -> None:
    """Tasks finishing out of order come back in order; a failure is raised and stops the rest."""
    second_done = threading.Event()

    def task(k: int) -> int:
        if k == 0:
            assert second_done.wait(30)  # the first finishes after the third
        if k == 2:
            second_done.set()
        if k == 5:
            raise ValueError("task 5")
        return k * k

    stop = threading.Event()
    results = in_order(task, range(10), 3, stop=stop)
    assert [next(results) for _ in range(5)] == [0, 1, 4, 9, 16]
    assert not stop.is_set()
    with pytest.raises(ValueError, match="task 5"):
        next(results)
    assert stop.is_set()  # the tasks still running are told to stop
    whole = threading.Event()
    assert list(in_order(task, range(5), 2, stop=whole)) == [0, 1, 4, 9, 16]
    assert not whole.is_set()
    assert list(in_order(task, range(3), 1)) == [0, 1, 4]
