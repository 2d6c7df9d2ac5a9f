"""Save screenshots of the live window's main states (run under a virtual display).

Usage::

    xvfb-run -a -s "-screen 0 1920x1080x24" .venv/bin/python scripts/screenshots.py \\
        [--source sim] [--out resources/screenshots] [--label RB1=FX,FY --label FB1=FX,FY]

States saved, one PNG each: ``1-start`` (frames, spectrum, detected peaks),
``2-labelled`` (two peaks labelled: predicted carriers, windows, maps, profile),
``3-phase`` (the same maps as phase with the cyclic colour map), ``4-recording``
(a recording running, its indicator), ``5-trends`` (the depth series and rate).
Without ``--label`` the two brightest detected peaks are labelled RB1 and FB1
(the paper's procedure names the brightest RB1).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

from PyQt6.QtWidgets import QApplication

from holoview.live.session import RecordRequest
from holoview.ui.app import application
from holoview.ui.main_window import MainWindow


def wait(app: QApplication, seconds: float) -> None:
    """Run the event loop for ``seconds``."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        app.processEvents()
        time.sleep(0.005)


def parse_label(text: str) -> tuple[str, float, float]:
    """Parse ``NAME=FX,FY`` (cycles per pixel)."""
    name, _, carrier = text.partition("=")
    fx, fy = (float(v) for v in carrier.split(","))
    return name, fx, fy


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", default="sim:evaporation")
    parser.add_argument("--size", type=int, default=512, help="simulated frame side, pixels")
    parser.add_argument("--out", type=Path, default=Path("resources/screenshots"))
    parser.add_argument("--label", action="append", type=parse_label, default=[])
    parser.add_argument("--settle", type=float, default=3.0, help="seconds per state")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO)
    args.out.mkdir(parents=True, exist_ok=True)
    app = application()
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["XDG_CONFIG_HOME"] = tmp  # the default layout, not the user's
        options = {"shape": (args.size, args.size)} if args.source.startswith("sim") else {}
        window = MainWindow(
            source=args.source,
            experiment_path=Path(tmp) / "experiment.json",
            source_options=options,
        )
        window.resize(1800, 1000)
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
        labels = args.label or window.suggested_labels()
        for name, fx, fy in labels:
            window.label_peak(name, fx, fy)
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
        window.trends.pca_box.setChecked(True)
        wait(app, args.settle * 2)
        save("5-trends")
        window.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
