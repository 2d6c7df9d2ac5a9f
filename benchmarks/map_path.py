"""The map path after the demodulator, for ``bench_demodulation.py --floor`` (issue 23).

One frame's maps, as the maps step (:mod:`holoview.engine.map_step`) makes them in
``holoview process``, its workers and the live maps worker, at 1024 x 1024 with 4 peaks,
one thread, side by side in rounds on the same frames:

- demodulation (``Demodulator.process``, defaults);
- the trusted maps (delta-h, NaN where untrusted: :func:`trusted_maps`);
- fusion alone (:func:`fuse_maps` without displacements);
- co-registration and fusion (:func:`fuse_maps` with fixed sub-pixel displacements, so the
  maps are moved onto the first peak's grid as a run moves them);
- writing: :meth:`ResultsFile.write_maps` of the 4 maps and the fused one into a
  ``results.h5`` on the temporary folder, the file's own batching (16 frames a write)
  included, the share of each frame of a batch's write.

The demodulation's own parts are ``demod_floor.profile``'s.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from holoview.engine.map_step import fuse_maps, trusted_maps
from holoview.headless.results.results_file import MAP_BATCH, ResultsFile
from holoview.processing.maps.coregister import Displacement
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.peaks.detection import Peak

#: Fixed displacements (map pixels) of the peaks after the first, as a run might measure.
SHIFTS = ((0.0, 0.0), (0.31, -0.74), (-0.52, 0.18), (1.27, 0.43))


def run_map_path(
    peaks: list[Peak], frames: list[np.ndarray], *, wavelength: float, rounds: int
) -> None:
    """Print each step's time per frame (median over rounds, thread CPU time) and share."""
    shape = (int(frames[0].shape[0]), int(frames[0].shape[1]))
    demod = Demodulator(shape, peaks, wavelength=wavelength, threads=1)
    for k in range(2):  # the reference frame, plans
        demod.process(frames[k % len(frames)])
    results = [demod.process(frame) for frame in frames]
    maps = [trusted_maps(r) for r in results]
    noise = [[p.noise_height for p in r.peaks] for r in results]
    steady = [False] * len(peaks)
    moved = [Displacement(s, (0.01, 0.01), True, 100) for s in SHIFTS[: len(peaks)]]
    fused = [fuse_maps(m, n, steady, moved) for m, n in zip(maps, noise, strict=True)]
    per_batch = MAP_BATCH
    with tempfile.TemporaryDirectory(prefix="holoview-map-path-") as folder:
        count = rounds * per_batch
        sink = ResultsFile(
            Path(folder) / "results.h5",
            labels=[p.label or "?" for p in peaks],
            n_frames=count + per_batch,
            box_shape=demod.box_shape,
            maps=True,
        )
        written = [0]

        def write(k: int) -> None:
            for _ in range(per_batch):  # one batch: the last call writes it to the file
                j = written[0] % len(frames)
                sink.write_maps(written[0], maps[j], fused[j])
                written[0] += 1

        cases: dict[str, tuple[Callable[[int], object], int]] = {
            "demodulation (Demodulator.process)": (
                lambda k: demod.process(frames[k % len(frames)]),
                1,
            ),
            "trusted maps (delta-h, NaN untrusted)": (
                lambda k: trusted_maps(results[k % len(results)]),
                1,
            ),
            "fusion alone": (
                lambda k: fuse_maps(maps[k % len(maps)], noise[k % len(maps)], steady),
                1,
            ),
            "co-registration and fusion": (
                lambda k: fuse_maps(maps[k % len(maps)], noise[k % len(maps)], steady, moved),
                1,
            ),
            "writing (results.h5, 5 maps)": (write, per_batch),
        }
        times: dict[str, list[float]] = {name: [] for name in cases}
        calls = 0
        for _ in range(rounds):
            for name, (fn, frames_per_call) in cases.items():
                start = time.thread_time()
                for _ in range(4 if frames_per_call == 1 else 1):
                    fn(calls)
                    calls += 1
                elapsed = time.thread_time() - start
                times[name].append(elapsed / (4 if frames_per_call == 1 else frames_per_call))
        sink.close()
    median = {name: statistics.median(t) for name, t in times.items()}
    coregistration = median["co-registration and fusion"] - median["fusion alone"]
    steps = {
        "demodulation (Demodulator.process)": median["demodulation (Demodulator.process)"],
        "trusted maps (delta-h, NaN untrusted)": median["trusted maps (delta-h, NaN untrusted)"],
        "co-registration (moving 3 maps)": coregistration,
        "fusion": median["fusion alone"],
        "writing (results.h5, 5 maps)": median["writing (results.h5, 5 maps)"],
    }
    whole = sum(steps.values())
    print(
        f"\nthe map path per frame, {len(peaks)} peaks, box {demod.box_shape} (thread CPU "
        "time, median over rounds; co-registration is the difference of the two fusions):"
    )
    for name, value in steps.items():
        print(f"{name:>56}: {1e3 * value:6.3f} {100 * value / whole:5.1f} %")
    print(f"{'the whole map path':>56}: {1e3 * whole:6.3f} 100.0 %")
