"""Run slow calls (opening a camera, looking for cameras, measuring a run) off the GUI thread.

The call runs on a thread of its own; a QTimer on the GUI thread polls it and emits
:attr:`BackgroundCall.done` with what it returned, so the window never waits and no
signal crosses threads. A call that raises is logged with its traceback and delivered
as the exception. :class:`BackgroundCall` runs one call at a time and refuses another
meanwhile; :class:`LatestCall` gives a running call up for a newer one (a run measured
again with new labels).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from PyQt6.QtCore import QObject, QTimer, pyqtSignal

from holoview.errors import HoloviewError
from holoview.live.side_workers import yield_to_others

logger = logging.getLogger(__name__)


class BackgroundCall(QObject):
    """One call at a time on a thread named ``thread_name``; the result comes back as a signal.

    Parameters
    ----------
    thread_name : str
        Name of the thread (``holoview-...``, so tests see any that outlives them).
    timer_name : str
        Object name of the polling timer.
    parent : QObject
        The owner (the main window).
    poll_ms : int
        How often the timer looks, milliseconds.

    Signals
    -------
    done(object)
        The call's return value, or the exception it raised.
    """

    done = pyqtSignal(object)

    def __init__(self, thread_name: str, timer_name: str, parent: QObject, poll_ms: int = 20):
        super().__init__(parent)
        self.thread_name = thread_name
        self.timer = QTimer(self)
        self.timer.setObjectName(timer_name)
        self.timer.setInterval(poll_ms)
        self.timer.timeout.connect(self._poll)
        self._thread: threading.Thread | None = None
        self._outcome: list[object] = []

    @property
    def busy(self) -> bool:
        """True from :meth:`start` until :attr:`done` is emitted."""
        return self._thread is not None

    def start(self, function: Callable[[], object]) -> bool:
        """Call ``function`` on the thread; False (and nothing done) while a call is busy."""
        if self._thread is not None:
            return False
        outcome: list[object] = []

        def run() -> None:
            try:
                outcome.append(function())
            except Exception as exc:  # a bug: keep the traceback in the log, the window running
                logger.exception("%s failed", self.thread_name)
                outcome.append(exc)

        self._outcome = outcome
        self._thread = threading.Thread(target=run, name=self.thread_name, daemon=True)
        self._thread.start()
        self.timer.start()
        return True

    def wait(self) -> object | None:
        """Join a busy call without emitting :attr:`done`; return its outcome (window closing)."""
        self.timer.stop()
        if self._thread is None:
            return None
        self._thread.join()
        self._thread = None
        return self._outcome[0] if self._outcome else None

    def _poll(self) -> None:
        if self._thread is None or self._thread.is_alive():
            return
        self.done.emit(self.wait())


#: A call :class:`LatestCall` runs: given ``progress(done, total)`` and ``cancelled()``.
Job = Callable[[Callable[[int, int], None], Callable[[], bool]], object]


class _Run:
    """One call of a :class:`LatestCall`: its thread, its give-up flag, its progress."""

    def __init__(self, job: Job, thread_name: str, niceness: int) -> None:
        self.cancel = threading.Event()
        self.progress: tuple[int, int] | None = None
        self.outcome: list[object] = []

        def report(done: int, total: int) -> None:
            self.progress = (done, total)

        def run() -> None:
            if niceness:
                yield_to_others(niceness)
            try:
                self.outcome.append(job(report, self.cancel.is_set))
            except Exception as exc:  # delivered; a HoloviewError is the user's to read
                if not isinstance(exc, HoloviewError):
                    logger.exception("%s failed", thread_name)
                self.outcome.append(exc)

        self.thread = threading.Thread(target=run, name=thread_name, daemon=True)
        self.thread.start()


class LatestCall(QObject):
    """Long calls on a thread where only the newest matters (a measurement redone).

    :meth:`start` while a call runs asks that call to give up (its ``cancelled()``
    turns True) and runs the new one when it has; only the newest call's outcome is
    emitted. :meth:`progress` reads how far the running call is.

    Parameters
    ----------
    thread_name : str
        Name of the threads (``holoview-...``).
    timer_name : str
        Object name of the polling timer.
    parent : QObject
        The owner.
    poll_ms : int
        How often the timer looks, milliseconds.
    niceness : int
        Added to the threads' scheduling niceness (Linux): a long measurement leaves the
        cores to the window and the live workers first.

    Signals
    -------
    done(object)
        The newest call's return value, or the exception it raised.
    """

    done = pyqtSignal(object)

    def __init__(
        self,
        thread_name: str,
        timer_name: str,
        parent: QObject,
        poll_ms: int = 50,
        niceness: int = 0,
    ):
        super().__init__(parent)
        self.niceness = niceness
        self.thread_name = thread_name
        self.timer = QTimer(self)
        self.timer.setObjectName(timer_name)
        self.timer.setInterval(poll_ms)
        self.timer.timeout.connect(self._poll)
        self._run: _Run | None = None
        self._next: Job | None = None

    @property
    def busy(self) -> bool:
        """True from :meth:`start` until the newest call's outcome is emitted."""
        return self._run is not None or self._next is not None

    def progress(self) -> tuple[int, int] | None:
        """``(done, total)`` of the running call as it last said (None before it says)."""
        if self._next is not None or self._run is None:
            return None
        return self._run.progress

    def start(self, job: Job) -> None:
        """Run ``job(progress, cancelled)`` on the thread, after the running call gives up."""
        if self._run is not None:
            self._run.cancel.set()
            self._next = job
        else:
            self._run = _Run(job, self.thread_name, self.niceness)
        self.timer.start()

    def cancel(self) -> None:
        """Give up the running call and the one waiting; nothing more is emitted."""
        self._next = None
        if self._run is not None:
            self._run.cancel.set()

    def wait(self) -> None:
        """Give every call up and join the thread (the window closing)."""
        self.cancel()
        self.timer.stop()
        if self._run is not None:
            self._run.thread.join()
            self._run = None

    def _poll(self) -> None:
        run = self._run
        if run is None or run.thread.is_alive():
            return
        self._run = None
        if self._next is not None:
            job, self._next = self._next, None
            self._run = _Run(job, self.thread_name, self.niceness)
            return
        self.timer.stop()
        if not run.cancel.is_set():
            self.done.emit(run.outcome[0] if run.outcome else None)
