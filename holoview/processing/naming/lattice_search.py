"""The automatic basis of the carrier lattice: candidates, their fit, and the choice.

Every pair of the brightest detected peaks, read as every pair of
:data:`ANCHOR_FAMILIES` that spans the lattice (a unimodular pair, so the basis follows
exactly modulo 1), on both relative twins, gives a candidate basis. All are scored at
once on a coarse match (the tolerance widening with a point's distance from the
origin); the best :data:`KEEP_CANDIDATES` distinct ones are refined on the peaks they
explain (:func:`holoview.processing.naming.lattice_geometry.refine`) and scored again: 1 per
first-order family, 0.5 per harmonic, 0.25 per intermodulation product
(:data:`RANK_WEIGHTS`). :func:`choose` takes the best, the PCA and the model's
brightness order telling apart candidates within :data:`CONTENDER_MARGIN` of it
(:mod:`holoview.processing.naming.lattice`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from holoview.processing.fourier.windows import wrap_frequency
from holoview.processing.naming.lattice_brightness import missing_brighter, violations
from holoview.processing.naming.lattice_geometry import (
    Basis,
    LatticeKind,
    Match,
    Point,
    SearchPoint,
    match,
    point_of,
    refine,
)
from holoview.processing.naming.lattice_pca import PcaEvidence
from holoview.processing.peaks.snapping import bin_distance

__all__ = [
    "ANCHOR_FAMILIES",
    "CONTENDER_MARGIN",
    "CONTRADICTION_MARGIN",
    "RANK_WEIGHTS",
    "Candidate",
    "Fitter",
    "auto_candidates",
    "choose",
    "orient",
    "signature",
]

#: The brightest detected peaks tried as the two that fix an automatic basis.
ANCHOR_PEAKS = 6

#: The families the anchor peaks are tried as (any two that span the lattice).
ANCHOR_FAMILIES = ("RF", "RB1", "FB1", "RB2", "FB2", "RB3")

#: Score of a peak explained as a first order, a harmonic and an intermodulation product.
RANK_WEIGHTS = (1.0, 0.5, 0.25)

#: Candidates within this score of the best are told apart by the PCA, then brightness.
CONTENDER_MARGIN = 0.5

#: Labels lose to a lattice that explains at least this much more by the carriers alone:
#: one more first order, or one peak it names first order where the labels' lattice can
#: only call it a product (1 - 0.25).
CONTRADICTION_MARGIN = 0.75

#: Candidate bases kept from the coarse scoring for the full fit (of at most twice as
#: many tried: duplicates and collapsed bases are skipped).
KEEP_CANDIDATES = 40


@dataclass(frozen=True)
class Candidate:
    """A fitted basis, its matches and what ranks it."""

    basis: Basis
    matches: tuple[Match, ...]
    score: float
    penalty: int
    violations: int
    agreement: int = 0
    """A fitted naming.

    Attributes
    ----------
    basis : Basis
    matches : tuple of Match
    score : float
        Peaks explained, by rank (:data:`RANK_WEIGHTS`).
    penalty : int
        Clear departures from the model's brightness order
        (:mod:`holoview.processing.naming.lattice_brightness`).
    violations : int
        Pairs out of that order at all (a tie-break).
    agreement : int
        Peaks whose PCA prefactor agrees with the naming, less those that disagree.
    """

    @property
    def merit(self) -> float:
        """The score less one per clear violation of the brightness order."""
        return self.score - self.penalty


def score(matches: Sequence[Match]) -> float:
    """The peaks a naming explains, weighted by rank (:data:`RANK_WEIGHTS`)."""
    return float(sum(RANK_WEIGHTS[m.target.rank] for m in matches))


def weights(matches: Sequence[Match], n_peaks: int) -> NDArray[np.float64]:
    """Per detected peak, its rank's weight in the basis fit (0 when unmatched)."""
    w = np.zeros(n_peaks)
    for m in matches:
        w[m.peak] = RANK_WEIGHTS[m.target.rank]
    return w


def degenerate(basis: Basis, shape: tuple[int, int], tolerance: float) -> bool:
    """Whether RF, FB1 or RB1 falls on the zero order (a collapsed basis)."""
    points = np.array([(0, 1), (1, -1), (1, 0)], dtype=np.float64)
    distance = bin_distance(points @ basis.matrix, shape)
    return bool(np.min(distance) < 2 * tolerance)


