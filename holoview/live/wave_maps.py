"""The Waves panel's map of each frame, made in a child process beside the live window.

A map costs about 5-7 ms of one core at 1024 x 1024 (the frame's row FFTs, the column
FFTs under one window, one box's inverse FFT, the carrier probe; see
``benchmarks/bench_wave_map.py``), well under a 60 frames/s camera's 16.7 ms. Made on a
thread of the live window's process it took 4-5 times that: its FFTs and array steps
release the GIL some sixty times a map, and each time the map waits to take it back
from the GUI, the maps worker and the series worker (measured beside one busy Python
thread on two cores: 5.5 ms alone, 25 ms beside it). :class:`MapProcess` makes the maps
in a child process (``holoview-waves-maps``) with its own interpreter: the waves worker's
thread copies the frame into a shared buffer, sends a few bytes and waits for the map,
taking the GIL a handful of times a frame.

:class:`WaveMapper` is the map itself, the same wherever it runs: the engine's per-frame
core (:class:`~holoview.engine.frame_core.FrameCore` and
:class:`~holoview.engine.map_step.MapStep`) for the chosen peaks and settings, so the
Waves panel's map of a frame is the engine's map of that frame (the child computes
exactly what the thread would, with the same demodulator state carried from frame to
frame). :class:`MapProcess` with ``child=False`` runs it on the calling thread.

A child that ends (killed, or a bug) is said once (:class:`MapProcessError`) and started
again for the next frame: its demodulator is new, so the panel's window starts again.
"""

from __future__ import annotations

import contextlib
import logging
import math
import mmap
import multiprocessing
import os
import signal
import tempfile
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import numpy as np

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FrameCore
from holoview.engine.map_step import MapStep
from holoview.errors import HoloviewError, InputError
from holoview.processing.peaks.detection import Peak

logger = logging.getLogger(__name__)

__all__ = ["START_TIMEOUT_S", "MapProcess", "MapProcessError", "WaveMap", "WaveMapper"]

#: Seconds a child may take to start (import holoview, open the shared buffer).
START_TIMEOUT_S = 60.0
#: Seconds between two looks at the child while waiting for its answer.
POLL_S = 0.5


class MapProcessError(HoloviewError):
    """The child process making the maps ended or could not start (it is started again)."""


@dataclass(frozen=True)
class WaveMap:
    """One frame's chosen map and what the window needs to know about it.

    Attributes
    ----------
    height : ndarray of float32
        The map (m, NaN where untrusted), on the demodulation box's grid.
    pixel_size : (float, float) or None
        The map's pixel size (rows, cols), m; None without a pixel pitch.
    k_cut : float
        The window's cut-off, rad/m (inf without a pixel pitch).
    rebuilt : bool
        A new demodulator made it (its reference starts anew; its first map also
        planned the FFTs).
    relative : bool
        The map is the step since the previous frame's (relative reference).
    cpu_s : float
        CPU time the map took on the thread that made it, s.
    """

    height: np.ndarray
    pixel_size: tuple[float, float] | None
    k_cut: float
    rebuilt: bool
    relative: bool
    cpu_s: float


class WaveMapper:
    """Make the chosen map of frame after frame with the engine's per-frame core.

    Parameters
    ----------
    frame_shape : (int, int)
        Frames' ``(rows, cols)``, pixels.
    saturation : float, optional
        Raw value at which the camera saturates.
    """

    def __init__(self, frame_shape: tuple[int, int], saturation: float | None = None) -> None:
        self.frame_shape = (int(frame_shape[0]), int(frame_shape[1]))
        self.saturation = saturation
        self._core: FrameCore | None = None
        self._step: MapStep | None = None

    def break_sequence(self) -> None:
        """The next frame does not follow the previous one: no map pairs them."""
        if self._core is not None:
            self._core.break_sequence()

    def map(
        self,
        pixels: np.ndarray,
        chosen: Sequence[Peak],
        experiment: Experiment,
        *,
        label: str,
        fused: bool,
        estimate: bool,
    ) -> WaveMap:
        """The map ``label`` of a frame (not modified): one peak's or the fused map of ``chosen``.

        Raises
        ------
        InputError
            No map from this frame, or peaks and settings that cannot work.
        """
        tick = time.thread_time()
        if self._core is None or self._step is None:
            self._core = FrameCore(self.frame_shape, experiment, chosen, saturation=self.saturation)
            self._step = MapStep(self._core)
        core = self._core
        core.configure(experiment, chosen)
        before = core.demodulator
        maps = self._step.process(pixels, estimate=estimate, fuse=fused)
        demod = maps.result
        if demod is None or not maps.maps:
            raise InputError(f"no map of {label} from this frame ({', '.join(maps.flags)})")
        height = maps.fused if fused else maps.maps[0]
        if height is None:
            raise InputError("no fused map: fewer than two peaks give a height on this frame")
        rows, cols = self.frame_shape
        by, bx = demod.box_shape
        pitch = experiment.pixel_pitch_m
        pixel_size = None if pitch is None else (pitch * rows / by, pitch * cols / bx)
        demodulator = core.demodulator
        radius = demod.radius if demodulator is None else min(demodulator.radii)
        k_cut = math.inf if pitch is None else 2.0 * math.pi * radius / pitch
        return WaveMap(
            height=height,
            pixel_size=pixel_size,
            k_cut=k_cut,
            rebuilt=demodulator is not before,
            relative=core.experiment.reference == "relative",
            cpu_s=time.thread_time() - tick,
        )


