"""The carrier lattice: every peak of a multiplexed spectrum as two integers.

Every first-order family is an integer combination of two carriers (paper eq. 6,
docs/design.md "The lattice"): ``f_FB_j = j f_FB1`` and ``f_RB_j = j f_FB1 - f_RF``. A point
of the lattice is written ``(fb1, rf)``, its carrier ``fb1 * f_FB1 + rf * f_RF``
(cycles/pixel, folded into ``[-0.5, 0.5)`` as the camera samples it), and its prefactor
follows exactly as the same combination of ``alpha_FB1 = n2`` and ``alpha_RF = n1``:

==========================  ================  ====================
point ``(fb1, rf)``         label             alpha
==========================  ================  ====================
``(0, 1)``                  ``RF``            ``n1``
``(j, -1)``                 ``RBj``           ``j n2 - n1``
``(j, 0)``                  ``FBj``           ``j n2`` (also B_(l) B_(l-j))
``k (a, b)``                ``kX``            ``k alpha_X`` (harmonic)
``P + Q``, ``P - Q``        ``P+Q``, ``P-Q``  summed (intermodulation)
==========================  ================  ====================

The camera's nonlinearity makes the harmonics and the intermodulation products (every
``f +- g`` of two carriers); they are lattice points too, with the summed alpha. The
reference-arm phase enters a point ``rf`` times (RF once, every RB_j negatively, no
FB_j): :func:`coupling`. A point and its negative are the two twins of one peak; the
*stored* twin is the one with a positive alpha (docs/design.md, twin rule), which needs
``n2 > n1``.

A :class:`Basis` (the two carriers) predicts every point; :func:`match` names detected
peaks by their nearest point on either twin, with the residual in FFT bins
(``fx * cols``, ``fy * rows``, wrapped), and :func:`refine` fits the basis to every
matched peak by least squares. Arithmetic is modulo 1 cycle/pixel throughout, so a
point past Nyquist is predicted where the camera folds it.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError
from holoview.processing.fourier.windows import wrap_frequency
from holoview.processing.peaks.snapping import bin_distance

__all__ = [
    "Basis",
    "LatticeKind",
    "LatticePeak",
    "Match",
    "Point",
    "SearchPoint",
    "alpha_at",
    "check_indices",
    "coupling",
    "describe",
    "higher_points",
    "match",
    "point_of",
    "point_of_family",
    "refine",
    "search_points",
    "stored",
]

#: A lattice point ``(fb1, rf)``: the carrier is ``fb1 * f_FB1 + rf * f_RF``.
Point = tuple[int, int]

#: Search rank of a first-order family, a harmonic and an intermodulation product:
#: a peak near two points takes the lower rank (first orders are the brightest).
RANK_FIRST, RANK_HARMONIC, RANK_PRODUCT, RANK_HIGHER = 0, 1, 2, 3

_FAMILY = re.compile(r"(RF)|(RB|FB)([1-9]\d*)|B([1-9]\d*)B([1-9]\d*)")
_HARMONIC = re.compile(r"([2-9]|[1-9]\d+)(.+)")


class LatticeKind(StrEnum):
    """What a peak is, by where it sits in the spectrum."""

    FIRST_ORDER = "first order"
    SECOND_ORDER = "second order"
    INTERMODULATION = "intermodulation"
    GHOST = "ghost"
    OFF_LATTICE = "off-lattice"


def check_indices(n1: float, n2: float) -> None:
    """Raise :class:`InputError` unless ``0 < n1 < n2`` (both finite)."""
    for name, value in (("n1", n1), ("n2", n2)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive finite number, got {value!r}")
    if n2 <= n1:
        raise InputError(
            f"n2 = {n2:g} must exceed n1 = {n1:g}: the lattice's twin rule (RB_j's alpha "
            "j n2 - n1 > 0) assumes a fluid denser than the medium above"
        )


def alpha_at(point: Point, n1: float, n2: float) -> float:
    """Return the prefactor of a lattice point: ``fb1 * n2 + rf * n1`` (dimensionless)."""
    return point[0] * n2 + point[1] * n1


def coupling(point: Point) -> int:
    """Return how many times the reference-arm phase enters the point (its ``rf``)."""
    return point[1]


def stored(point: Point, n1: float, n2: float) -> Point:
    """Return the twin of ``point`` whose alpha is positive (the stored twin)."""
    return point if alpha_at(point, n1, n2) > 0 else (-point[0], -point[1])


def _family_name(point: Point) -> str | None:
    """The first-order family at ``point`` (stored twin), or None."""
    fb1, rf = point
    if point == (0, 1):
        return "RF"
    if rf == -1 and fb1 >= 1:
        return f"RB{fb1}"
    if rf == 0 and fb1 >= 1:
        return f"FB{fb1}"
    return None


def _family_order(point: Point) -> int:
    """``j`` of RB_j and FB_j, 1 for RF."""
    return max(point[0], 1)


def describe(point: Point, n1: float, n2: float) -> tuple[str, LatticeKind]:
    """Return the label and the kind of a lattice point (either twin).

    Parameters
    ----------
    point : tuple of int
        ``(fb1, rf)``, not ``(0, 0)``.
    n1, n2 : float
        Refractive indices (they decide which twin is stored).

    Returns
    -------
    label : str
        ``"RF"``, ``"RB2"``, ``"FB1"``, a harmonic ``"2RB1"``, a product ``"RF+FB1"``
        or ``"RF-RB1"``, else ``"L(fb1,rf)"``.
    kind : LatticeKind
        First order, second order (a harmonic ``2X``) or intermodulation (products and
        higher harmonics).
    """
    if point == (0, 0):
        raise InputError("(0, 0) is the zero order, not a peak")
    p = stored(point, n1, n2)
    name = _family_name(p)
    if name is not None:
        return name, LatticeKind.FIRST_ORDER
    k = math.gcd(abs(p[0]), abs(p[1]))
    base = _family_name((p[0] // k, p[1] // k)) if k > 1 else None
    if base is not None:
        kind = LatticeKind.SECOND_ORDER if k == 2 else LatticeKind.INTERMODULATION
        return f"{k}{base}", kind
    families = [(0, 1)] + [(j, r) for j in range(1, 2 * abs(p[0]) + 3) for r in (-1, 0)]
    best: tuple[tuple[int, int, str], str] | None = None
    for i, a in enumerate(families):
        for b in families[i:]:
            for sign, symbol in ((1, "+"), (-1, "-")):
                total = (a[0] + sign * b[0], a[1] + sign * b[1])
                if total not in (p, (-p[0], -p[1])) or a == b:
                    continue
                first, second = (a, b) if sign == 1 or total == p else (b, a)
                label = f"{_family_name(first)}{symbol}{_family_name(second)}"
                key = (_family_order(a) + _family_order(b), 0 if sign == 1 else 1, label)
                if best is None or key < best[0]:
                    best = (key, label)
    if best is not None:
        return best[1], LatticeKind.INTERMODULATION
    return f"L({p[0]},{p[1]})", LatticeKind.INTERMODULATION


def _parse_family(text: str) -> Point | None:
    match_ = _FAMILY.fullmatch(text)
    if match_ is None:
        return None
    if match_.group(1):
        return (0, 1)
    if match_.group(2):
        j = int(match_.group(3))
        return (j, -1) if match_.group(2) == "RB" else (j, 0)
    high, low = int(match_.group(4)), int(match_.group(5))
    if high <= low:
        return None
    return (high - low, 0)


def point_of_family(label: str) -> Point | None:
    """Return the point of a first-order family (``"RF"``, ``"RB2"``, ``"B3B1"``), else None."""
    return _parse_family(label)


def point_of(label: str, n1: float, n2: float) -> Point:
    """Return the stored-twin lattice point a label names.

    Parameters
    ----------
    label : str
        ``"RF"``, ``"RBj"``, ``"FBj"``, ``"BlBj"`` (on FB_(l-j)), a harmonic ``"2RB1"``,
        or a product of two of those, ``"RF+FB1"`` or ``"RF-RB1"``.
    n1, n2 : float
        Refractive indices (they decide which twin is stored).

    Raises
    ------
    InputError
        For anything else (a ghost's label names no lattice point: its tilt is unknown).
    """
    if not isinstance(label, str):
        raise InputError(f"a peak label must be a string, got {label!r}")
    text = label.strip()
    for symbol, sign in (("+", 1), ("-", -1)):
        if symbol in text:
            left, _, right = text.partition(symbol)
            a, b = _parse_single(left, label), _parse_single(right, label)
            total = (a[0] + sign * b[0], a[1] + sign * b[1])
            if total == (0, 0):
                raise InputError(f"{label!r} is the zero order, not a peak")
            return stored(total, n1, n2)
    return stored(_parse_single(text, label), n1, n2)


def _parse_single(text: str, label: str) -> Point:
    point = _parse_family(text)
    if point is not None:
        return point
    harmonic = _HARMONIC.fullmatch(text)
    if harmonic is not None:
        base = _parse_family(harmonic.group(2))
        if base is not None:
            k = int(harmonic.group(1))
            return (k * base[0], k * base[1])
    raise InputError(
        f"{label!r} names no lattice point: use RF, RBj, FBj, BlBj, a harmonic such as "
        "2RB1, or a product such as RF+FB1 (a ghost's carrier depends on its unknown tilt)"
    )


@dataclass(frozen=True)
class SearchPoint:
    """A lattice point identification looks for.

    Attributes
    ----------
    point : tuple of int
        ``(fb1, rf)`` of the stored twin.
    label : str
    kind : LatticeKind
    rank : int
        :data:`RANK_FIRST`, :data:`RANK_HARMONIC` or :data:`RANK_PRODUCT`: of two points
        near one peak, the lower rank names it.
    alpha : float
        Prefactor (positive).
    """

    point: Point
    label: str
    kind: LatticeKind
    rank: int
    alpha: float


#: Largest ``j`` of the families whose harmonics and products are looked for: the
#: camera's nonlinearity makes visible products of the brightest peaks only.
PRODUCT_ORDER = 2


@functools.lru_cache(maxsize=16)
def search_points(n1: float, n2: float, max_order: int) -> tuple[SearchPoint, ...]:
    """Return the points identification looks for, lowest rank first.

    The first-order families up to ``max_order`` (RF, RB_j, FB_j); the second
    harmonics of those up to :data:`PRODUCT_ORDER`, and the third of RF, RB1 and FB1;
    and every sum and difference of two of those (intermodulation). A product that
    lands on a first-order family (RF + RB1 on FB1) is that family; one that lands
    past ``max_order`` is left out.

    Parameters
    ----------
    n1, n2 : float
        Refractive indices, ``0 < n1 < n2``.
    max_order : int
        Largest ``j`` of the first-order families, >= 1.
    """
    check_indices(n1, n2)
    if isinstance(max_order, bool) or not isinstance(max_order, int) or max_order < 1:
        raise InputError(f"max_order must be a positive integer, got {max_order!r}")
    first = [(0, 1)] + [(j, r) for j in range(1, max_order + 1) for r in (-1, 0)]
    parents = [p for p in first if max(p[0], 1) <= PRODUCT_ORDER]
    candidates: dict[Point, int] = {}

    def add(point: Point, rank: int) -> None:
        if point == (0, 0):
            return
        key = stored(point, n1, n2)
        family = _family_name(key)
        if family is not None:
            if max(key[0], 1) > max_order:
                return
            rank = RANK_FIRST
        candidates[key] = min(rank, candidates.get(key, rank))

    for p in first:
        add(p, RANK_FIRST)
    for p in parents:
        add((2 * p[0], 2 * p[1]), RANK_HARMONIC)
    for p in parents[:3]:
        add((3 * p[0], 3 * p[1]), RANK_PRODUCT)
    for i, a in enumerate(parents):
        for b in parents[i + 1 :]:
            add((a[0] + b[0], a[1] + b[1]), RANK_PRODUCT)
            add((a[0] - b[0], a[1] - b[1]), RANK_PRODUCT)
    points = []
    for point, rank in candidates.items():
        label, kind = describe(point, n1, n2)
        points.append(SearchPoint(point, label, kind, rank, alpha_at(point, n1, n2)))
    points.sort(key=lambda s: (s.rank, abs(s.point[0]) + abs(s.point[1]), s.label))
    return tuple(points)


@functools.lru_cache(maxsize=16)
def higher_points(
    n1: float, n2: float, max_order: int, searched: tuple[SearchPoint, ...]
) -> tuple[SearchPoint, ...]:
    """Lattice points beyond :func:`search_points`: higher products (``|rf| <= 3``,
    ``|fb1| <= 2 max_order + 2``), for peaks left over once the lattice is chosen (a
    saturated camera makes third orders); rank :data:`RANK_HIGHER`."""
    known = {p.point for p in searched}
    points = []
    for fb1 in range(-2 * max_order - 2, 2 * max_order + 3):
        for rf in range(-3, 4):
            point = (fb1, rf)
            if point == (0, 0) or alpha_at(point, n1, n2) <= 0 or point in known:
                continue
            label, kind = describe(point, n1, n2)
            points.append(SearchPoint(point, label, kind, RANK_HIGHER, alpha_at(point, n1, n2)))
    return tuple(points)


@dataclass(frozen=True)
class Basis:
    """The two carriers that span the lattice, on their stored twins.

    Attributes
    ----------
    fb1, rf : tuple of float
        ``f_FB1`` and ``f_RF`` as the camera sees them, ``(fx, fy)`` in cycles/pixel,
        folded into ``[-0.5, 0.5)``.
    """

    fb1: tuple[float, float]
    rf: tuple[float, float]

    @classmethod
    def from_arrays(cls, fb1: ArrayLike, rf: ArrayLike) -> Basis:
        """Build a basis from two ``(fx, fy)`` arrays (folded here)."""
        f = wrap_frequency(np.asarray(fb1, dtype=np.float64))
        r = wrap_frequency(np.asarray(rf, dtype=np.float64))
        return cls((float(f[0]), float(f[1])), (float(r[0]), float(r[1])))

    @property
    def matrix(self) -> NDArray[np.float64]:
        """``[[f_FB1], [f_RF]]``, shape (2, 2): ``point @ matrix`` is a carrier."""
        return np.array([self.fb1, self.rf], dtype=np.float64)

    def carrier(self, point: Point) -> tuple[float, float]:
        """Return the folded carrier of ``point``, cycles/pixel."""
        f = wrap_frequency(np.asarray(point, dtype=np.float64) @ self.matrix)
        return (float(f[0]), float(f[1]))

    def flipped(self) -> Basis:
        """Return the basis of the other global twin (every carrier negated)."""
        return Basis((-self.fb1[0], -self.fb1[1]), (-self.rf[0], -self.rf[1]))


@dataclass(frozen=True)
class Match:
    """A detected peak on a lattice point.

    Attributes
    ----------
    peak : int
        Index of the detected peak.
    target : SearchPoint
    residual_bins : float
        Distance from the peak (on the matching twin) to the point's carrier, FFT bins.
    twin : bool
        True when the detected carrier is the negative of the stored twin's.
    """

    peak: int
    target: SearchPoint
    residual_bins: float
    twin: bool


def _tolerances(points: tuple[SearchPoint, ...], tolerance: float, grow: bool) -> np.ndarray:
    """Per point, the match tolerance in bins: wider for far points of a rough basis."""
    if not grow:
        return np.full(len(points), tolerance)
    reach = np.array([abs(p.point[0]) + abs(p.point[1]) for p in points], dtype=np.float64)
    return tolerance * np.clip(reach / 2.0, 1.0, 3.0)


def match(
    basis: Basis,
    carriers: NDArray[np.float64],
    shape: tuple[int, int],
    points: tuple[SearchPoint, ...],
    tolerance: float,
    *,
    grow: bool = False,
    exclude: frozenset[int] = frozenset(),
) -> list[Match]:
    """Name detected peaks by the lattice points they sit on.

    Each peak takes, among the points within ``tolerance`` bins of it on either twin,
    the lowest rank, then the nearest. Two peaks on one point: the nearer keeps it.

    Parameters
    ----------
    basis : Basis
    carriers : ndarray, shape (M, 2)
        Detected carriers, cycles/pixel, either twin.
    shape : tuple of int
        Frame ``(rows, cols)``: one bin is ``1 / cols`` by ``1 / rows`` cycles/pixel.
    points : tuple of SearchPoint
    tolerance : float
        Largest residual for a match, FFT bins.
    grow : bool
        Widen the tolerance with the point's distance from the origin (up to three
        times), for a basis taken from two peaks only.
    exclude : frozenset of int
        Peaks not to match.

    Returns
    -------
    list of Match
        One per matched peak, by peak index.
    """
    coords = np.array([p.point for p in points], dtype=np.float64)
    predicted = coords @ basis.matrix
    direct = bin_distance(carriers[:, None, :] - predicted[None], shape)
    mirrored = bin_distance(-carriers[:, None, :] - predicted[None], shape)
    distance = np.minimum(direct, mirrored)
    limit = _tolerances(points, tolerance, grow)
    ranks = np.array([p.rank for p in points], dtype=np.float64)
    cost = np.where(distance <= limit[None], ranks[None] * 1e6 + distance, np.inf)
    best = np.argmin(cost, axis=1)
    owner: dict[int, Match] = {}
    for m in range(carriers.shape[0]):
        s = int(best[m])
        if m in exclude or not np.isfinite(cost[m, s]):
            continue
        found = Match(m, points[s], float(distance[m, s]), bool(mirrored[m, s] < direct[m, s]))
        held = owner.get(s)
        if held is None or found.residual_bins < held.residual_bins:
            owner[s] = found
    return sorted(owner.values(), key=lambda x: x.peak)


def refine(
    basis: Basis, carriers: NDArray[np.float64], matches: list[Match], weights: NDArray[np.float64]
) -> Basis:
    """Fit the basis to matched peaks by weighted least squares (modulo 1).

    Parameters
    ----------
    basis : Basis
        The current basis; the fit corrects it.
    carriers : ndarray, shape (M, 2)
        Detected carriers, cycles/pixel.
    matches : list of Match
        Peaks and their points; fewer than two independent points leave ``basis``.
    weights : ndarray, shape (M,)
        Per detected peak, its weight (for example its rank's and its brightness).

    Returns
    -------
    Basis
    """
    if len(matches) < 2:
        return basis
    coords = np.array([m.target.point for m in matches], dtype=np.float64)
    if np.linalg.matrix_rank(coords) < 2:
        return basis
    signs = np.array([-1.0 if m.twin else 1.0 for m in matches])[:, None]
    observed = carriers[[m.peak for m in matches]] * signs
    residual = wrap_frequency(observed - coords @ basis.matrix)
    w = np.sqrt(np.array([weights[m.peak] for m in matches], dtype=np.float64))[:, None]
    correction, *_ = np.linalg.lstsq(coords * w, residual * w, rcond=None)
    return Basis.from_arrays(
        np.asarray(basis.fb1) + correction[0], np.asarray(basis.rf) + correction[1]
    )


@dataclass(frozen=True)
class LatticePeak:
    """One detected peak, named.

    Attributes
    ----------
    index : int
        Position in the caller's list of detected peaks.
    label : str or None
        ``"RB1"``, ``"2RB1"``, ``"RF+FB1"``, ``"RB1~g0"``; None off the lattice.
    kind : LatticeKind
    lattice : tuple of int or None
        ``(fb1, rf)`` of the stored twin: the carrier is ``fb1 f_FB1 + rf f_RF``
        (for a ghost, of the lattice point it copies).
    ghost : tuple of int or None
        ``(ghost index, multiple)``: a ghost sits at its point plus ``multiple`` times
        the ghost's offset.
    residual_bins : float or None
        Distance from the peak to its predicted carrier, FFT bins.
    alpha : float or None
        Prefactor on the stored twin: exact on the lattice, from the model family the
        PCA matched off it; None when unknown.
    twin : bool
        True when the stored twin (phase grows with the height) is the negative of the
        detected carrier: demodulate ``-carrier``.
    carrier : tuple of float
        The stored twin's carrier, cycles/pixel (the detected one, negated if ``twin``).
    coupling : int or None
        How many times the reference-arm phase enters the peak (RF +1, RB_j -1, FB_j 0).
    pca_alpha : float or None
        The PCA's prefactor on the stored twin, when computed.
    pca_agrees : bool or None
        Whether the PCA's prefactor is within 10 % of ``alpha`` (None without either).
    pca_label : str or None
        Off the lattice: the model family whose alpha the PCA prefactor matches.
    notes : tuple of str
    """

    index: int
    label: str | None
    kind: LatticeKind
    lattice: Point | None
    ghost: tuple[int, int] | None
    residual_bins: float | None
    alpha: float | None
    twin: bool
    carrier: tuple[float, float]
    coupling: int | None
    pca_alpha: float | None = None
    pca_agrees: bool | None = None
    pca_label: str | None = None
    notes: tuple[str, ...] = ()
