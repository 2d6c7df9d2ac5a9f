"""A one-line label that takes the room it is given and elides what does not fit."""

from __future__ import annotations

from PyQt6.QtCore import Qt
from PyQt6.QtGui import QPainter, QPaintEvent
from PyQt6.QtWidgets import QLabel, QSizePolicy, QWidget

__all__ = ["ElidedLabel"]


class ElidedLabel(QLabel):
    """A label that never widens its layout: text too long for it ends in an ellipsis.

    A caption that grows with what it reports ("maps of frame 14 (55 behind)") would
    otherwise either widen its dock past a small screen or be cut at an arbitrary
    character. The whole text is the tooltip.
    """

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)

    def setText(self, text: str | None) -> None:
        """Show ``text``, elided to the label's width; the whole of it as the tooltip."""
        super().setText(text)
        self.setToolTip(text or "")

    def elided(self) -> str:
        """The text as drawn at the label's present width."""
        rect = self.contentsRect()
        return self.fontMetrics().elidedText(self.text(), Qt.TextElideMode.ElideRight, rect.width())

    def paintEvent(self, event: QPaintEvent | None) -> None:
        """Draw the text elided to the width."""
        painter = QPainter(self)
        painter.drawText(self.contentsRect(), self.alignment(), self.elided())
        painter.end()