def _shared_folder() -> str | None:
    """A memory-backed folder for the frame buffer where there is one (Linux), else the default."""
    return "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None


def _serve(
    conn: Connection,
    path: str,
    shape: tuple[int, int],
    dtype: str,
    saturation: float | None,
) -> None:
    """The child: map the frame in the shared buffer each time it is asked, until told to end."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent ends it
    with open(path, "r+b") as f:
        buffer = mmap.mmap(f.fileno(), 0)
    frame: np.ndarray = np.ndarray(shape, np.dtype(dtype), buffer=buffer)
    mapper = WaveMapper(shape, saturation)
    conn.send(("ready", os.getpid()))
    chosen: Sequence[Peak] = ()
    experiment = Experiment()
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):  # the parent ended
            return
        if message is None:
            return
        kind = message[0]
        if kind == "settings":
            chosen, experiment = message[1], message[2]
            continue
        if kind == "break":
            mapper.break_sequence()
            continue
        _, label, fused, estimate = message
        try:
            answer: tuple[Any, ...] = (
                "map",
                mapper.map(frame, chosen, experiment, label=label, fused=fused, estimate=estimate),
            )
        except HoloviewError as exc:
            answer = ("error", str(exc))
        except Exception:  # a bug: its traceback goes to the parent's log
            answer = ("bug", traceback.format_exc())
        conn.send(answer)


class MapProcess:
    """Make the Waves panel's maps in a child process (module docstring), one frame at a time.

    Parameters
    ----------
    frame_shape : (int, int)
        Frames' ``(rows, cols)``, pixels.
    saturation : float, optional
        Raw value at which the camera saturates.
    child : bool
        Make the maps in a child process (default); False: on the calling thread.

    Notes
    -----
    Use it from one thread. The child starts with :meth:`launch` or the first frame (its
    dtype sizes the shared buffer) and takes a second or two to import holoview, which
    the first map waits for.
    """

    def __init__(
        self,
        frame_shape: tuple[int, int],
        saturation: float | None = None,
        *,
        child: bool = True,
    ) -> None:
        self.frame_shape = (int(frame_shape[0]), int(frame_shape[1]))
        self.saturation = saturation
        self.child = child
        self._local = WaveMapper(self.frame_shape, saturation) if not child else None
        self._process: Any = None  # multiprocessing's process, while a child runs
        self._conn: Connection | None = None
        self._buffer: mmap.mmap | None = None
        self._frame: np.ndarray | None = None
        self._sent: tuple[tuple[Peak, ...], Experiment] | None = None
        self._broken = False
        self._ready = False
        self._path = ""
        #: the child's process id (None: none running)
        self.pid: int | None = None

    # ---- the child's life ---------------------------------------------------------
    def launch(self, dtype: np.typing.DTypeLike) -> None:
        """Start the child for frames of ``dtype`` without waiting for it (nothing if one runs).

        The child imports holoview meanwhile; the first :meth:`map` waits for it.

        Raises
        ------
        MapProcessError
            The system would not start it.
        """
        if self._local is not None or self._process is not None:
            return
        try:
            self._launch(np.dtype(dtype))
        except OSError as exc:  # no shared memory, no process left
            self.close()
            raise MapProcessError(f"the waves map process cannot start: {exc}") from exc

    def _launch(self, dtype: np.dtype) -> None:
        nbytes = self.frame_shape[0] * self.frame_shape[1] * dtype.itemsize
        fd, path = tempfile.mkstemp(prefix="holoview-waves-", dir=_shared_folder())
        self._path = path  # close() removes it
        try:
            os.ftruncate(fd, nbytes)
            self._buffer = mmap.mmap(fd, nbytes)
        finally:
            os.close(fd)
        self._frame = np.ndarray(self.frame_shape, dtype, buffer=self._buffer)
        context = multiprocessing.get_context("spawn")  # no fork of a threaded (Qt) process
        ours, theirs = context.Pipe()
        process = context.Process(
            target=_serve,
            args=(theirs, path, self.frame_shape, dtype.str, self.saturation),
            name="holoview-waves-maps",
            daemon=True,
        )
        try:
            process.start()
        finally:
            theirs.close()
        self._process, self._conn = process, ours
        self.pid = process.pid
        self._sent = None
        self._ready = False
        self._broken = False  # a new demodulator: nothing to break

    def _wait_ready(self) -> None:
        """Wait for the launched child's first word (it has mapped the shared buffer)."""
        try:
            answer = self._receive(START_TIMEOUT_S)
        finally:
            Path(self._path).unlink(missing_ok=True)  # both map it now: nothing left on disk
        if answer[0] != "ready":
            self.close()
            raise MapProcessError(f"the waves map process did not start: {answer!r}")
        self._ready = True
        logger.info("waves: maps made in process %d", self.pid)

    def _receive(self, timeout: float | None = None) -> tuple[Any, ...]:
        """The child's next message; MapProcessError (and the child ended) when it is gone."""
        conn, process = self._conn, self._process
        assert conn is not None and process is not None
        deadline = None if timeout is None else time.monotonic() + timeout
        try:
            while not conn.poll(POLL_S):
                late = deadline is not None and time.monotonic() > deadline
                if late or not process.is_alive():
                    break
            else:
                message: tuple[Any, ...] = conn.recv()
                return message
        except (EOFError, OSError):
            pass
        code = process.exitcode
        self.close()
        raise MapProcessError(
            "the waves map process ended"
            + ("" if code is None else f" (exit status {code})")
            + "; it starts again with the next frame and the window with it"
        )

    def close(self) -> None:
        """End the child (if any) and free the shared buffer."""
        conn, process = self._conn, self._process
        self._conn = self._process = None
        self.pid = None
        self._ready = False
        if self._path:
            Path(self._path).unlink(missing_ok=True)
            self._path = ""
        if conn is not None:
            with contextlib.suppress(OSError):  # a child that ended has closed its end
                conn.send(None)
            conn.close()
        if process is not None:
            process.join(5.0)
            if process.is_alive():
                process.kill()
                process.join(5.0)
        self._frame = None
        if self._buffer is not None:
            self._buffer.close()
            self._buffer = None

    # ---- the maps -------------------------------------------------------------------
    def break_sequence(self) -> None:
        """The next frame does not follow the previous one: no map pairs them."""
        if self._local is not None:
            self._local.break_sequence()
        else:
            self._broken = True

    def map(
        self,
        pixels: np.ndarray,
        chosen: Sequence[Peak],
        experiment: Experiment,
        *,
        label: str,
        fused: bool,
        estimate: bool,
    ) -> WaveMap:
        """:meth:`WaveMapper.map` of one frame, in the child (started if needed).

        Raises
        ------
        InputError
            No map from this frame, or peaks and settings that cannot work.
        MapProcessError
            The child ended or could not start (said once; the next frame starts one).
        """
        if self._local is not None:
            return self._local.map(
                pixels, chosen, experiment, label=label, fused=fused, estimate=estimate
            )
        pixels = np.asarray(pixels)
        if self._process is None:
            self.launch(pixels.dtype)
        if not self._ready:
            self._wait_ready()
        conn, frame = self._conn, self._frame
        assert conn is not None and frame is not None
        np.copyto(frame, pixels, casting="unsafe")
        settings = (tuple(chosen), experiment)
        if settings != self._sent:
            conn.send(("settings", *settings))
            self._sent = settings
        if self._broken:
            conn.send(("break",))
            self._broken = False
        conn.send(("map", label, fused, estimate))
        answer = self._receive()
        if answer[0] == "map":
            result: WaveMap = answer[1]
            return result
        if answer[0] == "error":
            raise InputError(answer[1])
        logger.error("waves map process: internal error\n%s", answer[1])
        raise MapProcessError("the waves map failed (an internal error; see the log)")
