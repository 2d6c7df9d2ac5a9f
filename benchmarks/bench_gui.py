"""The live window's speed: display, processing and camera rates, stalls, frame-to-screen latency.

Run it under a virtual display (or offscreen)::

    xvfb-run -a -s "-screen 0 1920x1080x24" .venv/bin/python benchmarks/bench_gui.py \\
        [--source sim] [--size 1024] [--fps 60] [--seconds 20]

It opens the main window on the source, labels two peaks (RB1 and FB1 from the
simulator's known setup or ``--label``; the model adds the other families), lets it
run, and prints medians and extremes:

- camera, series, maps and display frames per second, each counted separately, and the
  frames the series missed (it is meant to take every frame from the camera); the
  display is the camera view (the hologram, redrawn from the newest camera frame at up
  to the window's redraw rate), and the maps drawn are counted beside it;
- the longest event-loop stall: the largest gap between ticks of a 5 ms QTimer,
  minus 5 ms (the GUI is frozen that long);
- latency from the frame's host timestamp to the end of its draw call, for the maps
  and for the camera view; the maps' in parts: the newest frame's wait for the maps
  worker, the work, the maps' wait for the GUI thread, the draw call;
- the time per draw call, each worker's CPU per frame, and the machine's load average
  before and after (and its vector extensions);
- the targets of issue 17 (the series takes every frame, display >= 25 Hz, longest
  stall < 100 ms, no dropped frame) with issue 23's map latency p95 < 70 ms, and the
  maps' rate against the camera's with the reason when they fall behind (a map's CPU
  (the maps worker's and the maps process's, its side threads included) against a camera
  frame's interval, or what the other threads and the machine's load leave it);
- with ``--waves LABEL`` (a labelled peak, or ``fused``): the Waves panel open on that
  map; its worker's maps per second against the camera's, the stride (camera frames per
  map), frames lost or overwritten before it read them, and whether every camera frame
  gave a map (issue 24's live target) beside the issue-17 targets, and a map's time
  (the worker thread's per frame kept) beside its CPU time in the map's process (the
  rest is waiting for a core, or for the thread, which waits for the GIL);
- per thread, the share of the run it waited runnable for a core (Linux's schedstat:
  the machine's other work), beside its CPU share; and the CPU share of each child
  process (the maps', the Waves panel's map), by name;
- with ``--profile N``: where the GUI thread's time goes over the measured run (cProfile
  of the GUI thread, the N entries of largest cumulative time under pyqtgraph and
  holoview, in ms per displayed frame), and each image's render and paint time by shape.
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import math
import os
import pstats
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import pyqtgraph as pg
from machine import machine
from PyQt6.QtCore import QEventLoop, QTimer

from holoview.live.wave_worker import IN_FLIGHT
from holoview.ui.app import application
from holoview.ui.garbage import collect_between_events
from holoview.ui.main_window import MainWindow


def parse_label(text: str) -> tuple[str, float, float]:
    """Parse ``NAME=FX,FY`` (cycles per pixel)."""
    name, _, carrier = text.partition("=")
    fx, fy = (float(v) for v in carrier.split(","))
    return name, fx, fy


def child_cpu_seconds() -> dict[str, float]:
    """CPU seconds used so far by each child process of this one, by its name (Linux)."""
    ticks = os.sysconf("SC_CLK_TCK")
    out: dict[str, float] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            head, _, rest = stat.read_text().rpartition(")")
        except OSError:
            continue
        fields = rest.split()
        if int(fields[1]) == os.getpid():
            name = head.partition("(")[2]
            out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / ticks
    return out


def thread_cpu_seconds() -> dict[str, float]:
    """CPU seconds used so far by each Python thread of this process, by thread name (Linux)."""
    ticks = os.sysconf("SC_CLK_TCK")
    out: dict[str, float] = {}
    for thread in threading.enumerate():
        try:
            fields = Path(f"/proc/self/task/{thread.native_id}/stat").read_text().rsplit(")", 1)[1]
        except OSError:
            continue
        utime, stime = (int(v) for v in fields.split()[11:13])
        out[thread.name] = (utime + stime) / ticks
    return out


def thread_queue_seconds() -> dict[str, float]:
    """Seconds each Python thread of this process has waited runnable for a core (Linux)."""
    out: dict[str, float] = {}
    for thread in threading.enumerate():
        try:
            fields = Path(f"/proc/self/task/{thread.native_id}/schedstat").read_text().split()
        except OSError:
            continue
        out[thread.name] = int(fields[1]) * 1e-9
    return out


def median(values: list[float]) -> float:
    """The median of ``values`` (NaN for none: no map drawn on a machine too loaded)."""
    return statistics.median(values) if values else float("nan")


def percentile(values: list[float], q: float) -> float:
    """The ``q`` quantile (0..1) of ``values`` (nearest rank)."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


