"""FFTW threads per frame on a quiet and on a loaded machine: why the library defaults to one.

Run from the repository root::

    .venv/bin/python benchmarks/bench_threads.py     # about a minute

Times :class:`~holoview.processing.maps.demodulate.Demodulator` on 1024 x 1024 frames with
the four peaks of ``bench_demodulation.py`` (relative reference, no unwrapping), with
one FFTW thread and with one per core, first as the machine is, then while one busy
process per core competes (started here, stopped here). Prints the median, 90th
percentile and worst frame (ms) of each case.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_demodulation import WAVELENGTH, bench_peaks, synth
from machine import machine

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from holoview.processing.fourier.fftplans import DEFAULT_THREADS, usable_cpus  # noqa: E402
from holoview.processing.maps.demodulate import Demodulator  # noqa: E402

FRAMES = 150
SHAPE = (1024, 1024)


def timings(threads: int, frames: list[np.ndarray]) -> tuple[float, float, float]:
    """Median, 90th percentile and worst time of a frame, ms."""
    demod = Demodulator(
        SHAPE,
        bench_peaks(4),
        reference="relative",
        unwrap="never",
        wavelength=WAVELENGTH,
        threads=threads,
    )
    for frame in frames[:5]:
        demod.process(frame)
    times = []
    for k in range(FRAMES):
        start = time.perf_counter()
        demod.process(frames[k % len(frames)])
        times.append(1e3 * (time.perf_counter() - start))
    times.sort()
    return statistics.median(times), times[int(0.9 * len(times))], times[-1]


def main() -> int:
    os.environ.setdefault(
        "HOLOVIEW_CACHE_DIR", str(Path(tempfile.gettempdir()) / "holoview-bench-cache")
    )
    print("machine:", machine())
    rng = np.random.default_rng(1)
    frames = [synth(SHAPE, bench_peaks(4), 0.0, rng) for _ in range(4)]
    cores = usable_cpus()
    counts = sorted({DEFAULT_THREADS, cores})
    print(f"1024 x 1024, 4 peaks, {FRAMES} frames; default threads {DEFAULT_THREADS}")
    print(f"{'machine':>24} {'threads':>7} {'median ms':>10} {'p90 ms':>8} {'worst ms':>9}")
    for state in ("as it is", f"{cores} busy processes"):
        hogs = []
        if state != "as it is":
            hogs = [
                subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(cores)
            ]
            time.sleep(1.0)
        try:
            for n in counts:
                median, p90, worst = timings(n, frames)
                print(f"{state:>24} {n:>7} {median:>10.2f} {p90:>8.2f} {worst:>9.2f}")
        finally:
            for hog in hogs:
                hog.terminate()
            for hog in hogs:
                hog.wait()
    print("\nload average at the end:", ", ".join(f"{v:.2f}" for v in os.getloadavg()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
