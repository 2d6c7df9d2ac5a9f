"""``holoview process --jobs 1`` against ``--jobs 2`` end to end, the disk, and a scaling model.

Run from the repository root (the machine otherwise idle: read the load printed)::

    .venv/bin/python benchmarks/bench_parallel.py               # 2000 frames of 1024^2
    .venv/bin/python benchmarks/bench_parallel.py --frames 400  # quicker

Makes the recording with ``holoview simulate`` (evaporation, 1024 x 1024, 80 frames/s,
uncompressed 16-bit) in a temporary folder under /tmp, then prints in one run:

1. the disk's read rate for the recording: cold (its pages dropped from the page cache
   with ``posix_fadvise(DONTNEED)``, then read in 16 MiB blocks) and from the page cache;
2. ``holoview process`` in a child process, end to end (start, detection, frames,
   analysis, outputs), ``--jobs 1`` and ``--jobs 2`` in turn, ``--repeat`` times each,
   the file in the page cache for both: the best wall time of each, their ratio
   (target >= 1.7 on two cores), and that their ``trends.csv`` are the same bytes;
3. a scaling model to 16 and 64 cores: a worker's time per frame ``c`` (carrier probe
   and reading from the page cache, from ``--jobs 1``, a process with a core to itself as
   a worker of a large machine has), the parent's sequential time per frame ``p`` (the
   series stitched in order with its joint estimate, from ``--jobs 2``), and the
   read time per frame ``r`` (the frame's bytes over the measured disk rate, or a
   network's). With ``W`` workers (cores minus one) the frames go at
   ``min(W / c, 1 / p, 1 / r)`` frames/s, plus the run's fixed part (start, detection,
   the maps of about 50 frames demodulated in the parent, analysis, outputs). The disk
   (or network) becomes the limit beyond ``W = c / r`` workers, the parent beyond
   ``W = c / p``.

The recording and the outputs are deleted at the end.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from machine import machine

REPO = Path(__file__).resolve().parents[1]

#: Networks a cluster might read the recording over, bytes/s.
NETWORKS = (("1 Gb/s Ethernet", 125e6), ("10 Gb/s Ethernet", 1.25e9))

#: Cores of the scaling model.
MODEL_CORES = (2, 16, 64)


def _holoview(*args: str) -> float:
    """Run ``python -m holoview ARGS`` from this checkout; return its wall time, s."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "holoview", *args], check=True, env=env, cwd=REPO)
    return time.perf_counter() - start


