"""Recorder throughput: the simulated camera to disk through the ring, every frame kept.

Run from the repository root::

    .venv/bin/python benchmarks/bench_recorder.py                    # the target: 80 fps, 60 s
    .venv/bin/python benchmarks/bench_recorder.py --seconds 10       # a quick look
    .venv/bin/python benchmarks/bench_recorder.py --out /fast/disk   # where the file goes

The target (issue 6): 1024 x 1024 uint16 at 80 frames/s for 60 s from the simulated
source, every frame on disk in order, none dropped. The simulated camera plays a
pre-rendered cycle (its waves render slower than 80 frames/s here), so the
benchmark measures the acquisition and recording path, not the synthesiser.

Prints the machine (CPU, cores, load average), the disk's own sequential write speed
(a 1 GB write with fsync, for scale), then: frames acquired, recorded, dropped by the
ring and lost in transport, the achieved frame rate, the sustained MB/s to disk,
the most frames ever waiting in the ring, the median and 99th-percentile time the
recorder spent per frame, whether every frame is on disk in order (ids checked by
reading the file back), and the target met or missed. The recording (about 10 GB)
is deleted afterwards unless ``--keep``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from machine import machine

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from holoview.acquire.camera_thread import CameraThread  # noqa: E402
from holoview.acquire.recorder import Recorder  # noqa: E402
from holoview.acquire.recording_reader import RecordingReader  # noqa: E402
from holoview.acquire.ring import FrameRing  # noqa: E402
from holoview.acquire.simulated import SimulatedSource  # noqa: E402


def disk_write_speed(folder: Path, megabytes: int = 1024) -> float:
    """Sequential write speed of ``folder``'s disk with fsync, MB/s."""
    block = np.random.default_rng(0).integers(0, 255, 4 << 20, dtype=np.uint8).tobytes()
    path = folder / "holoview-disk-speed.bin"
    t0 = time.perf_counter()
    with open(path, "wb") as f:
        for _ in range(megabytes // 4):
            f.write(block)
        f.flush()
        os.fsync(f.fileno())
    elapsed = time.perf_counter() - t0
    path.unlink()
    return megabytes * (1 << 20) / 1e6 / elapsed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--fps", type=float, default=80.0)
    parser.add_argument("--size", type=int, default=1024, help="frame rows = cols, pixels")
    parser.add_argument("--ring-mb", type=float, default=512.0)
    parser.add_argument("--out", type=Path, default=None, help="folder for the recording")
    parser.add_argument("--keep", action="store_true", help="keep the recording")
    args = parser.parse_args()

    folder = Path(tempfile.mkdtemp(prefix="holoview-bench-", dir=args.out))
    path = folder / "bench.h5"
    print(f"machine: {machine()}")
    print(f"disk: {folder} ({shutil.disk_usage(folder).free / 1e9:.0f} GB free)")
    print(f"disk sequential write with fsync: {disk_write_speed(folder):.0f} MB/s")

    shape = (args.size, args.size)
    source = SimulatedSource(
        shape=shape, frame_rate_hz=args.fps, render="cycle", cycle_frames=32, seed=1
    )
    source.open()
    while source._rendered < source.cycle_frames:  # let the cycle finish rendering first
        time.sleep(0.1)
    frame_bytes = shape[0] * shape[1] * source.dtype.itemsize
    ring = FrameRing(max(4, int(args.ring_mb * 1e6 // frame_bytes)), shape, source.dtype)
    recorder = Recorder.for_source(ring, path, source)
    n_frames = round(args.fps * args.seconds)
    camera = CameraThread(source, ring, max_frames=n_frames)
    append_times: list[float] = []
    original_append = recorder.writer.append

    def timed_append(*a: object, **k: object) -> None:
        t = time.perf_counter()
        original_append(*a, **k)  # type: ignore[arg-type]
        append_times.append(time.perf_counter() - t)

    recorder.writer.append = timed_append  # type: ignore[method-assign]
    peak_unread = 0
    done = threading.Event()

    def watch() -> None:
        nonlocal peak_unread
        while not done.wait(0.05):
            peak_unread = max(peak_unread, recorder.status().unread)

    watcher = threading.Thread(target=watch, name="bench-watch")
    print(
        f"recording {n_frames} frames of {shape[0]} x {shape[1]} {source.dtype} "
        f"at {args.fps:g} frames/s ({frame_bytes * args.fps / 1e6:.0f} MB/s), "
        f"ring {ring.capacity} frames ({ring.nbytes / 1e6:.0f} MB)"
    )
    recorder.start()
    watcher.start()
    t0 = time.perf_counter()
    camera.start()
    camera.join()
    recorder.join()
    elapsed = time.perf_counter() - t0
    done.set()
    watcher.join()
    source.close()
    status = recorder.status()

    with RecordingReader(path) as reader:
        ids = reader.frame_ids
        in_order = len(ids) == n_frames and bool((ids == np.arange(n_frames)).all())
        spot = [0, n_frames // 2, n_frames - 1]
        cycle_ok = all(
            np.array_equal(reader.frame(i), reader.frame(i % source.cycle_frames)) for i in spot
        )
    size = path.stat().st_size
    mb_per_s = status.read * frame_bytes / 1e6 / elapsed
    times_ms = sorted(1e3 * t for t in append_times)
    p99 = times_ms[int(0.99 * (len(times_ms) - 1))] if times_ms else float("nan")
    print(
        f"acquired {status.acquired}, recorded {recorder.written}, dropped {status.dropped} "
        f"(ring), lost {status.transport_lost} (transport), late {source.stats()['late']}"
    )
    print(f"achieved {status.acquired / elapsed:.1f} frames/s over {elapsed:.1f} s")
    print(f"sustained to disk: {mb_per_s:.0f} MB/s ({size / 1e9:.2f} GB file)")
    print(f"most frames waiting in the ring: {peak_unread} of {ring.capacity}")
    print(
        f"recorder per frame: median {statistics.median(times_ms):.2f} ms, "
        f"99th percentile {p99:.2f} ms (budget {1e3 / args.fps:.1f} ms)"
    )
    print(f"every frame on disk in order: {in_order}; content spot-checked: {cycle_ok}")
    met = in_order and cycle_ok and status.dropped == 0 and recorder.error is None
    print(f"target (all {n_frames} frames, none dropped): {'met' if met else 'MISSED'}")
    if recorder.error is not None:
        print(f"recorder error: {recorder.error}")
    if args.keep:
        print(f"kept {path}")
    else:
        shutil.rmtree(folder)
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
