"""Time and memory of maps on the frame's grid (``process --maps --maps-grid frame``), 1024^2.

Run from the repository root::

    .venv/bin/python benchmarks/bench_maps_grid.py              # 40 frames, about a minute
    .venv/bin/python benchmarks/bench_maps_grid.py --frames 20

Writes the simulated recording of ``bench_process.py`` (evaporating water, 1024 x 1024,
RB1 and FB1 labelled, the model adding the other families) into a temporary folder
under /tmp, then prints, with the machine and its load:

1. on frames held in memory: the maps step (:class:`holoview.engine.map_step.MapStep`,
   the fused map included, the peaks moved by fixed displacements as a run's are) per
   frame on the box's grid and on the frame's (medians), and the bytes of one frame's
   maps;
2. ``holoview process --maps`` in a child process on each grid (``--jobs 1``): time per
   frame of the whole run and of its maps (``summary.json``), the peak resident memory
   (RSS), which must not grow with the frames, and the size of ``results.h5``.

The recording and the outputs are deleted at the end.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from bench_process import REPO, label_args, run_process, write_recording
from machine import machine

sys.path.insert(0, str(REPO))

from holoview.engine.map_step import regridded
from holoview.headless.inputs import InputFile
from holoview.headless.prepare import prepare_run
from holoview.headless.selection import parse_assignment
from holoview.headless.settings import PeakChoice, ProcessOptions
from holoview.optics.setup import Setup
from holoview.processing.maps.coregister import Displacement

SHAPE = (1024, 1024)


def step_times(path: Path, labels: list[str], frames: int) -> dict[str, tuple[float, int, str]]:
    """Per grid: median seconds of the maps step per frame, bytes of a frame's maps, the peaks."""
    given = dict(parse_assignment(text, "--label") for text in labels[1::2])
    options = ProcessOptions(choice=PeakChoice(labels=given), report=False, jobs=1).checked()
    out = {}
    with InputFile(path) as source:
        run = prepare_run(source, range(len(source)), options).frames
        held = [source.read(i) for i in range(min(frames, 12))]
        box = run.spec.core(source.frame_shape, source.saturation).demodulator
        assert box is not None
        # every peak but the first moved by (0.4, -0.3) box pixels before fusion, as a
        # run's co-registration moves them
        moves = [Displacement((0.4, -0.3), (0.01, 0.01), True, 50) for _ in box.peaks]
        moves[0] = Displacement((0.0, 0.0), (0.0, 0.0), True, 50)
        for grid in ("box", "frame"):
            shape = box.box_shape if grid == "box" else source.frame_shape
            spec = replace(
                run.spec, grid=grid, displacements=tuple(regridded(moves, box.box_shape, shape))
            )
            step = spec.step(source.frame_shape, source.saturation)
            demod = step.core.demodulator
            assert demod is not None
            times = []
            for k, frame in enumerate(held * 2):
                t0 = time.perf_counter()
                maps = step.process(frame)
                if k >= len(held) // 2:  # plans and caches warm
                    times.append(time.perf_counter() - t0)
            fused = 0 if maps.fused is None else maps.fused.nbytes
            nbytes = sum(m.nbytes for m in maps.maps) + fused
            peaks = f"{len(demod.peaks)} peaks, maps {demod.box_shape}"
            out[grid] = (statistics.median(times), nbytes, peaks)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=40, help="frames in the recording")
    args = parser.parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix="holoview-bench-grid-", dir="/tmp"))
    try:
        path = folder / "evaporation.h5"
        print(machine())
        seconds = write_recording(path, args.frames, Setup(shape=SHAPE))
        print(f"recording: {args.frames} frames of {SHAPE[0]} x {SHAPE[1]} in {seconds:.1f} s")
        labels = label_args(Setup(shape=SHAPE))
        print("1. the maps step, frames in memory (medians):")
        for grid, (s, nbytes, peaks) in step_times(path, labels, args.frames).items():
            print(f"   {grid:<6} {s * 1e3:8.1f} ms/frame; {peaks}; {nbytes / 1e6:.1f} MB a frame")
        print("2. holoview process --maps --jobs 1 (child process):")
        for grid in ("box", "frame"):
            out = folder / f"out-{grid}"
            extra = [*labels, "--maps", "--maps-grid", grid, "--jobs", "1", "--report-format"]
            summary, wall, rss = run_process(path, out, [*extra, "png"])
            timing = summary["timing"]
            n = summary["frames"]["processed"]
            size = (out / "results.h5").stat().st_size
            print(
                f"   {grid:<6} {timing['seconds'] / n * 1e3:8.1f} ms/frame in all, maps "
                f"{timing['maps_seconds'] / n * 1e3:.1f} ms/frame; command {wall:.1f} s; "
                f"peak RSS {rss:.0f} MB; results.h5 {size / 1e6:.0f} MB"
            )
            shutil.rmtree(out)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
