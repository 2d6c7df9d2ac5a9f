"""Save screenshots of the live window's main states (run under a virtual display).

Usage::

    xvfb-run -a -s "-screen 0 1366x768x24" .venv/bin/python scripts/screenshots.py \\
        [--source sim] [--size 1024] [--out resources/screenshots] [--label RB1=FX,FY ...]

The window opens as it would on that screen (its own layout for the screen's size),
and the PNGs go to ``OUT/WIDTHxHEIGHT/``. States saved, one PNG each: ``1-start``
(frames, spectrum, detected peaks, the first step and the suggested labels),
``2-labelled`` (the suggested labels used: predicted carriers, windows, maps,
profile), ``3-phase`` (the same maps as phase with the cyclic colour map),
``4-recording`` (a recording running, its indicator), ``5-trends`` (the depth series
and rate), ``6-replay`` (that recording opened as File > Open does: its whole run, the
frame shown as a cursor, a range fitted), ``7-waves`` (the Waves panel on the first
labelled peak's map, centred on the field; ``--source replay:PATH`` of a ``holoview
simulate --scenario travelling`` recording shows waves). ``--label`` names peaks
instead of the source's suggestions.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from PyQt6.QtWidgets import QApplication

from holoview.live.replay_control import FASTEST
from holoview.live.session import RecordRequest
from holoview.ui.app import application
from holoview.ui.garbage import collect_between_events
from holoview.ui.main_window import MainWindow


def wait(app: QApplication, seconds: float) -> None:
    """Run the event loop for ``seconds``."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        app.processEvents()
        time.sleep(0.005)


def until(app: QApplication, done: Callable[[], bool], seconds: float) -> bool:
    """Run the event loop until ``done()`` or ``seconds`` pass; return ``done()``."""
    end = time.monotonic() + seconds
    while not done() and time.monotonic() < end:
        app.processEvents()
        time.sleep(0.005)
    return done()


def replay(app: QApplication, window: MainWindow, path: Path, settle: float) -> bool:
    """Open ``path`` as File > Open does, fit the middle half of its run, show its middle."""
    window.open_file(path)
    if not until(app, lambda: window.run_trends.series is not None, 300):
        print(f"no whole run: {window.banner_text}", file=sys.stderr)
        return False
    window.docks["Trends"].raise_()
    times = window.run_trends.series.times  # type: ignore[union-attr]
    n = len(times)
    window.trends.choose_range(float(times[n // 4]), float(times[3 * n // 4]))
    until(app, lambda: window.run_trends.range_series is not None, 300)
    window.transport.seek(n // 2)
    wait(app, settle)
    return True


def parse_label(text: str) -> tuple[str, float, float]:
    """Parse ``NAME=FX,FY`` (cycles per pixel)."""
    name, _, carrier = text.partition("=")
    fx, fy = (float(v) for v in carrier.split(","))
    return name, fx, fy


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", default="sim:evaporation")
    parser.add_argument("--size", type=int, default=1024, help="simulated frame side, pixels")
    parser.add_argument("--out", type=Path, default=Path("resources/screenshots"))
    parser.add_argument("--label", action="append", type=parse_label, default=[])
    parser.add_argument("--settle", type=float, default=3.0, help="seconds per state")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO)
    app = application()
    screen = app.primaryScreen().geometry()
    args.out = args.out / f"{screen.width()}x{screen.height()}"
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp, collect_between_events(app):
        os.environ["XDG_CONFIG_HOME"] = tmp  # the default layout, not the user's
        # rendered live: a cycle's loop would put a jump back in the run recorded (6-replay)
        options = (
            {"shape": (args.size, args.size), "render": "live"}
            if args.source.startswith("sim")
            else {}
        )
        window = MainWindow(
            source=args.source,
            experiment_path=Path(tmp) / "experiment.json",
            source_options=options,
        )
        window.show()
        while window.opening:
            app.processEvents()
            time.sleep(0.01)

        def save(name: str) -> None:
            path = args.out / f"{name}.png"
            window.grab().save(str(path))
            print(f"saved {path}")

        wait(app, args.settle)
        if window.session is None:
            print(f"no source: {window.banner_text}", file=sys.stderr)
            window.close()
            return 1
        save("1-start")
        if args.label:
            for name, fx, fy in args.label:
                window.label_peak(name, fx, fy)
        else:
            window.use_known_labels()
        window.surface.reference_box.setCurrentText("absolute")
        wait(app, args.settle)
        window.surface.auto_range()
        wait(app, 0.5)
        save("2-labelled")
        window.surface.mode_box.setCurrentIndex(1)
        wait(app, 1.0)
        save("3-phase")
        window.surface.mode_box.setCurrentIndex(0)
        window.start_recording(RecordRequest(Path(tmp) / "rec.h5", duration_s=None, frames=None))
        wait(app, 1.5)
        window.docks["Recording"].raise_()
        wait(app, 0.3)
        save("4-recording")
        window.stop_recording()
        window.docks["Source"].raise_()
        window.docks["Trends"].raise_()  # tabbed with the maps on smaller screens
        window.trends.pca_box.setChecked(True)
        wait(app, args.settle * 2)
        save("5-trends")
        window.trends.pca_box.setChecked(False)
        if not replay(app, window, Path(tmp) / "rec.h5", args.settle):
            window.close()
            return 1
        save("6-replay")
        window.show_waves()
        wait(app, 1.0)
        labels = [window.waves.map_box.itemText(i) for i in range(window.waves.map_box.count())]
        window.waves.choose_map("RB1" if "RB1" in labels else labels[0])
        window.waves.length_box.setCurrentIndex(window.waves.length_box.findData(128))
        replay_control = window.session.replay
        if replay_control is not None:  # played as fast as it reads: a map of every frame
            # once from the first frame to the last, not looped: a loop's jump starts the
            # window again, and the recording is a few dozen frames, one segment or two;
            # through the transport bar, as a click would, so the source panel follows
            window.transport.set_loop(False)
            window.transport.set_speed(FASTEST)
            window.transport.to_start()
            replay_control.play()
        # a spectrum (a fit too where the recording has waves; an evaporation's fails)
        until(app, lambda: (w := window.session.waves()) is not None and w.spectrum is not None, 60)
        waves = window.session.waves()
        if waves is not None and waves.latest is not None and waves.pixel_size is not None:
            rows, cols = waves.latest.shape
            window.waves.set_centre(
                (cols // 2 * waves.pixel_size[1], rows // 2 * waves.pixel_size[0])
            )
            until(app, lambda: (w := window.session.waves()) is not None and w.mf is not None, 30)
            wait(app, args.settle)
        save("7-waves")
        window.close()
    return 0


if __name__ == "__main__":
    status = main()
    # ended here, not in the interpreter's teardown, as holoview live ends (its
    # cli/live.py says why): Qt's and PyQt's objects go in no set order there, and one
    # run in ten of this script ended with a segmentation fault after saving every image
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)
