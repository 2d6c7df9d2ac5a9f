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


#: Windows that touch (radii at the bound: half the distance between carriers) are not
#: overlapping: a relative tolerance on the radii, for the labelled carriers drawn
#: being the refined ones, a fraction of a bin from those the radii were set from.
_TOUCHING = 0.02


def window_warnings(
    labelled: Mapping[str, Carrier],
    radius: float,
    predicted: Mapping[str, Carrier] | None = None,
    radii: Mapping[str, float] | None = None,
) -> list[str]:
    """Return one line per problem of the labelled windows, for the operator to read.

    Flags windows that overlap each other or each other's twins, overlap the zero
    order (a window reaching past half its carrier's frequency), or cross the Nyquist
    edge, and predicted carriers beyond Nyquist (aliased: they appear folded back).

    Parameters
    ----------
    labelled, predicted : mapping of str to (float, float)
        Carriers, cycles per pixel.
    radius : float
        Window radius of a labelled peak without one in ``radii``, cycles per pixel.
    radii : mapping of str to float, optional
        Each labelled peak's window radius in use, cycles per pixel.
    """
    problems: list[str] = []
    items = list(labelled.items())
    size = {name: (radii or {}).get(name, radius) * (1 - _TOUCHING) for name, _ in items}
    for i, (name, f) in enumerate(items):
        if math.hypot(*f) < 2 * size[name]:
            problems.append(f"{name} window overlaps the zero order (|f| < 2 r)")
        if max(abs(f[0]), abs(f[1])) + size[name] > 0.5:
            problems.append(f"{name} window crosses the Nyquist edge (aliasing)")
        for other, g in items[i + 1 :]:
            reach = size[name] + size[other]
            if math.dist(f, g) < reach:
                problems.append(f"{name} and {other} windows overlap")
            elif math.dist(f, (-g[0], -g[1])) < reach:
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