def read_rates(path: Path) -> tuple[float, float]:
    """Cold and page-cache read rates of ``path``, bytes/s (cold: its pages dropped first)."""
    block = 16 << 20
    rates = []
    for drop in (True, False):
        fd = os.open(path, os.O_RDONLY)
        try:
            if drop:
                os.fsync(fd)
                os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
            total, start = 0, time.perf_counter()
            while chunk := os.read(fd, block):
                total += len(chunk)
            rates.append(total / (time.perf_counter() - start))
        finally:
            os.close(fd)
    return rates[0], rates[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=2000)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--repeat", type=int, default=2, help="runs of each --jobs (best kept)")
    parser.add_argument("--keep", type=Path, help="keep the recording here (reused if present)")
    args = parser.parse_args()
    print(machine())
    print(f"load average at start: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    work = Path(tempfile.mkdtemp(prefix="holoview-bench-parallel-", dir="/tmp"))
    try:
        recording = args.keep or work / "evaporation.h5"
        if not recording.exists():
            seconds = _holoview(
                "-q", "simulate", str(recording), "--scenario", "evaporation",
                "--size", str(args.size), "--frames", str(args.frames), "--fps", "80",
                "--seed", "1",
            )  # fmt: skip
            print(f"recording: {args.frames} frames of {args.size}^2 simulated in {seconds:.0f} s")
        size = recording.stat().st_size
        frame_bytes = size / args.frames
        cold, warm = read_rates(recording)
        print(
            f"disk read of the recording ({size / 1e9:.2f} GB): cold {cold / 1e6:.0f} MB/s "
            f"({frame_bytes / cold * 1e3:.2f} ms a frame), page cache {warm / 1e6:.0f} MB/s"
        )
        walls: dict[int, list[float]] = {1: [], 2: []}
        for _ in range(args.repeat):
            for jobs in (1, 2):
                out = work / f"jobs{jobs}"
                argv = ["-q", "process", str(recording), "--out", str(out), "--overwrite"]
                walls[jobs].append(_holoview(*argv, "--jobs", str(jobs)))
        same = (work / "jobs1" / "trends.csv").read_bytes() == (
            work / "jobs2" / "trends.csv"
        ).read_bytes()
        t1, t2 = min(walls[1]), min(walls[2])
        print(
            f"holoview process end to end, {args.frames} frames: --jobs 1 {t1:.1f} s "
            f"({args.frames / t1:.0f} frames/s), --jobs 2 {t2:.1f} s "
            f"({args.frames / t2:.0f} frames/s): {t1 / t2:.2f}x (target >= 1.7); "
            f"trends.csv identical: {same}"
        )
        print(
            "  all runs, s: "
            + "; ".join(f"--jobs {j}: {', '.join(f'{w:.1f}' for w in walls[j])}" for j in walls)
        )
        one = json.loads((work / "jobs1" / "summary.json").read_text())["timing"]
        two = json.loads((work / "jobs2" / "summary.json").read_text())["timing"]
        n = args.frames
        carriers = (one["demodulate_seconds"] - one["maps_seconds"]) / n
        worker = carriers + one["read_seconds"] / n
        parent = (two["parent_seconds"] - two["maps_seconds"]) / n
        fixed = t2 - two["seconds"] + one["maps_seconds"]
        print(
            f"  --jobs 1: frame loop {one['seconds']:.1f} s (maps of ~50 frames "
            f"{one['maps_seconds']:.1f} s), the rest (start, detection, analysis, outputs) "
            f"{t1 - one['seconds']:.1f} s; per frame {carriers * 1e3:.2f} ms carriers + "
            f"{one['read_seconds'] / n * 1e3:.2f} ms reading (its thread)"
        )
        print(
            f"  --jobs 2: frame loop {two['seconds']:.1f} s (the parent's maps "
            f"{two['maps_seconds']:.1f} s), the rest {t2 - two['seconds']:.1f} s; per frame: "
            f"a worker {two['worker_seconds'] / n * 1e3:.2f} ms carriers + "
            f"{(two['read_seconds']) / n * 1e3:.2f} ms reading, the parent (stitching in "
            f"order, joint estimate) {parent * 1e3:.2f} ms; three processes on two cores"
        )
        print(f"load average at end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
        _model(n, worker, parent, fixed=fixed, frame_bytes=frame_bytes, disk=cold)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _model(
    frames: int, worker: float, parent: float, *, fixed: float, frame_bytes: float, disk: float
) -> None:
    """Print the scaling model (module documentation) for this machine's figures."""
    print(
        f"scaling model: W = cores - 1 workers at {worker * 1e3:.2f} ms a frame each, the "
        f"parent's sequential {parent * 1e3:.2f} ms a frame, frames of "
        f"{frame_bytes / 1e6:.2f} MB read at R bytes/s: frames/s = min(W / "
        f"{worker * 1e3:.2f} ms, 1 / {parent * 1e3:.2f} ms, R / frame), plus {fixed:.1f} s "
        "fixed"
    )
    reads = [("this disk", disk), *NETWORKS]
    print(f"  the parent's stitching limits a run to {1 / parent:.0f} frames/s whatever the cores")
    for name, rate in reads:
        limit = rate / frame_bytes
        print(
            f"  read from {name} ({rate / 1e6:.0f} MB/s): at most {limit:.0f} frames/s, "
            f"the limit beyond {worker * limit:.1f} workers"
        )
    for cores in MODEL_CORES:
        workers = max(1, cores - 1)
        parts = []
        for name, rate in reads:
            bounds = {
                "compute": workers / worker,
                "parent": 1 / parent,
                "read": rate / frame_bytes,
            }
            bound = min(bounds, key=bounds.__getitem__)
            per_s = bounds[bound]
            parts.append(
                f"{name} {per_s:.0f} frames/s ({bound}-bound, {frames} frames in "
                f"{fixed + frames / per_s:.1f} s)"
            )
        print(f"  {cores} cores: " + "; ".join(parts))


if __name__ == "__main__":
    main()
