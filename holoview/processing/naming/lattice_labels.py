"""The lattice from the operator's labels, checked against itself and the best automatic one.

Two labelled peaks that span the lattice fix it: exactly, modulo 1, for a unimodular
pair (RB1 and FB1, RF and FB1, RB1 and RF, RB1 and RB2, ...); a pair of determinant
``d`` (RF and RB2: 2) leaves ``d^2`` bases, of which the one explaining the most peaks
is kept. Further labels must sit where it puts them. The labels are then held against
the lattices found without them: one that explains at least
:data:`~holoview.processing.naming.lattice_search.CONTRADICTION_MARGIN` more, by the carriers
alone and with the model's brightness order both, and names a labelled peak otherwise
(or on its other twin), makes that label an error.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from holoview.errors import InputError
from holoview.processing.fourier.windows import wrap_frequency
from holoview.processing.naming.lattice_geometry import Basis, Point, point_of
from holoview.processing.naming.lattice_search import (
    CONTRADICTION_MARGIN,
    Candidate,
    Fitter,
    auto_candidates,
)
from holoview.processing.peaks.snapping import bin_distance
from holoview.processing.peaks.snapping import snap as snap_carrier

__all__ = ["Anchor", "LabelContradictionError", "from_labels", "snap_labels"]


class LabelContradictionError(InputError):
    """Labels the lattice contradicts: another peak's name, the wrong twin, one point twice.

    Attributes
    ----------
    label : str
        The label named (the first that the lattice calls otherwise).
    """

    def __init__(self, message: str, label: str) -> None:
        super().__init__(message)
        self.label = label


@dataclass(frozen=True)
class Anchor:
    """A labelled peak: its label's lattice point, the detected peak, and whether the
    label was given on that peak's other twin."""

    label: str
    point: Point
    peak: int
    twin: bool


def snap_labels(
    labels: Mapping[str, tuple[float, float]],
    carriers: NDArray[np.float64],
    shape: tuple[int, int],
    *,
    n1: float,
    n2: float,
    snap: float,
) -> list[Anchor]:
    """Snap each labelled position to the nearest detected peak on either twin.

    Parameters
    ----------
    labels : mapping of str to (fx, fy)
        Labels and positions, cycles/pixel, on each label's stored twin.
    carriers : ndarray, shape (M, 2)
        Detected carriers, cycles/pixel.
    shape : tuple of int
        Frame ``(rows, cols)``.
    n1, n2 : float
        Refractive indices.
    snap : float
        Largest distance from a position to its peak, FFT bins.

    Raises
    ------
    InputError
        A label that names no lattice point, a position that is not finite or is near
        no detected peak, two labels on one peak or one lattice point.
    """
    anchors: list[Anchor] = []
    for label, position in labels.items():
        point = point_of(label, n1, n2)
        click = np.asarray(position, dtype=np.float64)
        if click.shape != (2,) or not np.all(np.isfinite(click)):
            raise InputError(f"labelled position of {label!r} must be finite (fx, fy)")
        found = snap_carrier(click, carriers, shape, snap)
        if found is None:
            raise InputError(
                f"labelled peak {label} at ({click[0]:+.4f}, {click[1]:+.4f}) cycles/pixel "
                f"matches no detected peak within {snap:g} bins"
            )
        for other in anchors:
            if other.peak == found[0]:
                raise InputError(f"labels {other.label} and {label} name the same detected peak")
            if other.point == point:
                raise LabelContradictionError(
                    f"labels {other.label} and {label} name one lattice point", label
                )
        anchors.append(Anchor(label, point, found[0], found[1]))
    return anchors


