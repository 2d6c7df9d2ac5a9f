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
3. the same with ``--maps`` (every frame demodulated into maps, in the workers with
   ``--jobs 2``, and written to ``results.h5``): the best wall time of each, their ratio,
   the CPU time both vCPUs spent (from ``/proc/stat``), where the time went, and that
   the two ``results.h5`` hold the same maps (to float32 rounding);
4. a scaling model to 16 and 64 cores, without and with ``--maps``: a worker's time per
   frame ``c`` (carrier probe, with ``--maps`` the maps and fused map too, and reading
   from the page cache, from ``--jobs 1``, a process with a core to itself as a worker of
   a large machine has), the parent's sequential time per frame ``p`` (the series
   stitched in order with its joint estimate, with ``--maps`` the maps written to
   ``results.h5`` in order too, from ``--jobs 2``), and the read time per frame ``r``
   (the frame's bytes over the measured disk rate, or a network's). With ``W`` workers
   (cores minus one) the frames go at ``min(W / c, 1 / p, 1 / r)`` frames/s, plus the
   run's fixed part (start, detection, matched windows, the maps of about 50 frames
   demodulated in the parent, analysis, outputs). The disk (or network) becomes the limit
   beyond ``W = c / r`` workers, the parent beyond ``W = c / p``. A Dask cluster's
   workers send each frame's maps back over the network (local workers hand them over
   in a file): with ``--maps`` the parent's link adds ``R / maps bytes`` frames/s.

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

import h5py
import numpy as np
from machine import machine

REPO = Path(__file__).resolve().parents[1]

#: Networks a cluster might read the recording over, bytes/s.
NETWORKS = (("1 Gb/s Ethernet", 125e6), ("10 Gb/s Ethernet", 1.25e9))

#: Cores of the scaling model.
MODEL_CORES = (2, 16, 64)


def _cpu_seconds() -> float:
    """CPU time the whole machine has spent busy so far (all cores), s."""
    with open("/proc/stat") as f:
        fields = [int(x) for x in f.readline().split()[1:]]
    idle = fields[3] + fields[4]  # idle, iowait
    return (sum(fields[:8]) - idle) / os.sysconf("SC_CLK_TCK")


def _holoview(*args: str) -> float:
    """Run ``python -m holoview ARGS`` from this checkout; return its wall time, s."""
    return _timed(*args)[0]


