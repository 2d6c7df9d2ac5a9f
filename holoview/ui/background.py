"""Run a slow call (opening a camera, looking for cameras) off the GUI thread.

The call runs on a thread of its own; a QTimer on the GUI thread polls it and emits
:attr:`BackgroundCall.done` with what it returned, so the window never waits and no
signal crosses threads. A call that raises is logged with its traceback and delivered
as the exception.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from PyQt6.QtCore import QObject, QTimer, pyqtSignal

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