def label_bases(anchors: list[Anchor], carriers: NDArray[np.float64]) -> list[Basis]:
    """Every basis the first two independent anchors fix (several when folded twice over)."""
    for a, b in itertools.combinations(anchors, 2):
        matrix = np.array([a.point, b.point], dtype=np.float64)
        det = round(abs(np.linalg.det(matrix)))
        if det == 0:
            continue
        signs = [-1.0 if x.twin else 1.0 for x in (a, b)]
        observed = np.array([signs[0] * carriers[a.peak], signs[1] * carriers[b.peak]])
        inverse = np.linalg.inv(matrix)
        bases, seen = [], set()
        for shift in itertools.product(range(det), repeat=4):
            solution = wrap_frequency(inverse @ (observed + np.reshape(shift, (2, 2))))
            key = tuple(np.round(solution.ravel() * 1e9).astype(np.int64))
            if key not in seen:
                seen.add(key)
                bases.append(Basis.from_arrays(solution[0], solution[1]))
        return bases
    names = ", ".join(a.label for a in anchors)
    raise InputError(
        f"the labels {names} do not fix the lattice (they lie along one line of it): label "
        "two of RF, RB1, FB1, RB2 such as RB1 and FB1"
    )


def check_anchors(candidate: Candidate, anchors: list[Anchor], fitter: Fitter) -> None:
    """Raise when a labelled peak is not where the basis of the labels puts it."""
    by_peak = {m.peak: m for m in candidate.matches}
    for anchor in anchors:
        found = by_peak.get(anchor.peak)
        if found is not None and found.target.point == anchor.point and found.twin == anchor.twin:
            continue
        where = candidate.basis.carrier(anchor.point)
        if found is not None and found.target.point == anchor.point:
            raise LabelContradictionError(
                f"label {anchor.label} contradicts the lattice of the other labels: it is "
                f"given on the wrong twin; label ({where[0]:+.4f}, {where[1]:+.4f}) "
                "cycles/pixel instead",
                anchor.label,
            )
        distance = float(
            min(
                bin_distance(fitter.carriers[anchor.peak] - np.asarray(where), fitter.shape),
                bin_distance(fitter.carriers[anchor.peak] + np.asarray(where), fitter.shape),
            )
        )
        raise LabelContradictionError(
            f"label {anchor.label} contradicts the lattice of the other labels: it puts "
            f"{anchor.label} at ({where[0]:+.4f}, {where[1]:+.4f}) cycles/pixel, "
            f"{distance:.1f} bins from the peak labelled",
            anchor.label,
        )


def contradiction(best: Candidate, chosen: Candidate, anchors: list[Anchor]) -> None:
    """Raise naming the label that the lattice explaining the most peaks calls otherwise.

    The global twin of an automatic naming is free: it is aligned with most labels, and a
    label on the other twin than the rest is named (both halves where there is no majority).
    """
    named = {m.peak: m for m in best.matches}
    scores = f"it explains {best.score:g} against {chosen.score:g} with the labels given"
    for anchor in anchors:
        theirs = named.get(anchor.peak)
        if theirs is None:
            raise LabelContradictionError(
                f"label {anchor.label} contradicts the lattice: the peak labelled "
                f"{anchor.label} is off the lattice that explains the most peaks ({scores})",
                anchor.label,
            )
        if theirs.target.label != anchor.label:
            raise LabelContradictionError(
                f"label {anchor.label} contradicts the lattice: the peak labelled "
                f"{anchor.label} is {theirs.target.label} on the lattice that explains the "
                f"most peaks ({scores})",
                anchor.label,
            )
    flips = [named[a.peak].twin != a.twin for a in anchors]
    if 2 * sum(flips) == len(flips):  # no majority: either half may be the wrong one
        halves = [
            ", ".join(a.label for a, f in zip(anchors, flips, strict=True) if f == side)
            for side in (flips[0], not flips[0])
        ]
        raise LabelContradictionError(
            f"labels {halves[0]} and {halves[1]} contradict the lattice: they are given on "
            f"opposite twins; label {halves[0]} or {halves[1]} on its other twin ({scores})",
            anchors[0].label,
        )
    if 2 * sum(flips) > len(flips):
        flips = [not f for f in flips]
    for anchor, flip in zip(anchors, flips, strict=True):
        if flip:
            others = ", ".join(a.label for a, f in zip(anchors, flips, strict=True) if not f)
            raise LabelContradictionError(
                f"label {anchor.label} contradicts the lattice: it is given on the other "
                f"twin than {others}; label its other twin ({scores})",
                anchor.label,
            )


