"""Figures drawn with matplotlib on its Agg canvas, and written as PNG, PDF or SVG.

Every figure of holoview's headless commands (``process``'s report, ``simulate``'s
frame and spectrum) is a :class:`matplotlib.figure.Figure` with an Agg canvas
attached here, explicitly: no ``pyplot``, so no GUI backend is ever chosen, no Qt is
imported, and matplotlib's global state (a notebook's backend, its open figures) is
left alone. Saving as PDF or SVG goes through matplotlib's own vector writers, which
need no display either.

The format is the file's suffix (:data:`FORMATS`). Writers call :func:`save_figure`
on a temporary name (:mod:`holoview.atomic`), which keeps the suffix. matplotlib is
imported when the first figure is made, not with this module.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from holoview import __version__
from holoview.errors import InputError, OutputError, os_error_text

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: The formats figures are written in, named by the file's suffix.
FORMATS = ("png", "pdf", "svg")

#: Dots per inch of a PNG: a figure 13.66 inches wide is 1366 pixels.
DPI = 100


def new_figure(width_in: float, height_in: float) -> Figure:
    """Return an empty figure on an Agg canvas.

    Parameters
    ----------
    width_in, height_in : float
        Size, inches (at :data:`DPI` dots per inch in a PNG).

    Returns
    -------
    Figure
        Not known to ``pyplot``: it is freed with its last reference.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width_in, height_in), dpi=DPI)
    FigureCanvasAgg(figure)
    return figure


def spectrum_edges(rows: int, cols: int) -> tuple[float, float, float, float]:
    """The edges ``(x0, x1, y0, y1)`` in cycles/pixel of a centred (shifted) spectrum.

    Bin ``k`` of ``n`` (centred) is the frequency ``(k - n // 2) / n``; the image of a
    ``(rows, cols)`` spectrum spans half a bin beyond the first and last centres:
    ``extent=(x0, x1, y1, y0)`` with row 0 at the top.

    Examples
    --------
    >>> spectrum_edges(4, 4)
    (-0.625, 0.375, -0.625, 0.375)
    """
    x0, x1 = -(cols // 2) / cols - 0.5 / cols, (cols - cols // 2) / cols - 0.5 / cols
    y0, y1 = -(rows // 2) / rows - 0.5 / rows, (rows - rows // 2) / rows - 0.5 / rows
    return x0, x1, y0, y1


def map_edges(rows: int, cols: int, dy: float, dx: float) -> tuple[float, float, float, float]:
    """The edges ``(x0, x1, y0, y1)`` of a ``(rows, cols)`` map whose pixel ``(r, c)``
    stands at ``(c dx, r dy)``, as in ``results.h5``: half a pixel beyond the first and
    last centres (``extent=(x0, x1, y1, y0)`` with row 0 at the top).

    Examples
    --------
    >>> map_edges(2, 4, 1.0, 0.5)
    (-0.25, 1.75, -0.5, 1.5)
    """
    return -0.5 * dx, (cols - 0.5) * dx, -0.5 * dy, (rows - 0.5) * dy


def figure_format(path: str | Path, option: str) -> str:
    """Return the format of a figure file from its suffix (one of :data:`FORMATS`).

    Parameters
    ----------
    path : str or Path
        The figure's file name.
    option : str
        The option that named it, for the message.

    Raises
    ------
    InputError
        The suffix is not one of :data:`FORMATS`.
    """
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in FORMATS:
        raise InputError(
            f"{option} {path}: no image writer for that suffix "
            f"(use {', '.join('.' + f for f in FORMATS)})"
        )
    return suffix


def save_figure(figure: Figure, path: Path, *, name: str) -> None:
    """Write ``figure`` to ``path`` in the format of its suffix.

    Parameters
    ----------
    figure : Figure
        From :func:`new_figure`.
    path : Path
        The file to write (usually a temporary name, :mod:`holoview.atomic`).
    name : str
        What the file is called in a message (``report.png``).

    Raises
    ------
    OutputError
        The file could not be written (a full disk, a folder that went away).
    """
    kind = figure_format(path, name)
    # no creation date in vector files: the same run draws the same bytes
    metadata: dict[str, str | None] = {"Creator": f"holoview {__version__}"}
    if kind in ("pdf", "svg"):
        metadata["Date"] = None
    else:
        metadata = {"Software": f"holoview {__version__}"}
    from matplotlib import rc_context

    try:
        # text stays text in vector files (editable, searchable; TrueType fonts in a
        # PDF, as journals ask), not outlines
        with rc_context({"svg.fonttype": "none", "pdf.fonttype": 42}):
            figure.savefig(path, format=kind, dpi=DPI, metadata=metadata, facecolor="white")
    except OSError as exc:
        raise OutputError(f"cannot write {name}: {os_error_text(exc)}") from exc
