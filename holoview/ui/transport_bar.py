"""The replay transport bar: play and pause, a step either way, a slider, speed, loop.

Shown only while a replay streams (a camera is not steered). It draws the state of a
:class:`~holoview.live.replay_control.ReplayControl` at each redraw (the frame shown,
its index and the recording's time) and forwards the operator's commands to it; a
command the replay refuses (a seek outside the file) becomes one line in the window's
banner. Shortcuts, active only while a replay streams (so the arrow keys stay the
widgets' otherwise): Space play/pause, Left/Right one frame back/forward,
Shift+Left/Right ten frames, Home/End the first/last frame, [ and ] slower/faster.
"""

from __future__ import annotations

from collections.abc import Callable

from PyQt6.QtCore import Qt, pyqtSignal
from PyQt6.QtGui import QAction, QKeySequence
from PyQt6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QLabel,
    QSlider,
    QStyle,
    QToolBar,
    QToolButton,
    QWidget,
)

from holoview.errors import HoloviewError
from holoview.live.replay_control import SPEED_STEPS, ReplayControl, ReplayState, speed_text

#: Frames a Shift+arrow step moves.
BIG_STEP = 10


class TransportBar(QToolBar):
    """A tool bar that steers the replay of the current session.

    Signals
    -------
    message(str)
        A command the replay refused, in one line (for the banner).
    changed()
        A command changed the replay's settings (speed, loop): the source panel re-reads them.
    """

    message = pyqtSignal(str)
    changed = pyqtSignal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Replay", parent)
        self.setObjectName("transport")
        self.setMovable(False)
        self.control: ReplayControl | None = None
        self._drawn: ReplayState | None = None  # what the widgets show
        self._updating = False
        style = self.style()
        assert style is not None

        def button(
            icon: QStyle.StandardPixmap, tip: str, slot: Callable[[], object]
        ) -> QToolButton:
            b = QToolButton()
            b.setIcon(style.standardIcon(icon))
            b.setToolTip(tip)
            b.setFocusPolicy(Qt.FocusPolicy.NoFocus)  # Space stays the play/pause shortcut
            b.clicked.connect(slot)
            self.addWidget(b)
            return b

        SP = QStyle.StandardPixmap
        self.start_button = button(SP.SP_MediaSkipBackward, "first frame (Home)", self.to_start)
        self.back_button = button(
            SP.SP_MediaSeekBackward, "one frame back (Left; Shift+Left: ten)", lambda: self.step(-1)
        )
        self.play_button = button(SP.SP_MediaPlay, "play / pause (Space)", self.toggle)
        self.forward_button = button(
            SP.SP_MediaSeekForward,
            "one frame forward (Right; Shift+Right: ten)",
            lambda: self.step(1),
        )
        self.end_button = button(SP.SP_MediaSkipForward, "last frame (End)", self.to_end)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setToolTip("the frame shown: drag to go to a frame")
        self.slider.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        self.slider.valueChanged.connect(self._slider_moved)
        self.addWidget(self.slider)
        self.position_label = QLabel("frame - / -")
        self.position_label.setToolTip(
            "index of the frame shown (from 0) / the last index · the recording's time "
            "of that frame since its first"
        )
        self.position_label.setMinimumWidth(
            self.position_label.fontMetrics().horizontalAdvance("frame 00000 / 00000 · 0000.000 s")
        )
        self.addWidget(self.position_label)
        self.speed_box = QComboBox()
        self.speed_box.addItems([speed_text(s) for s in SPEED_STEPS])
        self.speed_box.setToolTip("times the recorded pace ([ slower, ] faster)")
        self.speed_box.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        self.speed_box.activated.connect(lambda i: self.set_speed(SPEED_STEPS[i]))
        self.addWidget(self.speed_box)
        self.loop_box = QCheckBox("Loop")
        self.loop_box.setToolTip("start over at the end; otherwise hold on the last frame")
        self.loop_box.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        self.loop_box.clicked.connect(self.set_loop)
        self.addWidget(self.loop_box)
        self.shortcuts = self._make_shortcuts()
        self.attach(None)

    def _make_shortcuts(self) -> list[QAction]:
        def action(text: str, keys: str, slot: Callable[[], object]) -> QAction:
            act = QAction(text, self)
            act.setShortcut(QKeySequence(keys))
            act.setShortcutContext(Qt.ShortcutContext.ApplicationShortcut)
            act.triggered.connect(slot)
            return act

        return [
            action("Play/pause", "Space", self.toggle),
            action("Frame back", "Left", lambda: self.step(-1)),
            action("Frame forward", "Right", lambda: self.step(1)),
            action(f"{BIG_STEP} frames back", "Shift+Left", lambda: self.step(-BIG_STEP)),
            action(f"{BIG_STEP} frames forward", "Shift+Right", lambda: self.step(BIG_STEP)),
            action("First frame", "Home", self.to_start),
            action("Last frame", "End", self.to_end),
            action("Slower", "[", self.slower),
            action("Faster", "]", self.faster),
        ]

    # ---- the session -------------------------------------------------------
    def attach(self, control: ReplayControl | None) -> None:
        """Steer ``control`` (shown, shortcuts on), or nothing (hidden, shortcuts off)."""
        self.control = control
        self._drawn = None
        for act in self.shortcuts:
            act.setEnabled(control is not None)
        self.setVisible(control is not None)
        self.refresh()

    def refresh(self) -> None:
        """Draw where the replay stands: the frame shown, its time, play/pause, speed, loop."""
        control = self.control
        if control is None:
            return
        try:
            state = control.state()
        except HoloviewError as exc:  # the source closed under us
            self.message.emit(str(exc))
            return
        if state == self._drawn:
            return  # the redraw timer calls at 30 Hz: nothing moved
        self._drawn = state
        self._updating = True
        try:
            self.slider.setRange(0, max(0, state.n_frames - 1))
            if state.index >= 0 and not self.slider.isSliderDown():
                self.slider.setValue(state.index)
            self.position_label.setText(state.text)
            icon = (
                QStyle.StandardPixmap.SP_MediaPlay
                if state.paused
                else QStyle.StandardPixmap.SP_MediaPause
            )
            style = self.style()  # the application's, while it runs (the stubs allow None)
            if style is not None:
                self.play_button.setIcon(style.standardIcon(icon))
            self.play_button.setToolTip(("play" if state.paused else "pause") + " (Space)")
            if state.speed in SPEED_STEPS:
                self.speed_box.setCurrentIndex(SPEED_STEPS.index(state.speed))
            self.loop_box.setChecked(state.loop)
        finally:
            self._updating = False

    # ---- commands ----------------------------------------------------------
    def _command(self, call: Callable[[ReplayControl], object], changes: bool = False) -> None:
        if self.control is None:
            return
        try:
            call(self.control)
        except HoloviewError as exc:
            self.message.emit(str(exc))
        if changes:
            self.changed.emit()
        self.refresh()

    def toggle(self) -> None:
        """Play when paused, pause when playing."""
        self._command(ReplayControl.toggle)

    def step(self, n: int) -> None:
        """Pause and show the frame ``n`` after the one shown (before it for negative ``n``)."""
        self._command(lambda c: c.step(n))

    def seek(self, index: int) -> None:
        """Show frame ``index`` (a frame outside the file: a message, nothing moves)."""
        self._command(lambda c: c.seek(index))

    def to_start(self) -> None:
        """Show the first frame."""
        self._command(ReplayControl.to_start)

    def to_end(self) -> None:
        """Show the last frame."""
        self._command(ReplayControl.to_end)

    def set_speed(self, speed: float) -> None:
        """Play at ``speed`` times the recorded pace (infinity: as fast as it reads)."""
        self._command(lambda c: c.set_speed(speed), changes=True)

    def slower(self) -> None:
        """The next speed down."""
        self._command(ReplayControl.slower, changes=True)

    def faster(self) -> None:
        """The next speed up."""
        self._command(ReplayControl.faster, changes=True)

    def set_loop(self, on: bool) -> None:
        """Start over at the end (on) or hold on the last frame (off)."""
        self._command(lambda c: c.set_loop(on), changes=True)

    def _slider_moved(self, value: int) -> None:
        if not self._updating:
            self.seek(value)