class ImageTimes:
    """Time every ``pg.ImageItem.paint`` (which renders the colour lookup when the image
    changed) by image shape and dtype, while installed."""

    def __init__(self) -> None:
        self.times: dict[str, list[float]] = collections.defaultdict(list)
        self._paint = pg.ImageItem.paint

    def __enter__(self) -> ImageTimes:
        paint = self._paint

        def timed(item: pg.ImageItem, *args: object) -> None:
            start = time.perf_counter()
            paint(item, *args)
            image = item.image
            key = "none" if image is None else f"{image.shape} {image.dtype}"
            self.times[key].append(time.perf_counter() - start)

        pg.ImageItem.paint = timed
        return self

    def __exit__(self, *exc: object) -> None:
        pg.ImageItem.paint = self._paint


def print_profile(profiler: cProfile.Profile, images: ImageTimes, frames: int, top: int) -> None:
    """Print the GUI thread's largest cumulative times and the images' paint times."""
    frames = max(frames, 1)
    stats = pstats.Stats(profiler)
    rows = [
        (cumulative, calls, f"{Path(path).name}:{line}({name})")
        for (path, line, name), (_, calls, _, cumulative, _) in stats.stats.items()  # type: ignore[attr-defined]
        if "pyqtgraph" in path or "holoview" in path
    ]
    print(f"GUI thread, ms per displayed frame (cumulative; {frames} frames drawn):")
    for cumulative, calls, where in sorted(rows, reverse=True)[:top]:
        print(f"  {1e3 * cumulative / frames:6.2f} ms  {calls / frames:5.1f} calls  {where}")
    print("images, paint (with the colour lookup when the image changed):")
    for key, times in sorted(images.times.items(), key=lambda kv: -sum(kv[1])):
        print(
            f"  {key:24s} {len(times) / frames:4.1f} per displayed frame, "
            f"{1e3 * statistics.median(times):5.2f} ms each, "
            f"{1e3 * sum(times) / frames:5.2f} ms per displayed frame"
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", default="sim")
    parser.add_argument("--size", type=int, default=1024, help="simulated frame side, pixels")
    parser.add_argument("--fps", type=float, default=60.0, help="simulated frame rate, Hz")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--warmup", type=float, default=4.0)
    parser.add_argument("--label", action="append", type=parse_label, default=[])
    parser.add_argument(
        "--profile", type=int, default=0, metavar="N", help="print the GUI thread's N top costs"
    )
    parser.add_argument(
        "--waves", metavar="LABEL", help="open the Waves panel on this map (a label or fused)"
    )
    parser.add_argument(
        "--waves-wait",
        type=float,
        default=20.0,
        metavar="S",
        help="seconds to wait for the labelled map to be offered in the Waves panel",
    )
    args = parser.parse_args()
    app = application()
    app.setQuitOnLastWindowClosed(False)
    load_before = os.getloadavg()
    options: dict[str, object] = {}
    if args.source.startswith("sim"):
        options = {"shape": (args.size, args.size), "frame_rate_hz": args.fps}
    elif args.source.startswith("replay:"):
        options = {"rate_hz": args.fps}
    with tempfile.TemporaryDirectory() as tmp, collect_between_events(app):
        os.environ["XDG_CONFIG_HOME"] = tmp
        window = MainWindow(
            source=args.source,
            experiment_path=Path(tmp) / "experiment.json",
            source_options=options,
        )
        window.show()
        while window.opening:
            app.processEvents()
            time.sleep(0.01)
        if window.session is None:
            print(f"cannot start {args.source}: {window.banner_text}", file=sys.stderr)
            return 1

        draws: list[float] = []
        work: list[float] = []
        latencies: list[float] = []
        waits: list[tuple[float, float]] = []  # (for the maps worker, for the GUI) per map
        views: list[float] = []
        view_latencies: list[float] = []
        original_draw = window._draw
        original_view = window._draw_camera

        def timed_draw(result: object) -> None:
            start = time.perf_counter()
            begun = time.time()
            done = result.t_done  # type: ignore[attr-defined]
            taken = done - result.processing_s  # type: ignore[attr-defined]
            waits.append((taken - result.t_host, begun - done))  # type: ignore[attr-defined]
            original_draw(result)  # type: ignore[arg-type]
            draws.append(time.perf_counter() - start)
            latencies.append(time.time() - result.t_host)  # type: ignore[attr-defined]
            work.append(result.processing_s)  # type: ignore[attr-defined]

        fetched: list = [None]
        original_newest = window.session.newest_frame

        def newest_frame() -> object:
            fetched[0] = original_newest()
            return fetched[0]

        def timed_view(frame: object) -> None:
            start = time.perf_counter()
            original_view(frame)  # type: ignore[arg-type]
            views.append(time.perf_counter() - start)
            view_latencies.append(time.time() - fetched[0][2].t_host)

        window.session.newest_frame = newest_frame  # type: ignore[method-assign]

        window._draw = timed_draw  # type: ignore[method-assign]
        window._draw_camera = timed_view  # type: ignore[method-assign]
        gaps: list[float] = []
        last = [time.perf_counter()]

        def tick() -> None:
            now = time.perf_counter()
            gaps.append(now - last[0])
            last[0] = now

        ticker = QTimer()
        ticker.setInterval(5)
        ticker.timeout.connect(tick)
        ticker.start()

        def run_for(seconds: float) -> None:
            loop = QEventLoop()
            QTimer.singleShot(int(seconds * 1000), loop.quit)
            loop.exec()

        run_for(1.5)
        labels = args.label or window.suggested_labels()
        for name, fx, fy in labels:
            window.label_peak(name, fx, fy)
        if args.waves:
            window.show_waves()
            for _ in range(round(2 * args.waves_wait)):  # offered once the maps show them
                run_for(0.5)
                if window.waves.map_box.findText(args.waves) >= 0:
                    break
            window.waves.choose_map(args.waves)
            if window.waves.map_box.currentText() != args.waves:
                print(f"no map {args.waves} to open in the Waves panel", file=sys.stderr)
                return 1
        run_for(args.warmup)
        draws.clear()
        views.clear()
        view_latencies.clear()
        work.clear()
        latencies.clear()
        waits.clear()
        gaps.clear()
        session = window.session
        cam0, seq0 = session.camera.frames, session.latest().seq
        series0 = session.series_worker.status()
        waves_worker = session.waves_worker
        if waves_worker is not None:
            waves0 = (
                waves_worker.history.pushed,
                waves_worker.status(),
                waves_worker.stride,
                waves_worker.backlog(),
            )
        cpu0, queue0 = thread_cpu_seconds(), thread_queue_seconds()
        children0 = child_cpu_seconds()
        t0 = time.monotonic()
        profiler = cProfile.Profile()  # the GUI thread only: cProfile hooks the calling thread
        with ImageTimes() as images:
            if args.profile:
                profiler.enable()
            run_for(args.seconds)
            profiler.disable()
        elapsed = time.monotonic() - t0
        cpu1, queue1 = thread_cpu_seconds(), thread_queue_seconds()
        children1 = child_cpu_seconds()
        camera_fps = (session.camera.frames - cam0) / elapsed
        processing_fps = (session.latest().seq - seq0) / elapsed
        series1 = session.series_worker.status()
        series_fps = (series1.read - series0.read) / elapsed
        missed = series1.dropped - series0.dropped
        labelled = sorted(session.latest().labelled)
        dropped = session.rates().dropped
        waves_line, waves_ok = "", True
        if waves_worker is not None:
            pushed = waves_worker.history.pushed - waves0[0]
            status = waves_worker.status()
            lost = status.dropped - waves0[1].dropped
            frames = session.camera.frames - cam0
            stride = waves_worker.stride
            # frames the worker has yet to read or whose maps are under way are not skipped
            waiting = waves_worker.backlog() - waves0[3] + IN_FLIGHT
            waves_ok = stride == 1 and waves0[2] == 1 and lost == 0 and pushed >= frames - waiting
            latest = session.waves()
            fit_s = f", analysis {latest.seconds * 1e3:.0f} ms" if latest is not None else ""
            waves_line = (
                f"waves       {pushed / elapsed:6.1f} maps/s of {args.waves} ({pushed} maps for "
                f"{frames} camera frames, {waiting} of them still waiting or under way; "
                f"stride {waves0[2]} -> {stride}; {lost} frames "
                f"overwritten before the waves worker read them{fit_s}; a map takes "
                f"{waves_worker.map_seconds() * 1e3:.1f} ms "
                f"({waves_worker.map_cpu_seconds() * 1e3:.1f} ms of CPU), a camera frame comes "
                f"every {1e3 / camera_fps:.1f} ms)"
            )
        ticker.stop()
        window.close()
    stall = max(gaps) - 0.005 if gaps else float("nan")
    print(
        f"source {args.source} {args.size} x {args.size} at {args.fps:g} fps; labelled {labelled}"
    )
    print(machine())
    print(f"load average before {load_before[0]:.2f}, after {os.getloadavg()[0]:.2f}")
    print(f"camera      {camera_fps:6.1f} fps")
    print(
        f"series      {series_fps:6.1f} fps  ({series_fps / max(camera_fps, 1e-9):.3f} of the "
        f"camera; {missed} frames missed)"
    )
    print(
        f"maps        {processing_fps:6.1f} fps  "
        f"({processing_fps / max(camera_fps, 1e-9):.2f} of the camera)"
    )
    print(f"display     {len(views) / elapsed:6.1f} fps  (the camera view)")
    print(f"maps drawn  {len(draws) / elapsed:6.1f} fps")
    print(
        f"draw call   maps median {median(draws) * 1e3:5.1f} ms, "
        f"p95 {percentile(draws, 0.95) * 1e3:5.1f} ms, "
        f"max {max(draws, default=math.nan) * 1e3:5.1f} ms; "
        f"camera view median {median(views) * 1e3:5.1f} ms, "
        f"p95 {percentile(views, 0.95) * 1e3:5.1f} ms"
    )
    print(
        f"view latency median {median(view_latencies) * 1e3:5.1f} ms, "
        f"p95 {percentile(view_latencies, 0.95) * 1e3:5.1f} ms (camera frame to screen)"
    )
    print(
        f"maps work   median {median(work) * 1e3:5.1f} ms per frame drawn, "
        f"max {max(work, default=math.nan) * 1e3:5.1f} ms"
    )
    print(
        f"map latency median {median(latencies) * 1e3:5.1f} ms, "
        f"p95 {percentile(latencies, 0.95) * 1e3:5.1f} ms, "
        f"max {max(latencies, default=math.nan) * 1e3:5.1f} ms"
    )
    for name, part in (
        ("the newest frame waits for the maps worker", [w[0] for w in waits]),
        ("the maps wait for the GUI thread", [w[1] for w in waits]),
    ):
        print(
            f"  of which {name}: median {median(part) * 1e3:5.1f} ms, "
            f"p95 {percentile(part, 0.95) * 1e3:5.1f} ms"
        )
    shares = ", ".join(
        f"{name} {100 * (cpu1[name] - cpu0.get(name, 0.0)) / elapsed:.0f}%" for name in sorted(cpu1)
    )
    print(f"CPU per thread (% of one core): {shares}")
    children = ", ".join(
        f"{name} {100 * (children1[name] - children0.get(name, 0.0)) / elapsed:.0f}%"
        for name in sorted(children1)
    )
    print(f"CPU per child process (% of one core): {children or 'none'}")
    queued = ", ".join(
        f"{name} {100 * (queue1[name] - queue0.get(name, 0.0)) / elapsed:.0f}%"
        for name in sorted(queue1)
    )
    print(f"waiting for a core per thread (% of the run): {queued}")
    gui_cpu = cpu1.get("MainThread", 0.0) - cpu0.get("MainThread", 0.0)
    demod_cpu = cpu1.get("holoview-demod", 0.0) - cpu0.get("holoview-demod", 0.0)
    # the maps are made in their own process (its side threads included) where it runs
    demod_cpu += children1.get("holoview-maps", 0.0) - children0.get("holoview-maps", 0.0)
    series_cpu = cpu1.get("holoview-series", 0.0) - cpu0.get("holoview-series", 0.0)
    # the series is measured in its own process where it runs
    series_cpu += children1.get("holoview-series", 0.0) - children0.get("holoview-series", 0.0)
    per_draw = gui_cpu / max(len(views), 1)
    per_frame = demod_cpu / max(processing_fps * elapsed, 1)
    per_series = series_cpu / max(series_fps * elapsed, 1)
    print(
        f"CPU per displayed frame {per_draw * 1e3:5.1f} ms (GUI thread, maps included), per map "
        f"{per_frame * 1e3:5.1f} ms (maps worker and process), per series frame "
        f"{per_series * 1e3:5.1f} ms (series worker and process)"
    )
    print(f"longest event-loop stall {stall * 1e3:5.1f} ms; dropped frames {dropped}")
    interval = 1.0 / max(camera_fps, 1e-9)
    maps_ok = processing_fps >= 0.98 * camera_fps
    if not maps_ok:
        cores = os.cpu_count() or 1
        busy = sum(cpu1[n] - cpu0.get(n, 0.0) for n in cpu1) / elapsed
        cost = (
            f"a map takes {per_frame * 1e3:.1f} ms of the maps' CPU (worker and process), "
            f"{'over' if per_frame > interval else 'under'} the {interval * 1e3:.1f} ms "
            "between camera frames"
        )
        spawned = sum(children1[n] - children0.get(n, 0.0) for n in children1) / elapsed
        share = (
            f"the maps got {100 * demod_cpu / elapsed:.0f}% of a core, this process "
            f"{100 * busy:.0f}% and its child processes {100 * spawned:.0f}% of the {cores} "
            f"cores (machine load {os.getloadavg()[0]:.1f})"
        )
        reason = f"{cost}; {share}"
        print(f"maps behind the camera: {reason}")
    if waves_line:
        print(waves_line)
    p95 = percentile(latencies, 0.95)
    checks = [
        ("series takes every frame", missed == 0 and series_fps >= 0.995 * camera_fps),
        ("display >= 25 Hz", len(views) / elapsed >= 25),
        ("map latency p95 < 70 ms", p95 < 0.07),
        ("maps at the camera's rate", maps_ok),
        ("longest stall < 100 ms", stall < 0.1),
        ("0 dropped", dropped == 0),
    ]
    if waves_line:
        checks.append(("waves map of every camera frame", waves_ok))
    print("targets: " + "; ".join(f"{name} {'met' if ok else 'MISSED'}" for name, ok in checks))
    if args.profile:
        print_profile(profiler, images, len(views), args.profile)
    return 0


if __name__ == "__main__":
    sys.exit(main())
