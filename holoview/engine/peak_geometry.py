"""Geometry of the windows around labelled peaks: overlaps, aliases, a radius that swallows a peak.

Pure functions on carriers in cycles per pixel (``fx`` along columns, ``fy`` along
rows): the warnings the spectrum view shows while the operator aligns and labels, and
the check that refuses a window radius that would take in a neighbouring peak.
Snapping a click or a carrier to a peak is :func:`holoview.engine.resolve.snap`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

Carrier = tuple[float, float]


def with_twins(peaks: Sequence[Carrier]) -> list[Carrier]:
    """Return every peak and its conjugate twin at ``(-fx, -fy)``, without duplicates."""
    out: list[Carrier] = []
    for fx, fy in peaks:
        for candidate in ((fx, fy), (-fx, -fy)):
            if all(math.dist(candidate, seen) > 1e-9 for seen in out):
                out.append(candidate)
    return out


def _aliased(f: float) -> float:
    return (f + 0.5) % 1.0 - 0.5


def window_warnings(
    labelled: Mapping[str, Carrier], radius: float, predicted: Mapping[str, Carrier] | None = None
) -> list[str]:
    """Return one line per problem of the labelled windows, for the operator to read.

    Flags windows of radius ``radius`` (cycles per pixel) that overlap each other or
    each other's twins, overlap the zero order, or cross the Nyquist edge, and
    predicted carriers beyond Nyquist (aliased: they appear folded back).
    """
    problems: list[str] = []
    items = list(labelled.items())
    for i, (name, f) in enumerate(items):
        if math.hypot(*f) < 2 * radius:
            problems.append(f"{name} window overlaps the zero order (|f| < 2 r)")
        if max(abs(f[0]), abs(f[1])) + radius > 0.5:
            problems.append(f"{name} window crosses the Nyquist edge (aliasing)")
        for other, g in items[i + 1 :]:
            if math.dist(f, g) < 2 * radius:
                problems.append(f"{name} and {other} windows overlap")
            elif math.dist(f, (-g[0], -g[1])) < 2 * radius:
                problems.append(f"{name} overlaps the twin of {other}")
    for name, (fx, fy) in (predicted or {}).items():
        if max(abs(fx), abs(fy)) > 0.5:
            problems.append(
                f"predicted {name} at ({fx:+.3f}, {fy:+.3f}) is beyond Nyquist: aliased to "
                f"({_aliased(fx):+.3f}, {_aliased(fy):+.3f})"
            )
    return problems


def swallowed_neighbour(centre: Carrier, radius: float, peaks: Sequence[Carrier]) -> Carrier | None:
    """Return a peak (or twin) other than ``centre`` inside the window, or None.

    A window that contains a neighbouring carrier mixes two holograms; the view
    refuses such a radius.
    """
    for p in with_twins(peaks):
        d = math.dist(p, centre)
        if 1e-6 < d <= radius:
            return p
    return None
