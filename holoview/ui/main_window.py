"""The main window."""

from __future__ import annotations

from PyQt6.QtWidgets import QLabel, QMainWindow

from holoview import __version__


class MainWindow(QMainWindow):
    """holoview's main window on one camera source."""

    def __init__(self, source: str = "sim") -> None:
        super().__init__()
        self.source = source
        self.setWindowTitle(f"holoview {__version__}: {source}")
        self.setCentralWidget(QLabel(f"source: {source}"))
        self.statusBar().showMessage("ready")
        self.resize(1280, 800)