def _fit_labels(anchors: list[Anchor], fitter: Fitter) -> Candidate:
    """The best lattice the labels fix where every label sits where it puts it."""
    fits: list[tuple[Candidate | None, InputError | None]] = []
    for basis in label_bases(anchors, fitter.carriers):
        try:
            candidate = fitter.fit(basis)
            check_anchors(candidate, anchors, fitter)
        except InputError as exc:
            fits.append((None, exc))
        else:
            fits.append((candidate, None))
    good = [c for c, _ in fits if c is not None]
    if not good:
        raise next(exc for _, exc in fits if exc is not None)
    return max(good, key=lambda c: (c.score, -c.penalty))


def _odd_one_out(anchors: list[Anchor], fitter: Fitter) -> LabelContradictionError | None:
    """With three labels or more that disagree: the one the others' best lattice calls wrong.

    The first two labels fix the lattice the rest are held to, so a wrong first label
    would otherwise be blamed on a right third one.
    """
    if len(anchors) < 3:
        return None
    found: list[tuple[float, LabelContradictionError]] = []
    for odd in anchors:
        rest = [a for a in anchors if a is not odd]
        try:
            candidate = _fit_labels(rest, fitter)
        except InputError:
            continue
        try:
            check_anchors(candidate, [odd], fitter)
        except LabelContradictionError as exc:
            found.append((candidate.score, exc))
    return max(found, key=lambda item: item[0])[1] if found else None


def from_labels(
    anchors: list[Anchor], fitter: Fitter, n1: float, n2: float
) -> tuple[Candidate, tuple[str, ...]]:
    """The labels' lattice, checked against itself and against the best automatic one."""
    try:
        chosen = _fit_labels(anchors, fitter)
    except LabelContradictionError as exc:
        raise _odd_one_out(anchors, fitter) or exc from None
    anchored = {a.peak for a in anchors}
    others = [m for m in chosen.matches if m.peak not in anchored]
    n_peaks = fitter.carriers.shape[0]
    names = ", ".join(a.label for a in anchors)
    # Two labels fix a lattice and nothing checks it but the other peaks; three or more
    # that sit where one lattice puts them check each other. Those then stand though
    # the other peaks are none of its points: on a wavy surface they are the waves'
    # sidebands, and a weak family the detection misses on such frames is kept.
    if not others and n_peaks > len(anchors) and len(anchors) < 3:
        raise InputError(
            f"the lattice of {names} explains none of the other {n_peaks - len(anchors)} "
            "detected peaks: check the labels and their twins"
        )
    # A lattice contradicts the labels when it explains more peaks both by the carriers
    # alone and with the brightness order: either alone may favour a wrong naming (a
    # spurious product, a bench departing from the model's amplitudes).
    better = [
        c
        for c in auto_candidates(fitter, n1, n2)
        if c.score >= chosen.score + CONTRADICTION_MARGIN
        and c.merit >= chosen.merit + CONTRADICTION_MARGIN
    ]
    if better:
        contradiction(max(better, key=lambda c: c.merit), chosen, anchors)
    hints = []
    for anchor in anchors[1:]:
        flipped = [replace(a, twin=not a.twin) if a is anchor else a for a in anchors]
        try:
            other = max(
                (fitter.fit(b) for b in label_bases(flipped, fitter.carriers)),
                key=lambda c: c.score,
            )
        except (InputError, ValueError):
            continue
        # better both by the carriers and with the brightness order, as a contradiction
        # must be: on a wavy surface a twin flipped explains one sideband more by the
        # carriers alone, and a brightness order worse (7 of 160 frames of the tests'
        # travelling waves with RB1 and FB1 labelled)
        if other.score > chosen.score and other.merit > chosen.merit:
            hints.append(anchor.label)
    return chosen, tuple(hints)
