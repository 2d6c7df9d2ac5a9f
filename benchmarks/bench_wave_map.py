"""The Waves panel's map of one frame: where its CPU goes, and what it waits for.

Run from the repository root::

    .venv/bin/python benchmarks/bench_wave_map.py [--size 1024] [--maps 200]

On simulated frames (uint16, the simulator's default setup; RB1 among the carriers the
live model places), the map the Waves panel makes of RB1 (the waves worker's own map
step, :class:`holoview.live.wave_map.WaveMapper`: the engine's FrameCore and
MapStep, window at the bound, relative reference), printed with the machine and its load:

1. the CPU time per map of each part on one thread (each part's functions timed with
   the thread's CPU clock, means over the maps), and the history's append;
2. the time per map on the calling thread, alone and beside one busy pure-Python
   thread at a lower priority (the GUI, maps and series workers of the live window
   hold the GIL so), split by Linux's schedstat into CPU, waiting runnable for a core
   (the machine's other work) and the rest (blocked: waiting for the GIL); and the same
   made in the map's process as the live worker does (the frame through shared
   memory): the wall time, the map's CPU there and the calling thread's;
3. the CPU time of one analysis of the panel's default window (256 maps: the omega-k
   spectrum and the dispersion fit), which the analysis thread takes at most
   ``FIT_SHARE`` of the time (``FIT_SHARE_BEHIND`` while frames are skipped).
"""

from __future__ import annotations

import argparse
import collections
import math
import os
import statistics
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from machine import machine

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from holoview.acquire.simulated import SimulatedSource  # noqa: E402
from holoview.engine import frame_core, map_step  # noqa: E402
from holoview.engine.experiment import Experiment  # noqa: E402
from holoview.live import wave_window  # noqa: E402
from holoview.live.child_work import ChildWork  # noqa: E402
from holoview.live.wave_map import FrameSlot, WaveJob, WaveMap, WaveMapper  # noqa: E402
from holoview.live.wave_window import WaveSettings  # noqa: E402
from holoview.optics.families import predict_families  # noqa: E402
from holoview.processing.fourier import half_spectrum  # noqa: E402
from holoview.processing.maps import box_maps, demodulate, mean_phases  # noqa: E402
from holoview.processing.peaks.detection import Peak  # noqa: E402

#: Rounds of section 2 (the cases take turns, so the load falls on each alike).
ROUNDS = 3
#: (module or class, function, the part it is) timed in section 1.
PARTS: list[tuple[Any, str, str]] = [
    (half_spectrum.HalfSpectrum, "_rows", "conversion to float32 + row FFTs"),
    (half_spectrum.HalfSpectrum, "_columns", "column FFTs under the window"),
    (half_spectrum.HalfSpectrum, "_floor_samples", "noise-floor samples"),
    (frame_core.CarrierCore, "measure", "carrier probe (mean phase's value)"),
    (box_maps, "invert_box", "box cut + inverse FFT"),
    (box_maps, "trusted_pixels", "trusted pixels (|f|^2)"),
    (box_maps, "angle", "phase (angle of field x ref*)"),
    (box_maps, "has_wraps", "wrap check"),
    (demodulate, "unwrap_maps", "unwrapping in space"),
    (box_maps, "trusted_level", "2 pi offset level"),
    (mean_phases.MeanPhases, "advance", "phase step (mean phases)"),
    (demodulate, "peak_result", "peak result (height)"),
    (map_step, "trusted_maps", "trusted maps (NaN)"),
    (wave_window.WaveHistory, "push", "history append (relative sum)"),
]


def scene(size: int) -> tuple[list[np.ndarray], list[Peak], Experiment]:
    """Frames, every carrier placed (RB1 first), and the experiment."""
    source = SimulatedSource(shape=(size, size), frame_rate_hz=60.0, seed=3, render="live")
    source.open()
    try:
        frames = [np.array(source._render(k / 60.0)) for k in range(12)]
        setup = source.sim_setup
    finally:
        source.close()
    frames += frames[-2:0:-1]  # back and forth: each frame follows a neighbour
    peaks = [
        Peak(f.observed_carrier, f.amplitude, 100.0, label=f.label, alpha=f.alpha)
        for f in predict_families(setup, max_order=2, second_order=False)
        if f.label != "B2B1"  # FB1's carrier again
    ]
    experiment = Experiment(wavelength_m=setup.wavelength, pixel_pitch_m=setup.pixel_pitch)
    return frames, peaks, experiment


class Mapper:
    """The waves worker's map of RB1, made on the calling thread or in its process."""

    def __init__(self, frames: list[np.ndarray], peaks: list[Peak], experiment: Experiment):
        shape = (int(frames[0].shape[0]), int(frames[0].shape[1]))
        self.mapper = WaveMapper(shape)
        self.slot = FrameSlot(shape, frames[0].dtype)
        self.child: ChildWork[WaveJob, WaveMap] = ChildWork(
            self.slot.child_work(None), "holoview-waves-map", 0
        )
        self.frames, self.job = frames, WaveJob(tuple(peaks), experiment, "RB1")
        self.count = 0
        for _ in range(3):  # plans, the reference
            self.map()
            self.map_in_child()

    def map(self) -> WaveMap:
        """Map the next frame on this thread."""
        frame = self.frames[self.count % len(self.frames)]
        self.count += 1
        return self.mapper.map(frame, self.job)

    def map_in_child(self) -> WaveMap:
        """Map the next frame in the map's process, as the live waves worker does."""
        self.slot.put(0, self.frames[self.count % len(self.frames)])
        self.count += 1
        return self.child(self.job)

    def close(self) -> None:
        """End the map's process; remove the shared frame."""
        self.child.close()
        self.slot.close()


