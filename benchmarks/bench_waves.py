"""Time and memory of ``holoview waves`` on 2000 frames of 256 x 256 maps.

Run from the repository root::

    .venv/bin/python benchmarks/bench_waves.py                # 2000 frames
    .venv/bin/python benchmarks/bench_waves.py --frames 8000  # memory must not grow

Writes a ``results.h5`` as ``holoview process --maps`` lays it out (float32 maps of
256 x 256, one chunk per frame, ``/trends/time_s``) with travelling capillary-gravity
waves on a flow (30 nm rms) plus weaker partial waves and a damped mode around a centre
(the simulator's surfaces sampled on the map grid, noise added, a masked core), then
runs in a child process, with the machine and its load printed:

1. the default analysis: omega-k, E(k), E(omega), the fit of sigma, d and U;
2. the whole analysis: that, the centre found (``--centre auto``), the (m, f) spectrum,
   the partial-wave fits, the ringdown fit and the lock-in maps at a drive frequency;
3. the whole analysis with a band filter writing every filtered frame.

Each line gives the wall time, the CPU time, the peak resident memory (RSS) of the
child and the timing of its stages (``waves.json``). Targets: the whole analysis under
15 s on 2 cores and the peak memory under 1 GB, whatever the number of frames. The
files are deleted at the end.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
from machine import machine

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from holoview.optics.wave_fields import (  # noqa: E402
    DampedMode,
    PartialWave,
    PartialWaves,
    random_travelling_waves,
)

SIZE, PIXEL, FPS = 256, 0.32e-3, 250.0


def write_results(path: Path, frames: int) -> None:
    """A results.h5 with ``frames`` maps of waves (module docstring), written in blocks."""
    rng = np.random.default_rng(7)
    travelling = random_travelling_waves(
        rng, k_range=(300, 1800), components=200, rms=30e-9, depth=3e-3, flow=(0.02, 0.01)
    )
    centre = (0.5 * SIZE * PIXEL, 0.5 * SIZE * PIXEL)
    partial = PartialWaves(
        (PartialWave(0, 14.0, 4e-9, 2.5e-9), PartialWave(2, 22.0, 1.6e-9, 3e-9)),
        centre=centre,
        core_radius=3e-3,
        depth=3e-3,
    )
    mode = DampedMode(1, 31.0, 0.5, 150e-9, centre=centre, depth=3e-3)
    x = (np.arange(SIZE) * PIXEL)[np.newaxis, :]
    y = (np.arange(SIZE) * PIXEL)[:, np.newaxis]
    core = np.hypot(x - centre[0], y - centre[1]) < 4e-3
    times = np.arange(frames) / FPS
    with h5py.File(path, "w") as f:
        maps = f.create_dataset(
            "maps/fused", (frames, SIZE, SIZE), np.float32, chunks=(1, SIZE, SIZE)
        )
        maps.attrs.update(
            {
                "unit": "m",
                "quantity": "delta_h",
                "reference": "absolute",
                "pixel_size_m": [PIXEL, PIXEL],
                "pixel_step_px": [4.0, 4.0],
                "radius_cpp": 0.12,
            }
        )
        f["trends/time_s"] = times
        for start in range(0, frames, 64):
            block = []
            for t in times[start : start + 64]:
                h = travelling(t, x, y) + partial(t, x, y) + mode(t, x, y)
                h = h + rng.normal(0, 0.5e-9, h.shape)
                h[core] = np.nan
                block.append(h)
            maps[start : start + len(block)] = np.array(block, np.float32)


def run(label: str, argv: list[str], out: Path) -> None:
    """Run ``holoview waves ARGV`` in a child; print wall, CPU, peak RSS and the stages."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "holoview", "-q", "waves", *argv, "--out", str(out)],
        capture_output=True,
        text=True,
        check=False,
    )
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        print(f"{label}: failed ({done.returncode}): {done.stderr.strip()}")
        return
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    summary = json.loads((out / "waves.json").read_text())
    stages = ", ".join(f"{k} {v:.1f} s" for k, v in summary["timing"].items())
    print(
        f"{label}: {wall:.1f} s wall, {cpu:.1f} s CPU, peak RSS {after.ru_maxrss / 1024:.0f} MB "
        f"({stages})"
    )
    shutil.rmtree(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=2000)
    parser.add_argument("--threads", type=int, default=2, help="FFT threads of the analysis")
    args = parser.parse_args()
    print(machine())
    folder = Path(tempfile.mkdtemp(prefix="bench_waves_"))
    try:
        results = folder / "results.h5"
        started = time.perf_counter()
        write_results(results, args.frames)
        os.sync()  # written out, as a run's results.h5 is: not flushed under the timing
        print(
            f"{args.frames} frames of {SIZE} x {SIZE} maps written in "
            f"{time.perf_counter() - started:.0f} s; load average {os.getloadavg()[0]:.2f}"
        )
        common = [str(results), "--threads", str(args.threads), "--depth-mm", "4"]
        whole = [
            *common,
            "--centre",
            "auto",
            "--r-range-mm",
            "5:38",
            "--drive-hz",
            "14",
            "--ringdown",
            "1,28:34",
        ]
        run("default (omega-k, E, dispersion fit)", common, folder / "a")
        run(
            "whole analysis (+ centre, (m, f), partial waves, ringdown, lock-in)",
            whole,
            folder / "b",
        )
        run("whole analysis + band filter written", [*whole, "--band-f", "10:40"], folder / "c")
        print(f"load average after: {os.getloadavg()[0]:.2f}")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
