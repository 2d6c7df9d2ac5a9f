"""Opening a file in the window: File > Open, the recent files, drag and drop.

Every way ends in :meth:`FileOpening.open_file`: the file (a holoview recording, a
TIFF stack, a folder of images, a video, a NumPy file) is replayed, paused on its
first frame, its whole run measured in the background
(:mod:`holoview.ui.run_trends`), and the experiment it carries applied as ``holoview
process`` applies it (:mod:`holoview.ui.window_experiment`). The files opened last
are remembered (at most :data:`MAX_RECENT`) in the window's settings
(:func:`~holoview.ui.settings.ui_settings`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

from PyQt6.QtGui import QAction, QDragEnterEvent, QDropEvent, QKeySequence
from PyQt6.QtWidgets import QFileDialog, QMenu, QWidget

from holoview.engine.experiment import Experiment
from holoview.errors import HoloviewError
from holoview.headless.run_series import recording_experiment
from holoview.live.session import LiveSession
from holoview.ui.settings import ui_settings

#: Where the recent files are kept in the settings, and how many.
RECENT_KEY = "files/recent"
MAX_RECENT = 8
#: The file dialog's filter.
FILE_FILTER = (
    "Recordings and frames (*.h5 *.hdf5 *.tif *.tiff *.npy *.npz *.avi *.mkv *.mp4 *.mov)"
    ";;All files (*)"
)


def recent_files() -> list[Path]:
    """The files opened last, newest first."""
    settings = ui_settings()
    paths = []
    for i in range(settings.beginReadArray(RECENT_KEY)):
        settings.setArrayIndex(i)
        value = settings.value("path")
        if isinstance(value, str) and value:
            paths.append(Path(value))
    settings.endArray()
    return paths


def remember(path: Path) -> None:
    """Put ``path`` first in the recent files."""
    paths = [path, *(p for p in recent_files() if p != path)][:MAX_RECENT]
    _store(paths)


def forget(path: Path) -> None:
    """Take ``path`` out of the recent files."""
    _store([p for p in recent_files() if p != path])


def _store(paths: list[Path]) -> None:
    settings = ui_settings()
    settings.remove(RECENT_KEY)
    settings.beginWriteArray(RECENT_KEY, len(paths))
    for i, path in enumerate(paths):
        settings.setArrayIndex(i)
        settings.setValue("path", str(path))
    settings.endArray()
    settings.sync()


@dataclass
class Opened:
    """A source opened off the GUI thread, with what the window needs at once.

    Attributes
    ----------
    session : LiveSession
        Started.
    stored : Experiment or None
        The experiment a replayed recording carries for its first frame (what
        ``holoview process`` applies); None for a camera and files without one.
    notes : list of str
        Problems met reading it (one line each).
    """

    session: LiveSession
    stored: Experiment | None = None
    notes: list[str] = field(default_factory=list)


def opened_source(session: LiveSession, paused: bool) -> Opened:
    """Read what a new session's file carries and, ``paused``, show its first frame.

    Runs on the opening thread: reading a recording's experiment takes a moment.
    """
    replay = session.replay
    if replay is None:
        return Opened(session)
    if paused:
        replay.seek(0)
    try:
        stored, notes = recording_experiment(replay.path)
    except HoloviewError as exc:
        return Opened(session, None, [f"the experiment {replay.path.name} carries: {exc}"])
    return Opened(session, stored, notes)


def dropped_path(event: QDragEnterEvent | QDropEvent) -> Path | None:
    """The local file or folder dragged in (the first), or None."""
    mime = event.mimeData()
    if mime is None or not mime.hasUrls():
        return None
    for url in mime.urls():
        if url.isLocalFile():
            return Path(url.toLocalFile())
    return None


class FileOpening:
    """File > Open, the recent files and drag and drop of the main window (a mixin)."""

    start_source: Callable[..., None]
    show_message: Callable[[str], None]
    recent_menu: QMenu

    def _window(self) -> QWidget:
        return cast(QWidget, self)

    def _make_file_actions(self) -> list[QAction]:
        """The Open actions (for the File menu); :attr:`recent_menu`, the Open recent submenu."""
        open_action = QAction("Open recording...", self._window())
        open_action.setShortcut(QKeySequence("Ctrl+O"))
        open_action.triggered.connect(self.open_file_dialog)
        folder_action = QAction("Open folder of images...", self._window())
        folder_action.triggered.connect(self.open_folder_dialog)
        self.recent_menu = QMenu("Open recent", self._window())
        self.recent_menu.aboutToShow.connect(self._fill_recent_menu)
        self._fill_recent_menu()
        return [open_action, folder_action]

    def _fill_recent_menu(self) -> None:
        menu = self.recent_menu
        menu.clear()
        paths = recent_files()
        for path in paths:
            act = menu.addAction(path.name)
            assert act is not None
            act.setToolTip(str(path))
            act.setStatusTip(str(path))
            act.triggered.connect(lambda _=False, p=path: self.open_file(p))
        menu.setEnabled(bool(paths))

    def open_file(self, path: Path) -> None:
        """Replay ``path``, paused on its first frame, and measure its whole run.

        A file that is not there is said in the banner and leaves the recent files.
        """
        path = Path(path).expanduser()
        if not path.exists():
            self.show_message(f"{path}: no such file or folder")
            forget(path)
            return
        remember(path)
        self.start_source(f"replay:{path}", paused=True)

    def open_file_dialog(self) -> None:
        """Ask for a recording (or frame file) and open it."""
        start = str(recent_files()[0].parent) if recent_files() else ""
        path, _ = QFileDialog.getOpenFileName(self._window(), "Open recording", start, FILE_FILTER)
        if path:
            self.open_file(Path(path))

    def open_folder_dialog(self) -> None:
        """Ask for a folder of images and open it."""
        path = QFileDialog.getExistingDirectory(self._window(), "Open folder of images")
        if path:
            self.open_file(Path(path))

    def dragEnterEvent(self, event: QDragEnterEvent | None) -> None:
        """Take a local file or folder dragged over the window."""
        if event is not None and dropped_path(event) is not None:
            event.acceptProposedAction()

    def dropEvent(self, event: QDropEvent | None) -> None:
        """Open the file or folder dropped on the window."""
        path = None if event is None else dropped_path(event)
        if path is not None and event is not None:
            event.acceptProposedAction()
            self.open_file(path)
