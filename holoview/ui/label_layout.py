"""Where the spectrum's peak labels go: beside each peak, clear of the others.

Peaks of a multiplexed hologram crowd into one quadrant of the spectrum; a label set at
the same offset from every peak lands on its neighbour's marker or label (RB2's and
FB2's at 1366x768). :func:`place_labels` puts each label against its peak's marker,
on the side (of eight) where its text box covers the least of the labels already placed,
of the peaks' markers and of the space outside the view.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["LabelSpot", "PeakLabel", "place_labels"]

#: The eight sides tried, (x, y) in the plot's data axes, y down the screen; the first
#: (up and to the right) wins ties.
SIDES: tuple[tuple[int, int], ...] = (
    (1, -1),
    (1, 0),
    (0, -1),
    (-1, -1),
    (1, 1),
    (-1, 0),
    (0, 1),
    (-1, 1),
)


@dataclass(frozen=True)
class PeakLabel:
    """A label to place: its text and its peak, cycles/pixel."""

    text: str
    fx: float
    fy: float


@dataclass(frozen=True)
class LabelSpot:
    """Where a label goes: ``pos`` in data units, and the text item's anchor there.

    ``anchor`` is pyqtgraph's: the point of the text box, as fractions of its width
    and height from its top left corner on screen, that sits at ``pos``.
    """

    pos: tuple[float, float]
    anchor: tuple[float, float]


Box = tuple[float, float, float, float]


def place_labels(
    labels: Sequence[PeakLabel],
    char_size: tuple[float, float],
    view: Box,
    marker: float,
) -> list[LabelSpot]:
    """Place each label against its peak, clear of the labels before it and of the peaks.

    Parameters
    ----------
    labels : sequence of PeakLabel
        In order of importance: earlier labels take the better sides.
    char_size : (float, float)
        One character's width and one line's height, in data units (cycles/pixel).
    view : (float, float, float, float)
        The visible range, ``(x0, y0, x1, y1)``, data units.
    marker : float
        Half the width of a peak's marker, data units.

    Returns
    -------
    list of LabelSpot
        One per label, in the order given.
    """
    char_w, line_h = char_size
    markers = [(p.fx - marker, p.fy - marker, p.fx + marker, p.fy + marker) for p in labels]
    placed: list[Box] = []
    spots: list[LabelSpot] = []
    for label in labels:
        w, h = char_w * len(label.text), line_h
        best: tuple[float, Box, LabelSpot] | None = None
        for rank, (sx, sy) in enumerate(SIDES):
            x, y = label.fx + marker * sx, label.fy + marker * sy
            anchor = ((1 - sx) / 2, (1 - sy) / 2)
            left, top = x - anchor[0] * w, y - anchor[1] * h
            box = (left, top, left + w, top + h)
            cost = sum(_overlap(box, other) for other in placed)
            cost += sum(_overlap(box, m) for m in markers)
            cost += w * h - _overlap(box, view)
            cost += 1e-3 * rank * w * h
            if best is None or cost < best[0]:
                best = (cost, box, LabelSpot((x, y), anchor))
        assert best is not None
        placed.append(best[1])
        spots.append(best[2])
    return spots


def _overlap(a: Box, b: Box) -> float:
    """Area common to two boxes ``(x0, y0, x1, y1)``."""
    dx = min(a[2], b[2]) - max(a[0], b[0])
    dy = min(a[3], b[3]) - max(a[1], b[1])
    return dx * dy if dx > 0 and dy > 0 else 0.0
