"""Record to HDF5 from the GUI: file name, duration or frame count, indicator, drops."""

from __future__ import annotations

from pathlib import Path

from PyQt6.QtCore import pyqtSignal
from PyQt6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QToolButton,
    QWidget,
)

from holoview.live.session import RecordingProgress, RecordRequest


class RecordingPanel(QWidget):
    """File name, limit (duration or frame count), record/stop button and indicator.

    Signals
    -------
    startRequested(RecordRequest)
    stopRequested()
    """

    startRequested = pyqtSignal(object)
    stopRequested = pyqtSignal()

    def __init__(self, default_dir: Path | None = None, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._recording = False
        self._shown: tuple[RecordingProgress | None] | None = None
        folder = default_dir or Path.cwd()
        self.path_edit = QLineEdit(str(folder / "recording.h5"))
        browse = QToolButton()
        browse.setText("...")
        browse.clicked.connect(self._browse)
        path_row = QHBoxLayout()
        path_row.addWidget(self.path_edit, 1)
        path_row.addWidget(browse)
        self.limit_box = QComboBox()
        self.limit_box.addItems(["until stopped", "duration", "frame count"])
        self.duration_spin = QDoubleSpinBox()
        self.duration_spin.setRange(0.1, 86400.0)
        self.duration_spin.setValue(10.0)
        self.duration_spin.setSuffix(" s")
        self.frames_spin = QSpinBox()
        self.frames_spin.setRange(1, 10_000_000)
        self.frames_spin.setValue(600)
        self.frames_spin.setSuffix(" frames")
        self.limit_box.currentIndexChanged.connect(self._limit_changed)
        self.record_button = QPushButton("Record")
        self.record_button.setToolTip("start or stop recording (Ctrl+R)")
        self.record_button.clicked.connect(self._toggle)
        self.indicator = QLabel("not recording")
        form = QFormLayout(self)
        form.addRow("file", path_row)
        form.addRow("stop", self.limit_box)
        form.addRow("duration", self.duration_spin)
        form.addRow("frames", self.frames_spin)
        form.addRow(self.record_button)
        form.addRow(self.indicator)
        self._limit_changed(0)

    @property
    def recording(self) -> bool:
        """Whether a recording is running (as last reported)."""
        return self._recording

    def request(self) -> RecordRequest:
        """Return the request the controls describe."""
        mode = self.limit_box.currentIndex()
        return RecordRequest(
            path=Path(self.path_edit.text().strip()).expanduser(),
            duration_s=self.duration_spin.value() if mode == 1 else None,
            frames=self.frames_spin.value() if mode == 2 else None,
        )

    def toggle(self) -> None:
        """Ask to start a recording, or to stop the one running."""
        self._toggle()

    def _toggle(self) -> None:
        if self._recording:
            self.stopRequested.emit()
        else:
            self.startRequested.emit(self.request())

    def set_progress(self, progress: RecordingProgress | None) -> None:
        """Show the recorder's progress (None: idle); nothing is redone when unchanged."""
        if self._shown == (progress,):
            return
        self._shown = (progress,)
        self._recording = progress is not None and progress.active
        self.record_button.setText("Stop recording" if self._recording else "Record")
        for widget in (self.path_edit, self.limit_box, self.duration_spin, self.frames_spin):
            widget.setEnabled(not self._recording)
        if not self._recording:
            self._limit_changed(self.limit_box.currentIndex())
        if progress is None:
            self.indicator.setText("not recording")
            self.indicator.setStyleSheet("")
            return
        state = "● REC" if progress.active else "saved"
        self.indicator.setText(
            f"{state} {progress.path.name}: {progress.frames} frames, "
            f"{progress.elapsed_s:.1f} s, {progress.dropped} dropped"
        )
        colour = "#d00000" if progress.active else ("#c06000" if progress.dropped else "#007000")
        self.indicator.setStyleSheet(f"color: {colour}; font-weight: bold;")

    def _limit_changed(self, index: int) -> None:
        self.duration_spin.setEnabled(index == 1 and not self._recording)
        self.frames_spin.setEnabled(index == 2 and not self._recording)

    def _browse(self) -> None:
        path, _ = QFileDialog.getSaveFileName(
            self, "Record to", self.path_edit.text(), "HDF5 (*.h5 *.hdf5)"
        )
        if path:
            self.path_edit.setText(path)
