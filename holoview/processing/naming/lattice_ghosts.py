"""Beam-splitter ghosts on the carrier lattice: copies of its points shifted by one offset.

A ghost copies one arm's field with an extra tilt (paper section 4: partial reflections
at the beam splitter's faces), so its peaks repeat lattice points ``P`` at ``P + g``
or ``P - g`` with the alpha of ``P`` (``g`` the tilt's carrier). After the lattice is
chosen, :func:`find_ghosts` seeks offsets among the peaks left over: one that repeats
two or more of them, including RB1 (every ghost copies it, as its brightest copy),
whose copies of RF and the RB_j are dimmer than their originals by one factor, and that
is itself neither near the zero order nor a lattice point (left-over products differ by
lattice vectors and would pair up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from holoview.processing.fourier.windows import wrap_frequency
from holoview.processing.naming.lattice_geometry import (
    RANK_FIRST,
    Basis,
    Match,
    Point,
    SearchPoint,
)
from holoview.processing.naming.lattice_search import Fitter
from holoview.processing.peaks.snapping import bin_distance

__all__ = ["Ghost", "find_ghosts"]

#: Most ghost offsets sought, and the fewest leftover peaks one must explain.
MAX_GHOSTS, MIN_GHOST_SUPPORT = 2, 2

#: The brightest leftover peaks a ghost offset is sought from (a ghost's brightest copy,
#: of RB1, is among them).
GHOST_SEEDS = 8

#: The best-supported offsets checked in full (brightness ratios, rivals) per ghost.
GHOST_TRIALS = 24

#: Largest spread (ratio) of a ghost's copy-to-original brightness over RF and the RB_j
#: (one field amplitude for all of them in the model; amplitude estimates and overlaps
#: allowed for). The FB_j are left out: their originals cancel, their copies need not.
GHOST_RATIO_SPREAD = 4.0


@dataclass(frozen=True)
class Ghost:
    """A leftover peak on a ghost offset: ``point + multiple * offset``.

    ``ambiguous``: another offset explains as many leftover peaks with other names (a
    ghost's copy of RB1 and its term against its own arm can swap when nothing else of
    it shows; the PCA tells them apart: the latter does not move).
    """

    point: Point
    index: int
    multiple: int
    residual_bins: float
    twin: bool
    ambiguous: bool = False


def find_ghosts(
    basis: Basis,
    fitter: Fitter,
    leftover: list[int],
    *,
    max_order: int,
    higher: tuple[SearchPoint, ...],
    matched: list[Match],
) -> tuple[list[tuple[float, float]], dict[int, Ghost]]:
    """Offsets that repeat lattice points onto two or more leftover peaks.

    The offset must repeat RB1 (every ghost does, as its brightest copy), and its copies
    of RF and the RB_j must be dimmer than their originals by one factor (within
    :data:`GHOST_RATIO_SPREAD`: the ghost's field amplitude). An offset on
    the lattice itself is no ghost (leftover products differ by lattice vectors, so
    they would pair up), nor is one near the zero order.
    """
    bases = [(0, 0)] + [
        p.point for p in fitter.points if p.rank == RANK_FIRST and max(p.point[0], 1) <= max_order
    ]
    lattice = np.array(bases, dtype=np.float64) @ basis.matrix
    originals = {m.target.point: m.peak for m in matched}
    offsets: list[tuple[float, float]] = []
    assigned: dict[int, Ghost] = {}
    remaining = list(leftover)
    shape, tol = fitter.shape, fitter.tolerance
    for g_index in range(MAX_GHOSTS):
        if len(remaining) < MIN_GHOST_SUPPORT:
            break
        c = fitter.carriers[remaining]
        seeds = c[np.argsort(-fitter.brightness[remaining], kind="stable")[:GHOST_SEEDS]]
        trials = np.concatenate(
            [
                wrap_frequency(w * (s * seeds[:, None, :] - lattice[None])).reshape(-1, 2)
                for s in (1.0, -1.0)
                for w in (1.0, -1.0)
            ]
        )
        trials = trials[bin_distance(trials, shape) > 3 * tol]
        grid = np.array([p.point for p in (*fitter.points, *higher)], dtype=np.float64)
        on_grid = grid @ basis.matrix
        off = np.minimum(
            bin_distance(trials[:, None] - on_grid[None], shape),
            bin_distance(trials[:, None] + on_grid[None], shape),
        ).min(axis=1)
        trials = trials[off > tol]
        if trials.shape[0] == 0:
            break
        shifted = np.concatenate(
            [lattice[None] + trials[:, None], lattice[None] - trials[:, None]], axis=1
        )
        every = np.minimum(
            bin_distance(c[None, :, None] - shifted[:, None], shape),
            bin_distance(-c[None, :, None] - shifted[:, None], shape),
        )
        counts = np.count_nonzero(every.min(axis=2) <= tol, axis=1)
        # every ghost copies RB1 (R~g B1 or R B1~g), its brightest copy: it must be there
        rb1 = bases.index((1, -1))
        copies = every[:, :, [rb1, rb1 + len(bases)]].min(axis=(1, 2))
        counts = np.where(copies <= tol, counts, 0)
        best, rival, top = None, False, 0
        names: frozenset[tuple[int, tuple[int, int]]] = frozenset()
        for k in np.argsort(-counts, kind="stable")[:GHOST_TRIALS]:
            if counts[k] < MIN_GHOST_SUPPORT or (best is not None and counts[k] < top):
                break
            support = _ghost_support(trials[k], c, lattice, shape, tol)
            if not _copies_agree(support, remaining, bases, originals, fitter.brightness):
                continue
            if best is None:
                best, top, names = trials[k], counts[k], _names(support, bases)
            elif _names(support, bases) != names:
                rival = True  # another offset explains as many peaks with other names
                break
        if best is None:
            break
        distance, which, multiple, twin = _ghost_support(best, c, lattice, shape, tol)
        offsets.append((float(best[0]), float(best[1])))
        for j, peak in enumerate(remaining):
            if np.isfinite(distance[j]):
                assigned[peak] = Ghost(
                    bases[int(which[j])],
                    g_index,
                    int(multiple[j]),
                    float(distance[j]),
                    bool(twin[j]),
                    rival,
                )
        remaining = [p for p in remaining if p not in assigned]
    return offsets, assigned


def _names(
    support: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]],
    bases: list[Point],
) -> frozenset[tuple[int, Point]]:
    """Which leftover peak an offset puts on which lattice point."""
    distance, which = support[0], support[1]
    return frozenset(
        (j, bases[int(which[j])]) for j in range(distance.size) if np.isfinite(distance[j])
    )


def _copies_agree(
    support: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]],
    remaining: list[int],
    bases: list[Point],
    originals: dict[Point, int],
    brightness: NDArray[np.float64],
) -> bool:
    """Whether a ghost's copies of RF and the RB_j share one brightness ratio."""
    distance, which = support[0], support[1]
    ratios = []
    for j, peak in enumerate(remaining):
        point = bases[int(which[j])]
        if np.isfinite(distance[j]) and point[1] != 0 and point in originals:
            ratios.append(brightness[peak] / brightness[originals[point]])
    return not ratios or max(ratios) <= GHOST_RATIO_SPREAD * min(ratios)


def _ghost_support(
    g: NDArray[np.float64],
    c: NDArray[np.float64],
    lattice: NDArray[np.float64],
    shape: tuple[int, int],
    tol: float,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
    """Per leftover peak: distance to the nearest ``P +- g`` (inf beyond ``tol``), which."""
    shifted = np.concatenate([lattice + g, lattice - g])
    direct = bin_distance(c[:, None, :] - shifted[None], shape)
    mirrored = bin_distance(-c[:, None, :] - shifted[None], shape)
    both = np.minimum(direct, mirrored)
    k = np.argmin(both, axis=1)
    rows = np.arange(c.shape[0])
    distance = np.where(both[rows, k] <= tol, both[rows, k], np.inf)
    n = lattice.shape[0]
    multiple = np.where(k < n, 1, -1)
    return distance, k % n, multiple, mirrored[rows, k] < direct[rows, k]
