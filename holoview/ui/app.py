"""Start the Qt application and the main window."""

from __future__ import annotations

import logging
from pathlib import Path

from PyQt6.QtCore import QTimer
from PyQt6.QtWidgets import QApplication

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


def run_live(
    source: str = "sim",
    quit_after: float | None = None,
    experiment: Path | None = None,
    optics: dict[str, float] | None = None,
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

    Returns
    -------
    int
        The exit status of the event loop.
    """
    app = application()
    window = MainWindow(source=source, experiment_path=experiment, optics=optics)
    window.show()
    if quit_after is not None:
        QTimer.singleShot(int(quit_after * 1000), window.close)
    logger.info("main window open on source %s", source)
    return app.exec()
