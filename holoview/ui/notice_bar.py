"""A notice that stays until dismissed, with one action: what the window did on its own.

The banner (:meth:`~holoview.ui.main_window.MainWindow.show_message`) says a problem
for a few seconds; a notice says something the window decided for the operator (the
experiment a recording carries, applied when it opened) and offers the one click that
undoes it. It stays until that click, the close button, or the next notice.
"""

from __future__ import annotations

from collections.abc import Callable

from PyQt6.QtWidgets import (
    QLabel,
    QPushButton,
    QSizePolicy,
    QStyle,
    QToolBar,
    QToolButton,
    QWidget,
)


class NoticeBar(QToolBar):
    """A tool bar holding one notice and its action; hidden while there is none."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Notice", parent)
        self.setObjectName("notice")
        self.setMovable(False)
        self.label = QLabel()
        self.label.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Preferred)
        self.label.setStyleSheet("background: #cfe2ff; color: #052c65; padding: 4px;")
        self.button = QPushButton()
        self.close_button = QToolButton()
        style = self.style()
        assert style is not None
        self.close_button.setIcon(style.standardIcon(QStyle.StandardPixmap.SP_DialogCloseButton))
        self.close_button.setToolTip("dismiss")
        self.close_button.clicked.connect(self.dismiss)
        self.button.clicked.connect(self._act)
        self.addWidget(self.label)
        self.addWidget(self.button)
        self.addWidget(self.close_button)
        self._action: Callable[[], None] | None = None
        self.setVisible(False)

    @property
    def text(self) -> str:
        """The notice shown ('' when none)."""
        return self.label.text() if self.isVisibleTo(self.parentWidget()) else ""

    @property
    def has_action(self) -> bool:
        """True while a notice waits for its click or dismissal."""
        return self._action is not None

    def show_notice(self, text: str, action: str, slot: Callable[[], None]) -> None:
        """Show ``text`` with a button ``action`` that calls ``slot`` (and dismisses)."""
        self.label.setText(text)
        self.button.setText(action)
        self._action = slot
        self.setVisible(True)

    def dismiss(self) -> None:
        """Hide the notice; its action is forgotten."""
        self._action = None
        self.setVisible(False)

    def _act(self) -> None:
        action = self._action
        self.dismiss()
        if action is not None:
            action()
