"""Start the Qt application and the main window.

Ctrl-C, SIGTERM and SIGHUP close the window as its close button does: a recording
in progress is stopped and its file closed, the layout is saved, and the process
exits with status 0. (Python runs signal handlers only when the interpreter has
control, so a timer hands it control five times a second.)
"""

from __future__ import annotations

import contextlib
import logging
import signal
from collections.abc import Iterator
from pathlib import Path
from types import FrameType

from PyQt6.QtCore import QTimer
from PyQt6.QtWidgets import QApplication, QWidget

from holoview.ui.main_window import MainWindow

logger = logging.getLogger(__name__)


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
def close_on_signals(window: QWidget) -> Iterator[None]:
    """Within the block, SIGINT, SIGTERM and SIGHUP close ``window`` (not ignored ones)."""

    def close(signum: int, frame: FrameType | None) -> None:
        logger.warning("%s: closing the window", signal.Signals(signum).name)
        QTimer.singleShot(0, window.close)

    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            previous[sig] = signal.signal(sig, close)
    poll = QTimer(window)
    poll.timeout.connect(lambda: None)
    poll.start(SIGNAL_POLL_MS)
    try:
        yield
    finally:
        poll.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


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
        Close the window after this many seconds.
    experiment : Path, optional
        Experiment file to use (and keep up to date) instead of the default.
    optics : dict, optional
        ``wavelength_m``, ``pixel_pitch_m``, ``n1``, ``n2`` to use over the experiment's.
    open_path : Path, optional
        A file to open as File > Open does, instead of starting ``source``.

    Returns
    -------
    int
        The exit status of the event loop.
    """
    app = application()
    window = MainWindow(
        source=source, autostart=open_path is None, experiment_path=experiment, optics=optics
    )
    window.show()
    if open_path is not None:
        window.open_file(open_path)
    if quit_after is not None:
        QTimer.singleShot(int(quit_after * 1000), window.close)
    logger.info("main window open on source %s", source)
    with close_on_signals(window):
        return app.exec()
