"""Where the main window's docks go, by the screen's size, and a window that fits its screen.

Three layouts, chosen from the available screen area (the screen less task bars):

- **wide** (at least :data:`WIDE` pixels): three columns, the controls (Source and
  Recording, tabbed), the camera (Hologram over Spectrum), the results (Surface over
  Trends);
- **medium** (a laptop's 1366 x 768): the same columns, the maps given more of the
  height and the camera more of the width;
- **compact** (below :data:`MEDIUM`, down to 800 x 600): two columns, Source and one
  tab group of Spectrum, Hologram, Surface, Trends and Recording.

Every dock stays reachable: a tabbed dock is one click away, and the window (restored
geometry included) is moved and shrunk into the available area.
"""

from __future__ import annotations

from PyQt6.QtCore import QPoint, QRect, QSize, Qt
from PyQt6.QtGui import QGuiApplication
from PyQt6.QtWidgets import QDockWidget, QMainWindow, QWidget

#: Smallest available area (width, height) of the wide and of the medium layout, pixels.
WIDE = (1600, 900)
MEDIUM = (1200, 700)
#: The window's size where the screen has room for it, pixels.
PREFERRED = QSize(1800, 1000)
#: Room left for a window manager's frame (title bar, borders) before the window is
#: shown and its frame known, pixels.
FRAME_ALLOWANCE = QSize(16, 40)


def available_area(window: QWidget) -> QRect:
    """The free area (less task bars) of the screen ``window`` is on, pixels.

    A window Qt has placed on no screen takes the primary screen's; where there is no
    screen at all (none connected, the display going), an area of :data:`PREFERRED`.
    """
    screen = window.screen() or QGuiApplication.primaryScreen()
    return screen.availableGeometry() if screen is not None else QRect(QPoint(0, 0), PREFERRED)


def layout_for(available: QSize) -> str:
    """``"wide"``, ``"medium"`` or ``"compact"`` for an available screen area."""
    if available.width() >= WIDE[0] and available.height() >= WIDE[1]:
        return "wide"
    if available.width() >= MEDIUM[0] and available.height() >= MEDIUM[1]:
        return "medium"
    return "compact"


def arrange_docks(window: QMainWindow, docks: dict[str, QDockWidget], layout: str) -> None:
    """Place the docks (``Source``, ``Recording``, ``Hologram``, ``Spectrum``, ``Surface``,
    ``Trends``) of ``window`` in ``layout`` and size the columns to its window.

    Each layout has one group of tabs: Qt (6.11) leaves a second group's tab bar drawn
    twice when two groups are made before the window is shown.
    """
    left = Qt.DockWidgetArea.LeftDockWidgetArea
    right = Qt.DockWidgetArea.RightDockWidgetArea
    horizontal, vertical = Qt.Orientation.Horizontal, Qt.Orientation.Vertical
    for name in ("Source", "Recording", "Hologram", "Spectrum"):
        window.addDockWidget(left, docks[name])
    for name in ("Surface", "Trends"):
        window.addDockWidget(right, docks[name])
    window.splitDockWidget(docks["Source"], docks["Hologram"], horizontal)
    width, height = window.width(), window.height()
    if layout == "compact":
        window.splitDockWidget(docks["Hologram"], docks["Spectrum"], vertical)
        for name in ("Hologram", "Surface", "Trends", "Recording"):
            window.tabifyDockWidget(docks["Spectrum"], docks[name])
        docks["Spectrum"].raise_()
        window.resizeDocks(
            [docks["Source"], docks["Spectrum"]], [width // 4, width - width // 4], horizontal
        )
        return
    window.tabifyDockWidget(docks["Source"], docks["Recording"])
    docks["Source"].raise_()
    window.splitDockWidget(docks["Hologram"], docks["Spectrum"], vertical)
    window.splitDockWidget(docks["Surface"], docks["Trends"], vertical)
    middle = 35 if layout == "wide" else 40
    window.resizeDocks(
        [docks["Source"], docks["Hologram"], docks["Surface"]],
        [width * 18 // 100, width * middle // 100, width * (82 - middle) // 100],
        horizontal,
    )
    maps = 62 if layout == "wide" else 68  # the maps keep their height on a short screen
    shares = [height * maps // 100, height * (100 - maps) // 100]
    window.resizeDocks([docks["Surface"], docks["Trends"]], shares, vertical)


def fitted(frame: QRect, frame_margins: QSize, available: QRect) -> tuple[QPoint, QSize]:
    """Return where to move the window and its client size so that it fits ``available``.

    Parameters
    ----------
    frame : QRect
        The window's frame geometry now (its client area plus ``frame_margins``).
    frame_margins : QSize
        Width and height the frame adds to the client area.
    available : QRect
        The screen's available geometry.

    Returns
    -------
    (QPoint, QSize)
        The frame's top-left corner (for ``move``) and the client size (for ``resize``).
    """
    width = min(frame.width(), available.width())
    height = min(frame.height(), available.height())
    x = min(max(frame.x(), available.x()), available.right() + 1 - width)
    y = min(max(frame.y(), available.y()), available.bottom() + 1 - height)
    client = QSize(max(1, width - frame_margins.width()), max(1, height - frame_margins.height()))
    return QPoint(x, y), client


def initial_size(available: QSize) -> QSize:
    """The window's first size: :data:`PREFERRED`, or the available area less a frame."""
    return QSize(
        min(PREFERRED.width(), available.width() - FRAME_ALLOWANCE.width()),
        min(PREFERRED.height(), available.height() - FRAME_ALLOWANCE.height()),
    )
