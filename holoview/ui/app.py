"""Start the Qt application and the main window; stop it however it is stopped.

Ctrl-C, SIGTERM and SIGHUP close the window as its close button does: a recording
in progress is stopped and its file closed, the layout is saved, and the process
exits with status 130 (Python runs signal handlers only when the interpreter has
control, so a timer hands it control five times a second). Before the event loop
runs (the window being built), the command's own handlers stop it as they stop any
command (:mod:`holoview.cli.signals`).

A display that goes away (the X server or Wayland compositor ends, an SSH connection
carrying X drops) makes Qt print a warning and end the process at once, with the
window's threads still running (seen: a worker's traceback, and a recording's file
left open). Qt's messages pass through :func:`stop_on_lost_display`, which on that
warning stops what the window runs (:meth:`MainWindow.shut_down`: the recording's
file closed, the threads joined), prints one line and exits with status 130, as a
closed terminal (SIGHUP) would.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
from collections.abc import Iterator
from pathlib import Path
from types import FrameType

from PyQt6.QtCore import QMessageLogContext, QTimer, QtMsgType, qInstallMessageHandler
from PyQt6.QtWidgets import QApplication

from holoview.ui.garbage import collect_between_events
from holoview.ui.main_window import MainWindow

logger = logging.getLogger(__name__)

#: Milliseconds between two looks at whether the window's source is still opening.
OPENING_POLL_MS = 50

#: Exit status of a window stopped by a signal or by the loss of its display.
STOPPED_STATUS = 130

#: The starts of the warnings Qt prints just before it ends a process whose display is gone.
LOST_DISPLAY_WARNINGS = ("The X11 connection broke", "The Wayland connection broke")


def application() -> QApplication:
    """Return the running QApplication, creating it (named ``holoview``) if needed."""
    app = QApplication.instance()
    if not isinstance(app, QApplication):
        app = QApplication(["holoview"])
    app.setOrganizationName("holoview")
    app.setApplicationName("holoview")
    return app


#: How often (ms) the event loop hands control to Python, so that signals are handled.
SIGNAL_POLL_MS = 200


@contextlib.contextmanager
def close_on_signals(window: MainWindow) -> Iterator[list[int]]:
    """Within the block, SIGINT, SIGTERM and SIGHUP close ``window`` (not ignored ones).

    Yields the list of the signals received (empty while none came).
    """
    received: list[int] = []

    def close(signum: int, frame: FrameType | None) -> None:
        logger.warning("%s: closing the window", signal.Signals(signum).name)
        received.append(signum)
        QTimer.singleShot(0, window.close)

    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            previous[sig] = signal.signal(sig, close)
    poll = QTimer(window)
    poll.timeout.connect(lambda: None)
    poll.start(SIGNAL_POLL_MS)
    try:
        yield received
    finally:
        poll.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def stop_on_lost_display(windows: list[MainWindow]) -> Iterator[None]:
    """Within the block, the loss of the display stops the ``windows`` and the process.

    Every other message of Qt's is printed on stderr as Qt prints it (or handed to the
    handler installed before).
    """

    def handle(kind: QtMsgType, context: QMessageLogContext, message: str | None) -> None:
        text = message or ""
        if text.startswith(LOST_DISPLAY_WARNINGS):
            for window in windows:
                window.shut_down()
            logger.error(
                "the display is gone (%s); the window's work was stopped and its files closed",
                text.strip(),
            )
            sys.stdout.flush()
            os._exit(STOPPED_STATUS)  # Qt ends the process as this returns: end it first
        if previous is not None:
            previous(kind, context, message)
        else:  # as Qt's own handler does
            sys.stderr.write(text + "\n")
            sys.stderr.flush()

    previous = qInstallMessageHandler(handle)
    try:
        yield
    finally:
        qInstallMessageHandler(previous)


def close_after_opening(window: MainWindow, seconds: float) -> None:
    """Close ``window`` ``seconds`` after its source has opened (or failed to open).

    Opening a source runs on a thread and may take seconds on a loaded machine: counted
    from the window's start, a short ``--quit-after`` could close it before its source
    ever ran.
    """

    def arm() -> None:
        if window.opening:
            QTimer.singleShot(OPENING_POLL_MS, arm)
        else:
            QTimer.singleShot(int(seconds * 1000), window.close)

    QTimer.singleShot(0, arm)


def run_live(
    source: str = "sim",
    quit_after: float | None = None,
    experiment: Path | None = None,
    optics: dict[str, float] | None = None,
    open_path: Path | None = None,
) -> int:
    """Open the main window on ``source`` and run the event loop.

    Parameters
    ----------
    source : str
        Source specification (``sim``, ``aravis[:ID]``, ``v4l2[:N]``, ``replay:PATH``).
    quit_after : float, optional
        Close the window this many seconds after its source has opened.
    experiment : Path, optional
        Experiment file to use (and keep up to date) instead of the default.
    optics : dict, optional
        ``wavelength_m``, ``pixel_pitch_m``, ``n1``, ``n2`` to use over the experiment's.
    open_path : Path, optional
        A file to open as File > Open does, instead of starting ``source``.

    Returns
    -------
    int
        The exit status of the event loop; :data:`STOPPED_STATUS` when a stop signal
        closed the window.

    Raises
    ------
    KeyboardInterrupt
        An interrupt (or a stop signal turned into one) before the event loop ran: the
        window built so far is closed first.
    """
    app = application()
    windows: list[MainWindow] = []
    with stop_on_lost_display(windows):
        try:
            window = MainWindow(
                source=source,
                autostart=open_path is None,
                experiment_path=experiment,
                optics=optics,
            )
            windows.append(window)
            window.show()
            if open_path is not None:
                window.open_file(open_path)
            if quit_after is not None:
                close_after_opening(window, quit_after)
            logger.info("main window open on source %s", source)
            with close_on_signals(window) as received, collect_between_events(app):
                status = app.exec()
        except KeyboardInterrupt:
            for built in windows:
                built.close()
            raise
    return STOPPED_STATUS if received else status
