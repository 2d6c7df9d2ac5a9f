"""Pick a source, start and stop it, and edit the settings it describes.

Editors are built from the source's own setting descriptions (kind, unit, limits,
increment, choices, read-only, locked while streaming): a setting the source
does not have is shown disabled, and every value shown is the value read back
from the source after a change.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from PyQt6.QtCore import pyqtSignal
from PyQt6.QtWidgets import (
    QAbstractSpinBox,
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

#: Settings every camera is expected to have, in the order shown; others follow.
STANDARD_SETTINGS: tuple[str, ...] = (
    "exposure_s",
    "gain_db",
    "frame_rate_hz",
    "pixel_format",
    "roi",
)

#: Display scale and unit for a setting's SI unit (seconds are shown in ms).
DISPLAY_UNITS: dict[str, tuple[float, str]] = {"s": (1e3, "ms")}

REPLAY_ITEM = "Replay a file..."


def _pretty(name: str) -> str:
    for suffix in ("_s", "_hz", "_db", "_px", "_m"):
        if name.endswith(suffix):
            return name[: -len(suffix)].replace("_", " ")
    return name.replace("_", " ")


class SourcePanel(QWidget):
    """Source choice, start/stop, and one editor per setting.

    Signals
    -------
    startRequested(str)
        Start the source with this specification (``sim``, ``aravis:ID``, ...).
    stopRequested()
    settingRequested(str, object)
        The operator changed a setting (name, value in SI units).
    """

    startRequested = pyqtSignal(str)
    stopRequested = pyqtSignal()
    settingRequested = pyqtSignal(str, object)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._streaming = False
        self._infos: dict[str, Any] = {}
        self._editors: dict[str, QWidget] = {}
        self._setters: dict[str, Callable[[Any], None]] = {}
        self._updating = False
        self.source_box = QComboBox()
        self.source_box.setEditable(False)
        self.source_box.activated.connect(self._source_chosen)
        self.refresh_button = QPushButton("Find cameras")
        self.start_button = QPushButton("Start")
        self.start_button.setToolTip("start or stop the source (F5)")
        self.start_button.clicked.connect(self.toggle)
        self.state_label = QLabel("stopped")
        top = QHBoxLayout()
        top.addWidget(self.source_box, 1)
        top.addWidget(self.refresh_button)
        self.form = QFormLayout()
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        row = QHBoxLayout()
        row.addWidget(self.start_button)
        row.addWidget(self.state_label, 1)
        layout.addLayout(row)
        layout.addLayout(self.form)
        layout.addStretch(1)
        self.set_sources(["sim"])

    # ---- sources -----------------------------------------------------------
    def set_sources(self, specs: Sequence[str], current: str | None = None) -> None:
        """Offer ``specs`` (``sim``, ``aravis:ID``, ``v4l2:N``, ``replay:PATH``) and replay."""
        chosen = current or self.current_source()
        self.source_box.clear()
        items = list(dict.fromkeys(specs))
        if chosen and chosen not in items:
            items.append(chosen)
        self.source_box.addItems([*items, REPLAY_ITEM])
        if chosen:
            self.source_box.setCurrentText(chosen)

    def current_source(self) -> str:
        """The source specification chosen (empty before any)."""
        text = self.source_box.currentText()
        return "" if text == REPLAY_ITEM else text

    def _source_chosen(self, index: int) -> None:
        if self.source_box.itemText(index) != REPLAY_ITEM:
            return
        path, _ = QFileDialog.getOpenFileName(
            self,
            "Replay a recording",
            "",
            "Recordings (*.h5 *.hdf5 *.tif *.tiff *.avi *.mkv);;All (*)",
        )
        if path:
            self.set_sources(
                [self.source_box.itemText(i) for i in range(self.source_box.count() - 1)],
                current=f"replay:{path}",
            )

    def toggle(self) -> None:
        """Ask to start the chosen source, or to stop the running one."""
        if self._streaming:
            self.stopRequested.emit()
        elif self.current_source():
            self.startRequested.emit(self.current_source())

    def set_opening(self, spec: str) -> None:
        """Show that ``spec`` is being opened; nothing can be started meanwhile."""
        self.state_label.setText(f"opening {spec}...")
        self.start_button.setEnabled(False)
        self.source_box.setEnabled(False)

    def set_streaming(self, streaming: bool, description: str = "") -> None:
        """Show whether the source streams; lock the settings that cannot change then."""
        self._streaming = streaming
        self.start_button.setText("Stop" if streaming else "Start")
        self.start_button.setEnabled(True)
        self.state_label.setText(description or ("streaming" if streaming else "stopped"))
        self.source_box.setEnabled(not streaming)
        self.refresh_button.setEnabled(not streaming)
        for name, info in self._infos.items():
            self._editors[name].setEnabled(self._editable(info))

    # ---- settings ----------------------------------------------------------
    def _editable(self, info: Any) -> bool:
        if info is None or info.read_only or info.kind == "roi":
            return False
        return not (info.locked_while_streaming and self._streaming)

    def set_settings(self, infos: Mapping[str, Any], values: Mapping[str, Any]) -> None:
        """Build editors from setting descriptions and show the values read back.

        Parameters
        ----------
        infos : mapping of str to SettingInfo
            What the source says about each setting.
        values : mapping of str to value
            The values read back from the source (SI units).
        """
        while self.form.rowCount():
            self.form.removeRow(0)
        self._infos, self._editors, self._setters = {}, {}, {}
        names = [*STANDARD_SETTINGS, *(n for n in infos if n not in STANDARD_SETTINGS)]
        for name in names:
            info = infos.get(name)
            editor, setter = self._make_editor(name, info)
            self._infos[name] = info
            self._editors[name] = editor
            self._setters[name] = setter
            label = _pretty(name)
            if info is None:
                editor.setToolTip(f"this source has no {label} setting")
            elif info.doc:
                editor.setToolTip(info.doc)
            self.form.addRow(label, editor)
            editor.setEnabled(self._editable(info))
        self.show_values(values)

    def show_values(self, values: Mapping[str, Any]) -> None:
        """Show values read back from the source (SI units)."""
        self._updating = True
        try:
            for name, value in values.items():
                setter = self._setters.get(name)
                if setter is not None and value is not None:
                    setter(value)
        finally:
            self._updating = False

    def editor(self, name: str) -> QWidget:
        """Return the editor widget of setting ``name``."""
        return self._editors[name]

    def _emit(self, name: str, value: Any) -> None:
        if not self._updating:
            self.settingRequested.emit(name, value)

    def _make_editor(self, name: str, info: Any) -> tuple[QWidget, Callable[[Any], None]]:
        if info is None:
            label = QLabel("not available")
            return label, lambda v: label.setText(str(v))
        if info.read_only and info.kind != "roi":
            shown = QLabel()
            scale, unit = DISPLAY_UNITS.get(info.unit, (1.0, info.unit))

            def show(v: Any, lab: QLabel = shown, sc: float = scale, u: str = unit) -> None:
                text = (
                    f"{v * sc:g}"
                    if isinstance(v, int | float) and not isinstance(v, bool)
                    else str(v)
                )
                lab.setText(f"{text} {u}".strip())

            return shown, show
        if info.kind in ("float", "int"):
            scale, unit = DISPLAY_UNITS.get(info.unit, (1.0, info.unit))
            spin: QAbstractSpinBox
            if info.kind == "int":
                spin = QSpinBox()
                low, high = info.limits or (-(2**31), 2**31 - 1)
                spin.setRange(int(low), int(high))
                spin.setSingleStep(int(info.increment or 1))
            else:
                spin = QDoubleSpinBox()
                low, high = info.limits or (-1e12, 1e12)
                spin.setRange(low * scale, high * scale)
                step = (info.increment or 0.0) * scale
                decimals = 3 if not step else max(0, min(6, -math.floor(math.log10(step))))
                spin.setDecimals(decimals)
                spin.setSingleStep(step or 10 ** (-decimals))
            spin.setKeyboardTracking(False)
            if unit:
                spin.setSuffix(f" {unit}")
            spin.valueChanged.connect(
                lambda v, n=name, s=scale, k=info.kind: self._emit(
                    n, int(v) if k == "int" else v / s
                )
            )
            if info.kind == "int":
                return spin, lambda v, s=spin: s.setValue(int(v))
            return spin, lambda v, s=spin, sc=scale: s.setValue(float(v) * sc)
        if info.kind == "enum":
            box = QComboBox()
            box.addItems(list(info.choices or ()))
            box.currentTextChanged.connect(lambda v, n=name: self._emit(n, v))
            return box, lambda v, b=box: b.setCurrentText(str(v))
        if info.kind == "bool":
            check = QCheckBox()
            check.toggled.connect(lambda v, n=name: self._emit(n, v))
            return check, lambda v, c=check: c.setChecked(bool(v))
        label = QLabel()
        if info.kind == "roi":
            label.setToolTip("draw the ROI on the hologram view (Draw ROI, then Apply ROI)")

            def show_roi(v: Any, lab: QLabel = label) -> None:
                left, top, width, height = v
                lab.setText(f"left {left}, top {top}, {width} x {height} px")

            return label, show_roi
        return label, lambda v, lab=label: lab.setText(str(v))
