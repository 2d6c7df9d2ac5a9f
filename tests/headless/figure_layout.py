"""What a reader of a figure would see wrong in its layout: text off the page, tick labels
running into each other."""

from __future__ import annotations

import itertools

import pytest
from matplotlib.axis import Axis
from matplotlib.backend_bases import RendererBase
from matplotlib.figure import Figure
from matplotlib.text import Text
from matplotlib.transforms import Bbox


def saved_figures(monkeypatch: pytest.MonkeyPatch) -> list[Figure]:
    """A list that every figure saved from now on (in this process) is added to."""
    saved: list[Figure] = []
    savefig = Figure.savefig

    def keep(figure: Figure, *args: object, **kwargs: object) -> None:
        saved.append(figure)
        savefig(figure, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    return saved


#: Pixels a text may reach past the page or into a neighbouring label (antialiasing).
SLACK_PX = 1.0


def _tick_labels(axis: Axis) -> tuple[list[Text], set[int]]:
    """The axis's tick labels drawn (their ticks in view), and the ids of all of them."""
    low, high = sorted(axis.get_view_interval())
    span = high - low
    drawn, every = [], set()
    for minor in (False, True):
        for location, label in zip(
            axis.get_ticklocs(minor=minor), axis.get_ticklabels(minor=minor), strict=False
        ):
            every.add(id(label))
            inside = low - 1e-9 * span <= location <= high + 1e-9 * span
            if inside and label.get_visible() and label.get_text().strip():
                drawn.append(label)
    return drawn, every


def _overlaps(labels: list[Text], renderer: RendererBase) -> list[str]:
    boxes = sorted(
        ((label.get_text(), label.get_window_extent(renderer)) for label in labels),
        key=lambda item: (item[1].x0, item[1].y0),
    )
    found = []
    for (first, a), (second, b) in itertools.pairwise(boxes):
        inner = Bbox.from_extents(
            a.x0 + SLACK_PX, a.y0 + SLACK_PX, a.x1 - SLACK_PX, a.y1 - SLACK_PX
        )
        if inner.overlaps(b):
            found.append(f"tick labels overlap: {first!r} and {second!r}")
    return found


def layout_problems(figure: Figure) -> list[str]:
    """Each text drawn that leaves the page, and each pair of an axis's tick labels that
    overlap, as a line naming the text. The figure is laid out again at its own dots per
    inch first (a legend keeps the places of the last draw, at the file's)."""
    figure.draw_without_rendering()
    renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]
    page = figure.bbox
    problems: list[str] = []
    ticks: set[int] = set()
    drawn: list[Text] = []
    for axis in figure.findobj(Axis):
        labels, every = _tick_labels(axis)
        ticks |= every
        drawn += labels
        problems += _overlaps(labels, renderer)
    texts = [
        text
        for text in figure.findobj(Text)
        if id(text) not in ticks and text.get_visible() and text.get_text().strip()
    ]
    for text in texts + drawn:
        box = text.get_window_extent(renderer)
        if (
            box.x0 < page.x0 - SLACK_PX
            or box.x1 > page.x1 + SLACK_PX
            or box.y0 < page.y0 - SLACK_PX
            or box.y1 > page.y1 + SLACK_PX
        ):
            problems.append(f"off the page: {text.get_text()!r}")
    return problems