def timed_parts(costs: dict[str, float]) -> Callable[[], None]:
    """Wrap each part of :data:`PARTS` to add its thread CPU time to ``costs``; return the undo."""
    saved = []
    for owner, name, part in PARTS:
        original = getattr(owner, name)

        def timed(*args: Any, _f: Any = original, _part: str = part, **kwargs: Any) -> Any:
            start = time.thread_time()
            try:
                return _f(*args, **kwargs)
            finally:
                costs[_part] += time.thread_time() - start

        saved.append((owner, name, original))
        setattr(owner, name, timed)

    def undo() -> None:
        for owner, name, original in saved:
            setattr(owner, name, original)

    return undo


def parts(mapper: Mapper, n: int) -> None:
    """Section 1: each part's CPU per map, one thread."""
    history = wave_window.WaveHistory(512)
    costs: dict[str, float] = collections.defaultdict(float)
    undo = timed_parts(costs)
    total = 0.0
    try:
        for k in range(n):
            start = time.thread_time()
            made = mapper.map()
            history.push(made.height, k / 60.0, k, relative=True)
            total += time.thread_time() - start
    finally:
        undo()
    rows, cols = made.height.shape
    print(f"1. CPU per map of RB1 ({rows} x {cols} map), one thread")
    for part, seconds in sorted(costs.items(), key=lambda kv: -kv[1]):
        print(f"   {part:40s} {seconds / n * 1e3:6.2f} ms")
    rest = total - sum(costs.values())
    print(f"   {'the rest (Python between the parts)':40s} {rest / n * 1e3:6.2f} ms")
    print(f"   {'total':40s} {total / n * 1e3:6.2f} ms")


def schedstat(path: str) -> tuple[float, float]:
    """CPU time and time spent runnable waiting for a core so far, s (Linux's schedstat)."""
    try:
        fields = Path(path).read_text().split()
    except OSError:
        return math.nan, math.nan
    return int(fields[0]) * 1e-9, int(fields[1]) * 1e-9


def busy(stop: threading.Event) -> None:
    """Pure Python at a lower priority until ``stop``: holds the GIL as a busy thread does."""
    os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 5)
    x = 0
    while not stop.is_set():
        for i in range(1000):
            x += i


def walls(mapper: Mapper, n: int) -> None:
    """Section 2: time per map, on this thread and in the map's process, alone and beside a
    busy Python thread."""
    print(
        "2. time per map (medians), alone and beside a busy Python thread; on this thread:\n"
        "   wall = CPU + waiting for a core (Linux's run queue) + the rest (the GIL); in the\n"
        "   map's process (the live waves worker): wall, the map's CPU there, this thread's CPU"
    )
    stat = f"/proc/self/task/{threading.get_native_id()}/schedstat"
    for round_ in range(ROUNDS):
        for beside in (False, True):
            stop = threading.Event()
            thread = threading.Thread(target=busy, args=(stop,), daemon=True)
            if beside:
                thread.start()
            wall, cpu, queued, rest = [], [], [], []
            for _ in range(n):
                before = schedstat(stat)
                start = time.perf_counter()
                mapper.map()
                took = time.perf_counter() - start
                after = schedstat(stat)
                wall.append(took)
                cpu.append(after[0] - before[0])
                queued.append(after[1] - before[1])
                rest.append(took - cpu[-1] - queued[-1])
            child_wall, child_cpu, caller_cpu = [], [], []
            for _ in range(n):
                start, thread_cpu = time.perf_counter(), time.thread_time()
                made = mapper.map_in_child()
                child_wall.append(time.perf_counter() - start)
                caller_cpu.append(time.thread_time() - thread_cpu)
                child_cpu.append(made.cpu_seconds)
            stop.set()
            if beside:
                thread.join()
            w, c, q, r = (statistics.median(v) * 1e3 for v in (wall, cpu, queued, rest))
            cw, cc, tc = (statistics.median(v) * 1e3 for v in (child_wall, child_cpu, caller_cpu))
            where = "beside a busy thread" if beside else "alone"
            print(
                f"   round {round_ + 1}, {where:20s} this thread: wall {w:6.2f} ms = CPU "
                f"{c:5.2f} + core wait {q:5.2f} + GIL {r:6.2f}; its process: wall {cw:6.2f} ms "
                f"(CPU {cc:5.2f} there, {tc:4.2f} here)"
            )


def analysis(mapper: Mapper) -> None:
    """Section 3: one analysis of 256 maps, CPU time (median of 3)."""
    settings = WaveSettings(label="RB1")
    history = wave_window.WaveHistory(settings.length)
    for k in range(settings.length):
        made = mapper.map()
        history.pixel_size, history.k_cut = made.pixel_size, made.k_cut
        history.push(made.height, k / 60.0, k, relative=True)
    window = history.snapshot()
    assert window is not None
    cpu = []
    for _ in range(3):
        start = time.thread_time()
        wave_window.analyse_window(window, settings, camera_rate=60.0)
        cpu.append(time.thread_time() - start)
    rows, cols = window.maps[0].shape
    print(
        f"3. one analysis of {len(window.maps)} maps of {rows} x {cols} (segments of "
        f"{settings.segment}): {statistics.median(cpu) * 1e3:.0f} ms of CPU"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024, help="frame side, pixels")
    parser.add_argument("--maps", type=int, default=200, help="maps timed per case")
    args = parser.parse_args()
    print(machine())
    mapper = Mapper(*scene(args.size))
    try:
        print(
            f"{args.size} x {args.size} uint16 frames; RB1's window radius "
            f"{mapper.mapper.radius:.4f}"
        )
        parts(mapper, args.maps)
        walls(mapper, max(20, args.maps // 4))
        analysis(mapper)
    finally:
        mapper.close()
    print(f"load average after {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
