"""Throughput and memory of ``holoview process`` on a long 1024 x 1024 recording.

Run from the repository root::

    .venv/bin/python benchmarks/bench_process.py              # 2000 frames, about 3 minutes
    .venv/bin/python benchmarks/bench_process.py --frames 500 # quicker

Writes a simulated recording (evaporating water, 12-bit in uint16, the default bench
setup at 1024 x 1024, pooled shot noise) into a temporary folder under /tmp, then prints,
with the machine and its load:

1. reading alone: every frame read back through the same reader ``process`` uses
   (the file is in the page cache, as it is right after recording);
2. on frames held in memory, for the same peaks, window and threads as ``process``
   chooses: the demodulator alone (the maps) and the carrier probe alone (the series);
3. ``holoview process`` end to end, in a child process, over the first 10 % of the
   frames and over all of them, without and with ``--maps``: frames per second, the
   reading share, and the peak resident memory (RSS) of each run, which must not grow
   with the number of frames; with ``--baseline DIR`` (a checkout of an earlier
   holoview, e.g. ``git worktree add /tmp/old e8e0650``) the same runs of that code too,
   without and with ``--maps``, each run of this checkout and of the baseline in turn
   (``--repeat`` times, the median kept);
4. the targets: without ``--maps``, ``process`` at least twice as fast as the map path
   of before (every frame demodulated: the baseline's run, else the demodulator's plus
   the reading's time, its lower bound); with ``--maps``, at most the demodulator's plus
   the reading's time per frame;
5. with ``--baseline``: this checkout against the baseline, ms/frame and peak RSS,
   without ``--maps`` (issue 23: at least as fast, RSS not much above) and with it
   (issue 23: at least 1.5 times as fast).

The recording and the outputs are deleted at the end. Timings on a shared machine are
noisy: read the load average printed with them.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from machine import machine

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from holoview.acquire.recording_writer import RecordingWriter  # noqa: E402
from holoview.engine.experiment import Experiment, LabelledPeak  # noqa: E402
from holoview.engine.frame_core import CarrierCore, FrameCore  # noqa: E402
from holoview.headless.inputs import InputFile, OpticsOptions, resolve_optics  # noqa: E402
from holoview.headless.selection import select_from_experiment  # noqa: E402
from holoview.optics.families import predict_families  # noqa: E402
from holoview.optics.setup import Setup  # noqa: E402
from holoview.optics.synthesis import HologramSynthesizer  # noqa: E402
from holoview.processing.peaks.detection import find_peaks  # noqa: E402

SHAPE = (1024, 1024)
FPS = 80.0
RATE = -60e-6 / 60  # m/s, 60 um/min

#: Runs ``holoview`` and reports its own peak RSS (kB) on the last line of stderr.
CHILD = (
    "import resource, sys\n"
    "from holoview.cli import main\n"
    "status = main(sys.argv[1:])\n"
    "print('MAXRSS_KB', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)\n"
    "sys.exit(status)\n"
)


def write_recording(path: Path, frames: int, setup: Setup) -> float:
    """Write the simulated recording; return the seconds it took."""
    synthesiser = HologramSynthesizer(setup, noise="pooled")
    rng = np.random.default_rng(1)
    start = time.perf_counter()
    with RecordingWriter(
        path,
        SHAPE,
        "uint16",
        setup=setup.as_attributes(),
        settings={"frame_rate_hz": FPS},
        source="bench_process",
        significant_bits=12,
        pixel_format="Mono12",
    ) as writer:
        for i in range(frames):
            t = i / FPS
            writer.append(synthesiser.render(RATE * t, rng=rng), i, t, time.time())
    return time.perf_counter() - start


def label_args(setup: Setup) -> list[str]:
    truth = {f.label: f.observed_carrier for f in predict_families(setup, max_order=2)}
    args = []
    for label in ("RB1", "FB1"):
        fx, fy = truth[label]
        args += ["--label", f"{label}={fx:.6f},{fy:.6f}"]
    return args


def read_speed(path: Path) -> float:
    """Seconds per frame reading every frame in order."""
    with InputFile(path) as source:
        start = time.perf_counter()
        for i in range(len(source)):
            source.read(i)
        return (time.perf_counter() - start) / len(source)


def demodulator_speed(path: Path, labels: list[str]) -> tuple[float, float, str]:
    """Median seconds per frame of the demodulator and of the carrier probe alone; the peaks."""
    with InputFile(path) as source:
        optics = resolve_optics(source.setup, OpticsOptions())
        frames = [source.read(i) for i in range(32)]
        shape = source.frame_shape
        saturation = source.saturation
    parsed = {}
    for k in range(0, len(labels), 2):
        name, _, carrier = labels[k + 1].partition("=")
        fx, fy = (float(v) for v in carrier.split(","))
        parsed[name] = (fx, fy)
    experiment = Experiment(
        wavelength_m=optics.wavelength_m,
        n1=optics.n1,
        n2=optics.n2,
        peaks=tuple(LabelledPeak(k, c) for k, c in parsed.items()),
    )
    selection = select_from_experiment(experiment, find_peaks(frames[0]), shape, "labels")
    core = FrameCore(shape, experiment, selection.peaks, saturation=saturation)
    demodulator = core.build()
    assert demodulator is not None
    for frame in frames[:4]:
        demodulator.process(frame)
    times = []
    for _ in range(4):
        for frame in frames:
            t0 = time.perf_counter()
            demodulator.process(frame)
            times.append(time.perf_counter() - t0)
    probe = CarrierCore(shape, saturation)
    probe.configure(demodulator.peaks)
    probe_times = []
    for _ in range(4):
        for frame in frames:
            t0 = time.perf_counter()
            probe.measure(frame)
            probe_times.append(time.perf_counter() - t0)
    peaks = ", ".join(p.label or "?" for p in selection.peaks)
    description = f"{len(selection.peaks)} peaks ({peaks}), boxes {demodulator.box_shape}"
    return statistics.median(times), statistics.median(probe_times), description


def run_process(
    path: Path, out: Path, args: list[str], code: Path = REPO
) -> tuple[dict, float, float]:
    """Run ``holoview process`` of the checkout ``code`` in a child; summary, wall s, RSS (MB)."""
    argv = ["-q", "process", str(path), "--out", str(out), *args]
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", CHILD, *argv],
        cwd=code,
        env={**os.environ, "PYTHONPATH": str(code)},
        capture_output=True,
        text=True,
        check=False,
    )
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"holoview process failed:\n{done.stderr}")
    rss_kb = next(
        int(line.split()[1]) for line in done.stderr.splitlines() if line.startswith("MAXRSS_KB")
    )
    summary = json.loads((out / "summary.json").read_text())
    return summary, wall, rss_kb / 1024


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=2000, help="frames in the recording")
    parser.add_argument(
        "--baseline", type=Path, metavar="DIR", help="an earlier holoview checkout to time too"
    )
    parser.add_argument(
        "--repeat", type=int, default=1, help="runs of each process command (median kept)"
    )
    args = parser.parse_args(argv)
    setup = Setup(shape=SHAPE)
    folder = Path(tempfile.mkdtemp(prefix="holoview-bench-process-", dir="/tmp"))
    try:
        path = folder / "evaporation.h5"
        print(machine())
        seconds = write_recording(path, args.frames, setup)
        size_gb = path.stat().st_size / 1e9
        print(
            f"recording: {args.frames} frames of {SHAPE[0]} x {SHAPE[1]} uint16 "
            f"({size_gb:.2f} GB) written in {seconds:.1f} s"
        )
        labels = label_args(setup)
        read_s = read_speed(path)
        print(f"1. reading alone: {read_s * 1e3:.2f} ms/frame ({1 / read_s:.0f} frames/s)")
        demod_s, probe_s, described = demodulator_speed(path, labels)
        print(
            f"2. frames in memory, {described}: demodulator {demod_s * 1e3:.2f} ms/frame, "
            f"carrier probe {probe_s * 1e3:.2f} ms/frame (medians; ratio "
            f"{demod_s / probe_s:.1f})"
        )
        print("3. holoview process (child process; time from summary.json, RSS = peak resident)")
        short = max(10, args.frames // 10)
        runs = [
            (f"first {short} frames", [*labels, "--frames", f"0:{short}"], REPO),
            (f"all {args.frames} frames", labels, REPO),
            (f"all {args.frames} frames --maps", [*labels, "--maps"], REPO),
        ]
        if args.baseline is not None:
            runs.append((f"all {args.frames} frames, baseline", labels, args.baseline))
            runs.append(
                (f"all {args.frames} frames --maps, baseline", [*labels, "--maps"], args.baseline)
            )
        # each run of this checkout beside the baseline's, in turn: a load that comes and
        # goes weighs on both alike
        timed: list[list[tuple[float, float, float, dict]]] = [[] for _ in runs]
        for _ in range(max(1, args.repeat)):
            for k, (_, extra, code) in enumerate(runs):
                summary, wall, rss = run_process(path, folder / "out", extra, code)
                timing = summary["timing"]
                per_frame = timing["seconds"] / summary["frames"]["processed"]
                timed[k].append((per_frame, rss, wall, timing))
                shutil.rmtree(folder / "out")
        results = []
        for (name, _, _), runs_of in zip(runs, timed, strict=True):
            per_frame = statistics.median(r[0] for r in runs_of)
            rss = statistics.median(r[1] for r in runs_of)
            wall = statistics.median(r[2] for r in runs_of)
            timing = min(runs_of, key=lambda r: abs(r[0] - per_frame))[3]
            results.append((per_frame, rss, wall))
            every = ", ".join(f"{r[0] * 1e3:.2f}" for r in runs_of)
            print(
                f"   {name:<38} {1 / per_frame:7.1f} frames/s ({per_frame * 1e3:.2f} ms/frame; "
                f"reading {timing['read_seconds'] / timing['seconds']:.0%} of the loop on its "
                f"thread, demodulating {timing['demodulate_seconds'] / timing['seconds']:.0%}); "
                f"command {wall:.1f} s in all; peak RSS {rss:.0f} MB"
                + (f" [runs: {every} ms/frame]" if len(runs_of) > 1 else "")
            )
        budget = demod_s + read_s
        before = results[3][0] if args.baseline is not None else budget
        source = "the baseline's run" if args.baseline is not None else "its lower bound"
        speedup = before / results[1][0]
        ratio = results[2][0] / budget
        growth = results[1][1] / results[0][1]
        print(
            f"4. targets: without --maps {results[1][0] * 1e3:.2f} ms/frame against the map "
            f"path of before {before * 1e3:.2f} ms/frame ({source}): x{speedup:.2f} "
            f"({'met' if speedup >= 2 else 'missed'}, >= 2 wanted); with --maps "
            f"{results[2][0] * 1e3:.2f} ms/frame against demodulator + reading "
            f"{budget * 1e3:.2f} ms/frame: ratio {ratio:.2f} "
            f"({'met' if ratio <= 1.05 else 'missed'}, <= 1 wanted); RSS {results[0][1]:.0f} MB "
            f"for {short} frames, {results[1][1]:.0f} MB for {args.frames}: x{growth:.2f} "
            f"({'bounded' if growth < 1.2 else 'GROWS'})"
        )
        if args.baseline is not None:
            plain = results[3][0] / results[1][0]
            maps = results[4][0] / results[2][0]
            print(
                f"5. against the baseline ({args.baseline}): without --maps "
                f"{results[1][0] * 1e3:.2f} against {results[3][0] * 1e3:.2f} ms/frame: "
                f"x{plain:.2f} ({'met' if plain >= 1 else 'missed'}, >= 1 wanted), peak RSS "
                f"{results[1][1]:.0f} against {results[3][1]:.0f} MB; with --maps "
                f"{results[2][0] * 1e3:.2f} against {results[4][0] * 1e3:.2f} ms/frame: "
                f"x{maps:.2f} ({'met' if maps >= 1.5 else 'missed'}, >= 1.5 wanted), peak RSS "
                f"{results[2][1]:.0f} against {results[4][1]:.0f} MB"
            )
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