def _timed(*args: str) -> tuple[float, float]:
    """Run ``python -m holoview ARGS``; return its wall time and the machine's CPU time, s."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    cpu, start = _cpu_seconds(), time.perf_counter()
    subprocess.run([sys.executable, "-m", "holoview", *args], check=True, env=env, cwd=REPO)
    return time.perf_counter() - start, _cpu_seconds() - cpu


def same_maps(a: Path, b: Path, block: int = 100) -> bool:
    """Whether two ``results.h5`` hold the same maps, NaN alike, to float32 rounding."""
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        if sorted(fa["maps"]) != sorted(fb["maps"]):
            return False
        for name in fa["maps"]:
            x, y = fa["maps"][name], fb["maps"][name]
            for start in range(0, x.shape[0], block):
                u, v = x[start : start + block], y[start : start + block]
                tiny = 1e-6 * float(np.nanmax(np.abs(u), initial=0.0))
                if not np.allclose(u, v, rtol=1e-5, atol=tiny, equal_nan=True):
                    return False
    return True


def bench_maps(work: Path, recording: Path, frames: int, repeat: int) -> dict[str, float]:
    """Print ``--maps`` with ``--jobs 1`` against ``--jobs 2`` (module documentation).

    Returns the model's figures: a worker's and the parent's seconds a frame, the fixed
    seconds, and the maps' bytes a frame.
    """
    runs: dict[int, list[tuple[float, float]]] = {1: [], 2: []}
    for _ in range(repeat):
        for jobs in (1, 2):
            out = work / f"maps{jobs}"
            argv = ["-q", "process", str(recording), "--out", str(out), "--overwrite", "--maps"]
            runs[jobs].append(_timed(*argv, "--jobs", str(jobs)))
    (t1, c1), (t2, c2) = min(runs[1]), min(runs[2])
    same = same_maps(work / "maps1" / "results.h5", work / "maps2" / "results.h5")
    same_trends = (work / "maps1" / "trends.csv").read_bytes() == (
        work / "maps2" / "trends.csv"
    ).read_bytes()
    print(
        f"--maps, {frames} frames: --jobs 1 {t1:.1f} s ({frames / t1:.0f} frames/s), "
        f"--jobs 2 {t2:.1f} s ({frames / t2:.0f} frames/s): {t1 / t2:.2f}x; CPU of both "
        f"vCPUs {c1:.1f} s and {c2:.1f} s; results.h5 maps equal: {same}, trends.csv "
        f"identical: {same_trends}"
    )
    print(
        "  all runs, s (CPU s of both vCPUs): "
        + "; ".join(
            f"--jobs {j}: {', '.join(f'{w:.1f} ({c:.1f})' for w, c in runs[j])}" for j in runs
        )
    )
    one = json.loads((work / "maps1" / "summary.json").read_text())["timing"]
    two = json.loads((work / "maps2" / "summary.json").read_text())["timing"]
    print(
        f"  --jobs 1: frame loop {one['seconds']:.1f} s (maps {one['maps_seconds']:.1f} s), "
        f"the rest (start, detection, analysis, fused maps, outputs) {t1 - one['seconds']:.1f} s"
    )
    print(
        f"  --jobs 2: frame loop {two['seconds']:.1f} s (the workers' maps and carriers "
        f"{two['worker_seconds']:.1f} s, the parent's stitching and writing "
        f"{two['parent_seconds']:.1f} s), the rest {t2 - two['seconds']:.1f} s"
    )
    with h5py.File(work / "maps1" / "results.h5", "r") as f:
        maps_bytes = sum(d[0].nbytes for d in f["maps"].values())
    return {
        "worker": (one["demodulate_seconds"] + one["read_seconds"]) / frames,
        "parent": two["parent_seconds"] / frames,
        "fixed": t2 - two["seconds"],
        "maps_bytes": float(maps_bytes),
    }


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
    parser.add_argument("--no-maps", action="store_true", help="skip the runs with --maps")
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
        # the parent's own maps (the spread pass) run beside the workers, not in its
        # sequential part: parent_seconds is the stitching in order alone
        parent = two["parent_seconds"] / n
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
        with_maps = None
        if not args.no_maps:
            with_maps = bench_maps(work, recording, args.frames, args.repeat)
        print(f"load average at end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
        print("scaling model without --maps:")
        _model(n, worker, parent, fixed=fixed, frame_bytes=frame_bytes, disk=cold)
        if with_maps is not None:
            print("scaling model with --maps:")
            _model(
                n,
                with_maps["worker"],
                with_maps["parent"],
                fixed=with_maps["fixed"],
                frame_bytes=frame_bytes,
                disk=cold,
                maps_bytes=with_maps["maps_bytes"],
            )
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _model(
    frames: int,
    worker: float,
    parent: float,
    *,
    fixed: float,
    frame_bytes: float,
    disk: float,
    maps_bytes: float = 0.0,
) -> None:
    """Print the scaling model (module documentation) for this machine's figures.

    ``maps_bytes``: the maps a frame sends back to the parent (with ``--maps``), over
    the network from a Dask cluster's workers.
    """
    back = f", R / {maps_bytes / 1e6:.2f} MB of maps back over a network" if maps_bytes else ""
    print(
        f"  W = cores - 1 workers at {worker * 1e3:.2f} ms a frame each, the "
        f"parent's sequential {parent * 1e3:.2f} ms a frame, frames of "
        f"{frame_bytes / 1e6:.2f} MB read at R bytes/s: frames/s = min(W / "
        f"{worker * 1e3:.2f} ms, 1 / {parent * 1e3:.2f} ms, R / frame{back}), plus "
        f"{fixed:.1f} s fixed"
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
            if maps_bytes and name != "this disk":  # a Dask cluster sends the maps back
                bounds["maps back"] = rate / maps_bytes
            bound = min(bounds, key=bounds.__getitem__)
            per_s = bounds[bound]
            parts.append(
                f"{name} {per_s:.0f} frames/s ({bound}-bound, {frames} frames in "
                f"{fixed + frames / per_s:.1f} s)"
            )
        print(f"  {cores} cores: " + "; ".join(parts))


if __name__ == "__main__":
    main()
