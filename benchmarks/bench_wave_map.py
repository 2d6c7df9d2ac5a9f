"""The Waves panel's map of one frame: where its time goes, and what the GIL adds.

Run from the repository root::

    .venv/bin/python benchmarks/bench_wave_map.py [--size 1024] [--maps 200]

On simulated frames (uint16, the simulator's default setup, its RB1 and the other
families' carriers as the live model places them), the map the Waves panel makes of
RB1 (:class:`holoview.live.wave_maps.WaveMapper`: the engine's FrameCore and MapStep,
window at the bound, relative reference), printed with the machine and its load:

1. the CPU time per map of each part on one thread (each part's own functions timed
   with the thread's CPU clock; medians would hide nothing here, means are given);
2. the wall time per map made on the calling thread and in the child process
   (:class:`holoview.live.wave_maps.MapProcess`), alone and beside one busy
   pure-Python thread at a lower priority (the GUI, maps and series workers of the live
   window hold the GIL so): what waiting for the GIL adds, and what the child saves.
"""

from __future__ import annotations

import argparse
import collections
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
from holoview.live.wave_maps import MapProcess, WaveMapper  # noqa: E402
from holoview.optics.families import predict_families  # noqa: E402
from holoview.processing.fourier import half_spectrum  # noqa: E402
from holoview.processing.maps import demodulate, mean_phases  # noqa: E402
from holoview.processing.peaks.detection import Peak  # noqa: E402
from holoview.processing.peaks.radii import peak_radii  # noqa: E402

#: (module or class, function, the part it is) timed in section 1.
PARTS: list[tuple[Any, str, str]] = [
    (half_spectrum.HalfSpectrum, "_rows", "conversion to float32 + row FFTs"),
    (half_spectrum.HalfSpectrum, "_columns", "column FFTs under the window"),
    (half_spectrum.HalfSpectrum, "_floor_samples", "noise-floor samples"),
    (frame_core.CarrierCore, "measure", "carrier probe (mean phase's value)"),
    (demodulate, "invert_box", "box cut + inverse FFT"),
    (demodulate, "trusted_pixels", "trusted pixels (|f|^2)"),
    (demodulate, "angle", "phase (angle of field x ref*)"),
    (demodulate, "has_wraps", "wrap check"),
    (demodulate, "unwrap_maps", "unwrapping in space"),
    (demodulate, "trusted_level", "2 pi offset level"),
    (mean_phases.MeanPhases, "advance", "phase step (mean phases)"),
    (demodulate, "peak_result", "peak result (height)"),
    (map_step, "trusted_maps", "trusted maps (NaN)"),
    (wave_window.WaveHistory, "push", "history append (relative sum)"),
]


def scene(size: int) -> tuple[list[np.ndarray], list[Peak], list[Peak], Experiment]:
    """Frames, the chosen peak (RB1), every carrier placed, and the experiment."""
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
    carriers = np.array([p.carrier for p in peaks])
    radius = float(peak_radii((size, size), carriers, None, np.zeros((0, 2)))[0])
    experiment = Experiment(
        wavelength_m=setup.wavelength, pixel_pitch_m=setup.pixel_pitch, radius=radius
    )
    return frames, peaks[:1], peaks, experiment


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


def parts(frames: list[np.ndarray], chosen: list[Peak], experiment: Experiment, n: int) -> None:
    """Section 1: each part's CPU per map, one thread."""
    mapper = WaveMapper(frames[0].shape)
    history = wave_window.WaveHistory(512)
    costs: dict[str, float] = collections.defaultdict(float)
    for k in range(3):  # plans, the reference
        mapper.map(frames[k], chosen, experiment, label="RB1", fused=False, estimate=False)
    undo = timed_parts(costs)
    total = 0.0
    try:
        for k in range(n):
            start = time.thread_time()
            frame = frames[k % len(frames)]
            made = mapper.map(frame, chosen, experiment, label="RB1", fused=False, estimate=False)
            history.push(made.height, k / 60.0, k, relative=made.relative)
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


def busy(stop: threading.Event) -> None:
    """Pure Python at a lower priority until ``stop``: holds the GIL as a busy thread does."""
    os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 5)
    x = 0
    while not stop.is_set():
        for i in range(1000):
            x += i


def walls(frames: list[np.ndarray], chosen: list[Peak], experiment: Experiment, n: int) -> None:
    """Section 2: wall time per map on this thread and in the child, alone and beside a busy one."""
    print("2. wall time per map (median; CPU where made), alone and beside a busy Python thread")
    mappers = {"this thread": MapProcess(frames[0].shape, child=False)}
    mappers["child process"] = MapProcess(frames[0].shape)
    try:
        for mapper in mappers.values():
            for k in range(3):
                mapper.map(frames[k], chosen, experiment, label="RB1", fused=False, estimate=False)
        for round_ in range(2):
            for beside in (False, True):
                for where, mapper in mappers.items():
                    stop = threading.Event()
                    thread = threading.Thread(target=busy, args=(stop,), daemon=True)
                    if beside:
                        thread.start()
                    wall, cpu = [], []
                    for k in range(n):
                        start = time.perf_counter()
                        made = mapper.map(
                            frames[k % len(frames)],
                            chosen,
                            experiment,
                            label="RB1",
                            fused=False,
                            estimate=False,
                        )
                        wall.append(time.perf_counter() - start)
                        cpu.append(made.cpu_s)
                    stop.set()
                    if beside:
                        thread.join()
                    print(
                        f"   round {round_ + 1}, {where:13s} "
                        f"{'beside a busy thread' if beside else 'alone':20s} "
                        f"{statistics.median(wall) * 1e3:6.2f} ms "
                        f"(CPU {statistics.median(cpu) * 1e3:5.2f} ms)"
                    )
    finally:
        for mapper in mappers.values():
            mapper.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024, help="frame side, pixels")
    parser.add_argument("--maps", type=int, default=200, help="maps timed per case")
    args = parser.parse_args()
    print(machine())
    frames, chosen, _, experiment = scene(args.size)
    print(f"{args.size} x {args.size} uint16 frames; RB1's window radius {experiment.radius:.4f}")
    parts(frames, chosen, experiment, args.maps)
    walls(frames, chosen, experiment, max(20, args.maps // 4))
    print(f"load average after {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