class Fitter:
    """Matching and refinement of bases against one set of detected peaks."""

    def __init__(
        self,
        carriers: NDArray[np.float64],
        shape: tuple[int, int],
        points: tuple[SearchPoint, ...],
        tolerance: float,
        brightness: NDArray[np.float64],
    ) -> None:
        self.carriers = carriers
        self.shape = shape
        self.points = points
        self.tolerance = tolerance
        self.brightness = brightness

    def fit(self, basis: Basis) -> Candidate:
        """Match with a widened tolerance, refine, match and refine again, match."""
        n = self.carriers.shape[0]
        found = match(basis, self.carriers, self.shape, self.points, self.tolerance, grow=True)
        for _ in range(2):
            basis = refine(basis, self.carriers, found, weights(found, n))
            found = match(basis, self.carriers, self.shape, self.points, self.tolerance)
        clear, reversed_ = violations(found, self.brightness)
        clear += missing_brighter(found, basis, self.brightness)
        return Candidate(basis, tuple(found), score(found), clear, reversed_)

    def coarse_scores(self, bases: NDArray[np.float64]) -> NDArray[np.float64]:
        """Score many bases ``(H, 2, 2)`` at once, without refinement or conflicts."""
        coords = np.array([p.point for p in self.points], dtype=np.float64)
        ranks = np.array([p.rank for p in self.points])
        reach = np.abs(coords).sum(axis=1)
        limit = self.tolerance * np.clip(reach / 2.0, 1.0, 3.0)
        predicted = np.einsum("sk,hkd->hsd", coords, bases)
        c = self.carriers
        direct = bin_distance(c[None, :, None, :] - predicted[:, None], self.shape)
        mirrored = bin_distance(-c[None, :, None, :] - predicted[:, None], self.shape)
        inside = np.minimum(direct, mirrored) <= limit[None, None]
        weight = np.where(inside, np.asarray(RANK_WEIGHTS)[ranks][None, None], 0.0)
        return weight.max(axis=2).sum(axis=1)


def anchor_pairs(n1: float, n2: float) -> list[tuple[Point, Point]]:
    """Ordered pairs of :data:`ANCHOR_FAMILIES` points that span the lattice (determinant 1)."""
    points = [point_of(label, n1, n2) for label in ANCHOR_FAMILIES]
    return [
        (a, b) for a, b in itertools.permutations(points, 2) if abs(a[0] * b[1] - a[1] * b[0]) == 1
    ]


def auto_candidates(fitter: Fitter, n1: float, n2: float) -> list[Candidate]:
    """Every basis two bright peaks fix, fitted, best first (module documentation)."""
    c = fitter.carriers
    order = np.argsort(-fitter.brightness, kind="stable")[:ANCHOR_PEAKS]
    bases = []
    for i, k in itertools.combinations(order, 2):
        for a, b in anchor_pairs(n1, n2):
            inverse = np.linalg.inv(np.array([a, b], dtype=np.float64))
            for sign in (1.0, -1.0):
                bases.append(np.rint(inverse) @ np.array([c[i], sign * c[k]]))
    if not bases:
        return []
    stack = wrap_frequency(np.array(bases))
    scores = fitter.coarse_scores(stack)
    chosen = np.argsort(-scores, kind="stable")
    fitted: list[Candidate] = []
    seen: set[frozenset[tuple[int, str, bool]]] = set()
    for h in chosen[: 2 * KEEP_CANDIDATES]:
        if len(fitted) >= KEEP_CANDIDATES or scores[h] <= 0:
            break
        basis = Basis.from_arrays(stack[h, 0], stack[h, 1])
        if degenerate(basis, fitter.shape, fitter.tolerance):
            continue
        candidate = fitter.fit(basis)
        key = signature(candidate)
        if key in seen or not candidate.matches:
            continue
        seen.add(key)
        fitted.append(candidate)
    fitted.sort(key=lambda x: (-x.merit, x.violations))
    return fitted


def signature(candidate: Candidate) -> frozenset[tuple[int, str, bool]]:
    """The naming, up to the global twin (flip so that the first matched peak is direct)."""
    if not candidate.matches:
        return frozenset()
    flip = candidate.matches[0].twin
    return frozenset((m.peak, m.target.label, m.twin != flip) for m in candidate.matches)


def orient(candidate: Candidate, reference: int | None) -> tuple[Candidate, str]:
    """Fix the global twin: the reference peak (if on the lattice), else RB1, else the
    brightest first order."""
    by_peak = {m.peak: m for m in candidate.matches}
    if reference is not None and reference in by_peak:
        keeper, how = by_peak[reference], "reference"
    else:
        firsts = [m for m in candidate.matches if m.target.kind is LatticeKind.FIRST_ORDER]
        rb1 = [m for m in firsts if m.target.label == "RB1"]
        keeper = (rb1 or firsts or list(candidate.matches))[0]
        how = "convention"
    if not keeper.twin:
        return candidate, how
    flipped = tuple(replace(m, twin=not m.twin) for m in candidate.matches)
    return replace(candidate, basis=candidate.basis.flipped(), matches=flipped), how


def choose(
    candidates: list[Candidate],
    evidence: PcaEvidence | None,
    n_peaks: int,
    notes: list[str],
) -> tuple[Candidate, float]:
    """The best candidate: score, then PCA agreement, then brightness order."""
    top = candidates[0].merit
    contenders = [c for c in candidates if c.merit >= top - CONTENDER_MARGIN]
    if evidence is not None:
        contenders = [
            replace(c, agreement=evidence.check(c.matches, n_peaks).net) for c in contenders
        ]
    contenders.sort(key=lambda c: (-c.agreement, -c.merit, c.violations))
    best = contenders[0]
    mine = signature(best)
    others = [c.merit for c in candidates if signature(c) != mine]
    margin = best.merit - max(others) if others else math.inf
    if margin < CONTRADICTION_MARGIN and evidence is None:
        notes.append(
            f"the carriers alone leave another naming {margin:g} behind: named by the "
            "brightness order; confirm with the PCA or label two peaks"
        )
    return best, margin
