"""``holoview record``: headless acquisition of a source into a holoview recording.

The camera thread fills a frame ring; the recorder thread writes every frame to
the file (format in :mod:`holoview.acquire.recording`); this command shows a
progress bar and ends with one line of what was acquired, recorded and lost.

The recording stores the experiment ``--experiment`` names; without it, a replayed
holoview recording's own experiment is copied with its changes, each from the frame
of the copy where the source's frame it held from went (``replay:`` keeps the
labelled peaks, so processing the copy measures what processing the source did).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from holoview.cli.options import add_experiment_option, add_optics_options, optics_in_metres
from holoview.cli.signals import deferred_signals, emit
from holoview.errors import HoloviewError, InputError

if TYPE_CHECKING:
    from holoview.acquire.camera_thread import CameraThread
    from holoview.acquire.recorder import Recorder
    from holoview.acquire.ring import FrameRing
    from holoview.engine.experiment import Experiment

logger = logging.getLogger(__name__)


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register ``record``."""
    parser = subparsers.add_parser(
        "record",
        help="record a source to an HDF5 file, headless",
        description="Record frames from a source into a new holoview recording (HDF5, "
        "readable while it is written). Ctrl-C stops and keeps what was recorded.",
    )
    parser.add_argument("out", type=Path, metavar="OUT.h5", help="the recording to create")
    parser.add_argument(
        "--source",
        default="sim",
        help="sim[:SCENARIO] (default), aravis[:ID], v4l2[:N] or replay:PATH",
    )
    length = parser.add_mutually_exclusive_group()
    length.add_argument("--frames", type=int, metavar="N", help="stop after N frames")
    length.add_argument(
        "--seconds", type=float, metavar="S", help="stop S seconds after the first frame"
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a source setting before streaming, e.g. exposure_s=0.002 or roi=0,0,640,480 "
        "(repeatable)",
    )
    parser.add_argument(
        "--ring-mb",
        type=float,
        default=512.0,
        metavar="MB",
        help="memory of the frame ring between camera and disk, MB (default 512: about "
        "3 s of 1024 x 1024 uint16 at 80 frames/s, for disk writeback stalls)",
    )
    add_experiment_option(
        parser,
        "the experiment in force (labelled peaks, optics, window, reference; as the GUI "
        "saves it): stored in the recording, so `holoview process` needs no peak options. "
        "Without it, a replayed recording's own experiment and its changes are copied; "
        "with it, they are replaced by FILE's",
    )
    add_optics_options(parser, "setup stored in the recording (over the experiment's)")
    return parser


def parse_setting(text: str) -> tuple[str, object]:
    """Return ``(name, value)`` from ``NAME=VALUE``: a number, a bool, a comma list, or text."""
    name, sep, raw = text.partition("=")
    if not sep or not name.strip():
        raise InputError(f"--set takes NAME=VALUE, got {text!r}")
    raw = raw.strip()
    if raw.lower() in ("true", "false", "yes", "no", "on", "off"):
        return name.strip(), raw.lower() in ("true", "yes", "on")
    if "," in raw:
        return name.strip(), tuple(_number(part.strip()) for part in raw.split(","))
    return name.strip(), _number(raw)


def _number(raw: str) -> object:
    for kind in (int, float):
        try:
            return kind(raw)
        except ValueError:
            continue
    return raw


#: The optics an experiment carries, as recording setup attributes.
OPTICS = ("wavelength_m", "pixel_pitch_m", "n1", "n2")


def _checked_optics(args: argparse.Namespace) -> dict[str, float]:
    """The optics the options give, in SI, checked for plausibility (InputError)."""
    from holoview.optics.setup import check_optics

    optics = optics_in_metres(args)
    check_optics(
        **optics,
        names={
            "wavelength_m": ("--wavelength-nm", 1e-9),
            "pixel_pitch_m": ("--pixel-pitch-um", 1e-6),
            "n1": ("--n1", 1.0),
            "n2": ("--n2" if args.n2 is not None else "--fluid", 1.0),
        },
    )
    return optics


def _experiment(args: argparse.Namespace, optics: dict[str, float]) -> Experiment | None:
    """The experiment to store: the file's with the optics options over it (None: no file)."""
    from holoview.engine.experiment import Experiment

    if args.experiment is None:
        return None
    return Experiment.load(args.experiment).with_optics(optics)


def _check_against_source(source_setup: dict[str, object], setup: dict[str, float]) -> None:
    """Refuse an n1 or n2 option that is not consistent with the source's other index."""
    from holoview.optics.setup import check_optics

    if "n1" not in setup and "n2" not in setup:
        return
    n1, n2 = (setup.get(name, source_setup.get(name)) for name in ("n1", "n2"))
    if isinstance(n1, int | float) and isinstance(n2, int | float):
        names = {n: (f"--{n}" if n in setup else f"the source's {n}", 1.0) for n in ("n1", "n2")}
        check_optics(n1=n1, n2=n2, names=names)


