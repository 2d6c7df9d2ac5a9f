"""Issue 14 figures: peak detection on frames with lost packets, and the relation check's scaling.

Run from the repository root::

    .venv/bin/python benchmarks/bench_peaks_damage.py

Prints, on simulated 256 x 256 and 1024 x 1024 holograms (:class:`HologramSynthesizer`):

1. :func:`~holoview.processing.fourier.frames.frame_damage` on a clean frame and on one with an
   eighth of its rows zeroed (the simulator's ``corrupt_rate``), microseconds; and
   :func:`~holoview.processing.peaks.detection.find_peaks` on both (the damaged frame is refused
   with the reason, not searched), milliseconds; medians of repeated calls;
2. the same frame with a zeroed block that leaves every row partly lit (not detected as
   damage: the search runs, bounded by ``MAX_CANDIDATES`` and the tree relation check);
3. :func:`~holoview.processing.peaks.detection.flag_relations` on n random peaks, n = 100 to 12800:
   milliseconds and the ratio to ``n log n`` (flat when the check is ``O(n log n)``), beside
   the cubic check it replaced for the smallest n (its cost grows as n^3).

Before this issue a damaged 256^2 frame took 2.6 s (60 spurious peaks) and a 1024^2
frame 113 s (241 peaks) on this machine.
"""

from __future__ import annotations

import itertools
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from machine import machine  # noqa: E402

from holoview.errors import InputError  # noqa: E402
from holoview.optics.setup import Setup  # noqa: E402
from holoview.optics.synthesis import HologramSynthesizer  # noqa: E402
from holoview.processing.fourier.frames import frame_damage  # noqa: E402
from holoview.processing.fourier.windows import wrap_frequency  # noqa: E402
from holoview.processing.peaks.detection import (  # noqa: E402
    RELATION_TOLERANCE_BINS,
    Peak,
    find_peaks,
    flag_relations,
)


def median_seconds(call, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def detect(frame: np.ndarray) -> str:
    try:
        return f"{len(find_peaks(frame))} peaks"
    except InputError as exc:
        return f"refused: {exc}"


def cubic_sums(peaks: list[Peak], shape: tuple[int, int]) -> None:
    """The sum check as it was: every pair of stronger peaks for every peak."""
    carriers = np.array([p.carrier for p in peaks])
    for i, peak in enumerate(peaks):
        stronger = [j for j, p in enumerate(peaks) if p.amplitude > peak.amplitude]
        for j, k in itertools.combinations(stronger, 2):
            for sj, sk in itertools.product((1, -1), repeat=2):
                d = wrap_frequency(carriers[i] - sj * carriers[j] - sk * carriers[k])
                _ = np.hypot(d[0] * shape[1], d[1] * shape[0]) <= RELATION_TOLERANCE_BINS


def main() -> None:
    print(machine())
    for side in (256, 1024):
        frame = HologramSynthesizer(Setup(shape=(side, side))).render(
            0.0, rng=np.random.default_rng(1)
        )
        band = side // 8
        damaged = frame.copy()
        damaged[side // 3 : side // 3 + band] = 0
        partial = frame.copy()
        partial[side // 3 : side // 3 + band, : int(side * 0.8)] = 0
        repeats = 20 if side == 256 else 5
        print(f"\n{side} x {side}")
        for name, f in (
            ("clean", frame),
            ("rows zeroed", damaged),
            ("rows partly zeroed", partial),
        ):
            check = median_seconds(lambda f=f: frame_damage(f), 200)
            search = median_seconds(lambda f=f: detect(f), repeats)
            print(
                f"  {name:<19} frame_damage {check * 1e6:7.1f} us   find_peaks "
                f"{search * 1e3:8.2f} ms   {detect(f)[:70]}"
            )
    print("\nflag_relations on n random peaks (1024 x 1024 frame, radius 0.01)")
    rng = np.random.default_rng(0)
    base = None
    for n in (100, 200, 400, 800, 1600, 3200, 6400, 12800):
        peaks = [
            Peak((float(x), float(y)), float(a), 10.0)
            for (x, y), a in zip(rng.uniform(-0.5, 0.5, (n, 2)), rng.uniform(0, 1, n), strict=True)
        ]
        seconds = median_seconds(lambda p=peaks: flag_relations(p, (1024, 1024), radius=0.01), 3)
        per = seconds / (n * np.log(n))
        base = base or per
        line = f"  n {n:6d}: {seconds * 1e3:9.2f} ms, per n log n {per / base:5.2f} x n=100's"
        if n == 100:
            cubic = median_seconds(lambda p=peaks: cubic_sums(p, (1024, 1024)), 1)
            line += f";  the cubic sum check: {cubic * 1e3:9.1f} ms"
        print(line)


if __name__ == "__main__":
    main()
