"""Side work in a process of its own, so that it never holds the maps' interpreter lock.

A side thread (:class:`~holoview.live.side_workers.SideWorker`) keeps slow work off the maps
worker's frames, but not off the interpreter's lock: matching the windows to the surface
at 1024^2 with six peaks is 0.6 s of CPU in some 56,000 Python calls, and while it runs
every other thread of the window (the maps, the series, the painting) waits its turn for
the lock again and again. Measured with ``benchmarks/bench_gui.py`` (2 cores, AVX2, load
1-2): with the match on a thread, 4.3 maps/s, the camera view at 14.5 Hz and event-loop
stalls up to 0.66 s; without it, 9.1 maps/s and 22.8 Hz.

:class:`ChildWork` is a callable for such a thread: each call sends the job to a child
process (started at the first call, ``spawn``: nothing of the window's threads or Qt in
it), which runs the work there at a lower priority and sends the result back; the
calling thread waits without the lock. The work's state (the matcher's frames) lives in
the child. Errors come back as the thread's would: a
:class:`~holoview.errors.HoloviewError` as such, anything else as a bug with the child's
traceback. The child plans its FFTs from the window's wisdom (the same transforms, so the
same numbers to the bit as on a thread). A child that ended (killed, out of memory) is
said once and started again at the next job; :meth:`ChildWork.close` ends it. The child
ends by itself when the window's process is gone (its end of the pipe closes) and
ignores the terminal's Ctrl-C (the window handles it).
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import signal
import threading
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any, Generic, NoReturn, TypeVar

from holoview.errors import HoloviewError
from holoview.processing.fourier.fftplans import adopt_wisdom, current_wisdom

logger = logging.getLogger(__name__)

__all__ = ["ChildWork"]

#: The type of the jobs and of their results.
J = TypeVar("J")
T = TypeVar("T")

#: Seconds :meth:`ChildWork.close` waits for the child to end before it is killed.
CLOSE_WAIT_S = 0.5


@dataclass(frozen=True)
class _Setup:
    """How a child sets itself up: its name, niceness and process group.

    ``group``: lead a process group of its own, so that the processes it starts end with
    it when it must be killed (:meth:`ChildWork.close`).
    """

    name: str
    niceness: int
    group: bool


def _serve(conn: Connection, make: Callable[[], Callable[[Any], Any]], setup: _Setup) -> None:
    """The child: take the parent's FFT wisdom (the first message: planned from alone, its
    transforms give the parent's numbers to the bit), make the work, then run each job
    received until ``None`` or the pipe ends."""
    name, niceness = setup.name, setup.niceness
    if setup.group:
        with contextlib.suppress(OSError):
            os.setpgrp()
    try:
        wisdom = conn.recv()
    except (EOFError, OSError):  # the window's process is gone
        return
    adopt_wisdom(wisdom)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with contextlib.suppress(OSError):  # its name in top and ps (Linux: 15 characters)
        Path("/proc/self/comm").write_text(name[:15])
    with contextlib.suppress(OSError):  # a sandbox that forbids it: the same priority
        os.nice(niceness)
    work = make()
    try:
        conn.send(("ready", None))
    except (EOFError, OSError):
        return
    while True:
        try:
            job = conn.recv()
        except Exception:  # the window's process is gone (or its pipe broke)
            return
        if job is None:
            return
        try:
            reply: tuple[str, Any] = ("done", work(job))
        except HoloviewError as exc:
            reply = ("input", str(exc))
        except Exception:  # a bug: its traceback goes to the window's log
            reply = ("bug", traceback.format_exc())
        try:
            conn.send(reply)
        except (EOFError, OSError):
            return


class ChildWork(Generic[J, T]):
    """Run ``make()``'s work on each job in a child process; call it from one thread.

    Parameters
    ----------
    make : callable
        Called once in the child (a module-level function: it is pickled): returns the
        work, a callable taking a job and returning its result. Jobs and results are
        pickled across.
    name : str
        The child's name (``holoview-...``), for its process title and the messages.
    niceness : int
        Added to the child's niceness at its start.
    daemon : bool
        A daemonic child (ended by the window's process at exit) may start no process of
        its own; one that does (the maps process: its match) is not daemonic and must be
        ended by :meth:`close` (the live workers' stop, at the latest at the
        interpreter's exit). It leads a process group of its own: killed, it is killed
        with the processes it started (one still starting would outlive it).
    """

    def __init__(
        self,
        make: Callable[[], Callable[[J], T]],
        name: str,
        niceness: int,
        daemon: bool = True,
    ) -> None:
        self._make = make
        self._name = name
        self._niceness = niceness
        self._daemon = daemon
        self._lock = threading.Lock()
        self._sending = threading.Lock()  # one message at a time on the pipe
        self._process: multiprocessing.process.BaseProcess | None = None
        self._conn: Connection | None = None
        self._starting = False  # the child's "ready" not read yet
        self._closed = False

    @property
    def pid(self) -> int | None:
        """The child's process id (None before the first job and after it ended)."""
        with self._lock:
            return None if self._process is None else self._process.pid

    def __call__(self, job: J) -> T:
        """Run ``job`` in the child; wait for its result without the interpreter's lock.

        Raises
        ------
        HoloviewError
            The work's own, or the child ended (it starts again at the next job) or was
            closed.
        RuntimeError
            A bug in the work, with the child's traceback.
        """
        self.submit(job)
        return self.result()

    def start(self) -> None:
        """Start the child now rather than at the first job (it takes a second or two)."""
        self._connection()

    def wait_ready(self, timeout: float) -> bool:
        """Wait up to ``timeout`` s for the child to have made its work; whether it has.

        Raises
        ------
        HoloviewError
            The child ended (it failed to start) or was closed.
        """
        with self._lock:
            conn, starting = self._conn, self._starting
        if conn is None:
            raise HoloviewError(
                f"{self._name} was stopped" if self._closed else f"{self._name} has no process"
            )
        if not starting:
            return True
        try:
            if not conn.poll(timeout):
                return False
        except Exception as exc:
            self._failed(exc)
        self._read_ready(conn)
        return True

    def _read_ready(self, conn: Connection) -> None:
        """Read the child's "ready" (the first message of each child)."""
        try:
            kind, _ = conn.recv()
        except Exception as exc:
            self._failed(exc)
        with self._lock:
            self._starting = False
        if kind != "ready":  # pragma: no cover - the protocol says otherwise
            raise RuntimeError(f"{self._name} said {kind!r} before it was ready")

    def submit(self, job: J) -> None:
        """Send ``job`` to the child (started if need be) and return at once.

        The child runs the jobs in the order sent; :meth:`result` gives their results in
        that order, one per job. A caller may keep a job running while it prepares the
        next (the window's process and the child then work at the same time).

        Raises
        ------
        HoloviewError
            The child ended (it starts again at the next job) or was closed.
        """
        conn = self._connection()
        try:
            with self._sending:
                conn.send(job)
        except Exception as exc:
            self._failed(exc)

    def result(self) -> T:
        """The result of the oldest job sent and not yet answered; waits without the lock.

        Raises
        ------
        HoloviewError
            The work's own, or the child ended (with every job sent to it: it starts again
            at the next job) or was closed.
        RuntimeError
            A bug in the work, with the child's traceback.
        """
        with self._lock:
            conn, starting = self._conn, self._starting
        if conn is None:
            raise HoloviewError(
                f"{self._name} was stopped" if self._closed else f"{self._name} has no job"
            )
        if starting:
            self._read_ready(conn)
        try:
            kind, value = conn.recv()
        except Exception as exc:
            self._failed(exc)
        if kind == "done":
            return value  # type: ignore[no-any-return]
        if kind == "input":
            raise HoloviewError(value)
        raise RuntimeError(f"{self._name} failed in its process:\n{value}")

    def _failed(self, exc: Exception) -> NoReturn:
        """Raise what a broken exchange with the child means for the caller."""
        # closed from another thread mid-call: the pipe's end may be gone under it
        # (any error then, a TypeError from a closed handle among them)
        if self._closed:
            raise HoloviewError(f"{self._name} was stopped") from exc
        if not isinstance(exc, (EOFError, OSError)):
            raise exc
        code = self._forget()
        raise HoloviewError(
            f"{self._name}'s process ended (exit code {code}); it starts again at the next job"
        ) from exc

    def close(self) -> None:
        """End the child (a job under way is abandoned: its call raises); no more jobs."""
        with self._lock:
            self._closed = True
            process, conn = self._process, self._conn
        if process is None:
            return
        # the message to stop goes after a job being sent, never inside it (a pipe
        # interleaves two writers' large writes); a child that reads nothing is killed
        if conn is not None and self._sending.acquire(timeout=CLOSE_WAIT_S):
            try:
                with contextlib.suppress(OSError):
                    conn.send(None)
            finally:
                self._sending.release()
        process.join(CLOSE_WAIT_S)
        if process.is_alive():
            self._kill(process)
            process.join(CLOSE_WAIT_S)
        self._forget()

    def _kill(self, process: multiprocessing.process.BaseProcess) -> None:
        """Kill the child (and its process group, where it leads one)."""
        if not self._daemon and process.pid is not None:
            with contextlib.suppress(OSError):  # gone meanwhile, or not its group yet
                if os.getpgid(process.pid) == process.pid:
                    os.killpg(process.pid, signal.SIGKILL)
                    return
        process.kill()

    def _connection(self) -> Connection:
        with self._lock:
            if self._closed:
                raise HoloviewError(f"{self._name} was stopped")
            if self._process is not None and self._conn is not None:
                return self._conn
            context = multiprocessing.get_context("spawn")
            ours, theirs = context.Pipe()
            process = context.Process(
                target=_serve,
                args=(theirs, self._make, _Setup(self._name, self._niceness, not self._daemon)),
                name=self._name,
                daemon=self._daemon,
            )
            process.start()
            theirs.close()
            self._process, self._conn, self._starting = process, ours, True
            # The wisdom (75 KB) is more than a pipe holds, and the child reads only once
            # it has started Python and imported the window's main module: written here,
            # the caller (the window's thread, opening the Waves panel) waited for that,
            # 0.25-1.3 s. A thread sends it; the jobs go after it.
            self._sending.acquire()
            threading.Thread(
                target=self._send_wisdom,
                args=(ours, current_wisdom()),
                name=f"{self._name}-start",
                daemon=True,
            ).start()
            logger.debug("%s started in process %d", self._name, process.pid)
            return ours

    def _send_wisdom(self, conn: Connection, wisdom: tuple[bytes, ...]) -> None:
        """Send the child its first message, the FFT wisdom; then let the jobs through.

        A child that ended meanwhile is said by the next exchange with it.
        """
        try:
            conn.send(wisdom)
        except (OSError, TypeError, ValueError):  # ended, or its pipe closed under us
            pass
        finally:
            self._sending.release()

    def _forget(self) -> int | None:
        """Drop the child (ended or ending); its exit code where known."""
        with self._lock:
            process, conn = self._process, self._conn
            self._process = self._conn = None
        if conn is not None:
            conn.close()
        if process is None:
            return None
        process.join(CLOSE_WAIT_S)
        return process.exitcode