def ring_capacity(ring_mb: float, frame_bytes: int) -> int:
    """Frames a ring of ``ring_mb`` megabytes holds (at least 4), checked against the memory.

    Raises
    ------
    InputError
        ``ring_mb`` is not a positive number, or asks for more than half this
        machine's memory.
    """
    if not (math.isfinite(ring_mb) and ring_mb > 0):
        raise InputError(f"--ring-mb must be a positive number of megabytes, got {ring_mb:g}")
    try:
        memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        memory = None
    capacity = max(4, int(ring_mb * 1e6 // frame_bytes))
    if memory and capacity * frame_bytes > memory / 2:
        raise InputError(
            f"--ring-mb {ring_mb:g} ({capacity} frames) is more than half this machine's "
            f"memory ({memory / 1e9:.1f} GB); give at most {memory / 2e6:.0f}"
        )
    return capacity


def run(args: argparse.Namespace) -> int:
    """Record, show progress, print the summary line.

    Exit status 2 when acquisition failed, 3 when the disk filled or a write failed
    (every frame written is kept and the file is closed), 130 when stopped (Ctrl-C,
    SIGTERM, SIGHUP). A recording that ends with no frame is not kept.
    """
    from holoview.acquire import open_source
    from holoview.acquire.camera_thread import CameraThread
    from holoview.acquire.recorder import Recorder
    from holoview.acquire.ring import FrameRing

    if args.frames is not None and args.frames < 1:
        raise InputError(f"--frames must be at least 1, got {args.frames}")
    if args.seconds is not None and not (math.isfinite(args.seconds) and args.seconds > 0):
        raise InputError(f"--seconds must be positive, got {args.seconds}")
    settings = [parse_setting(text) for text in args.set]
    optics = _checked_optics(args)
    experiment = _experiment(args, optics)
    out = args.out
    if out.exists():
        raise InputError(f"{out} exists; holoview does not overwrite recordings")
    if not out.parent.is_dir():
        raise InputError(f"folder {out.parent} does not exist")

    with open_source(args.source) as source:
        for name, value in settings:
            source.set(name, value)
        _check_against_source(dict(source.setup), optics)
        frame_bytes = source.frame_shape[0] * source.frame_shape[1] * source.dtype.itemsize
        ring = FrameRing(ring_capacity(args.ring_mb, frame_bytes), source.frame_shape, source.dtype)
        setup = optics
        if experiment is not None:
            setup = {k: getattr(experiment, k) for k in OPTICS if getattr(experiment, k)}
        if experiment is not None and source.carried_experiment(0) is not None:
            logger.info("the source's experiment is replaced by %s", args.experiment)
        problem = getattr(source, "experiment_problem", None)
        if experiment is None and problem is not None:
            logger.warning("%s: the copy carries no experiment", problem)
        recorder = Recorder.for_source(
            ring,
            out,
            source,
            setup=setup,
            max_seconds=args.seconds,
            experiment=None if experiment is None else experiment.to_json(),
        )
        camera = CameraThread(source, ring, max_frames=args.frames)
        recorder.start()
        interrupted = False
        try:
            camera.start()
            _follow(camera, recorder, args)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            _finish(camera, ring, recorder, out)
        elapsed = recorder.elapsed_s
    count = recorder.accounting()
    mb = count.recorded * frame_bytes / 1e6
    lost = f", lost {count.lost_to_disk} to the disk" if count.lost_to_disk else ""
    emit(
        f"{out}: acquired {count.acquired}, recorded {count.recorded}, "
        f"dropped {count.dropped} (ring overflow), lost {count.transport_lost} (transport)"
        f"{lost} in {elapsed:.1f} s ({count.acquired / max(elapsed, 1e-9):.1f} frames/s, "
        f"{mb / max(elapsed, 1e-9):.1f} MB/s)"
    )
    if count.recorded == 0:
        out.unlink(missing_ok=True)
        print(f"holoview record: no frame was recorded; {out} is not kept", file=sys.stderr)
    error = recorder.error or camera.error
    if error is not None:
        if isinstance(error, HoloviewError):
            raise error
        raise HoloviewError(f"acquisition failed: {error!r}") from error
    if interrupted:
        print("holoview record: interrupted; the recording is complete up to here", file=sys.stderr)
        return 130
    return 0 if count.recorded else 2


def _finish(camera: CameraThread, ring: FrameRing, recorder: Recorder, out: Path) -> None:
    """Stop the camera, write what the ring holds, close the file; signals wait meanwhile.

    A stop signal while the ring is being written stops that (the frames left are
    counted as lost); the file is closed in any case.
    """
    notice = f"holoview record: closing {out}; press Ctrl-C again to skip the frames still queued"
    with deferred_signals(notice) as received:
        camera.stop()
        if not camera.started:  # else the camera thread closes the ring when it ends
            ring.close()
        while not recorder.join(0.2):
            if received:
                recorder.stop(timeout=0.0, drain=False)


def _follow(camera: CameraThread, recorder: Recorder, args: argparse.Namespace) -> None:
    """Show progress until the camera ends or the recorder stops (5 Hz)."""
    from tqdm import tqdm

    with tqdm(
        total=args.frames,
        unit="frame",
        disable=args.quiet or None,
        file=sys.stderr,
        dynamic_ncols=True,
    ) as bar:
        # poll, not join: Ctrl-C inside Thread.join can mark a running thread stopped
        while camera.running:
            time.sleep(0.2)
            bar.update(recorder.written - bar.n)
            status = recorder.status()
            bar.set_postfix(dropped=status.dropped, lost=status.transport_lost, refresh=False)
            if not recorder.running:  # the time is up, or a write error: stop the camera now
                break
        bar.update(recorder.written - bar.n)
