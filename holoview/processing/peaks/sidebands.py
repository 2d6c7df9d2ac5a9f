"""The surface's own spectrum around the carriers: sidebands that are not peaks.

A surface with structure at wave vector ``q`` (cycles/pixel) modulates the phase of every
carrier it reflects: each carrier ``f`` gets sidebands at ``f + q`` and ``f - q``, of
equal magnitude (the height is real), about ``2 pi alpha_f h_q / wavelength`` times the
carrier's (the design notes, "The surface's own spectrum"). A strong wave shows as the same
offset pattern around several carriers. Such a sideband is surface content, to be
passed by the carrier's window: never a neighbour that shrinks it, never a peak to name.

:func:`surface_sidebands` recognises them among detected peaks, from positions and
amplitudes alone (one frame):

1. a *pair*: a peak ``b`` at ``a + q`` and another ``b'`` at ``a - q`` (detected, or
   significant in the spectrum there) around a brighter peak ``a`` (either twin), both
   at most :data:`MAX_SIDEBAND_RATIO` of ``a``,
   their amplitudes within :data:`PAIR_RATIO` of each other, ``|q|`` at least
   :data:`MIN_OFFSET_BINS` bins and not itself a detected carrier (lattice offsets are:
   ``f_FB1``, ``f_RF``, ...);
2. an offset is the surface's when its pairs sit around two or more carriers, within
   :data:`SPAN` of one carrier's distance to the nearest peak brighter than the pair (or
   zero frequency) and within :data:`CONFIRM_SPAN` of the others' (where waves fill a
   band, a pair may be detected around one carrier only: significant power at both
   ``c + q`` and ``c - q`` of another carrier counts as its pair), or around one carrier
   within :data:`SINGLE_SPAN` of it (a lattice line ``-RF, RB1, RB2`` is the same
   pattern, spaced a whole lattice vector);
3. then every peak at ``c + q``, ``c - q`` or ``c +- (q1 +- q2)`` (second order) of a
   carrier ``c`` that is not itself a sideband, at most :data:`MAX_SIDEBAND_RATIO` of
   ``c``, is a sideband of ``c``;
4. and so is every other peak weaker than ``c`` within the surface's band around it,
   :data:`BAND_FACTOR` times the largest offset found: a strongly modulated carrier
   has sidebands at sums of offsets, some too close to it to be told apart, and
   beyond a modulation of 1.4 rad they outshine it (``J1 > J0``).

A lattice point is never a sideband: naming (:mod:`holoview.processing.naming`) overrules
this by position when it places a peak on the lattice, on an intermodulation point only
within :data:`~holoview.engine.resolve.PRODUCT_SNAP_BINS` of it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

__all__ = [
    "CONFIRM_SPAN",
    "MAX_SIDEBAND_RATIO",
    "MIN_OFFSET_BINS",
    "PAIR_RATIO",
    "SINGLE_SPAN",
    "SPAN",
    "Sideband",
    "surface_sidebands",
]

#: A sideband's amplitude is at most this fraction of its carrier's (a phase modulation
#: of peak depth under about 1.2 rad: J1 / J0 below 0.5).
MAX_SIDEBAND_RATIO = 0.5

#: The two sidebands of a pair: amplitudes within this ratio of each other (equal in
#: theory; estimates of neighbouring maxima on a surface's continuous spectrum scatter).
PAIR_RATIO = 3.0

#: Sidebands closer to their carrier than this many FFT bins are not told apart.
MIN_OFFSET_BINS = 2.0

#: Tolerance (FFT bins) of a position: a mirror, a repeated offset, an offset on a carrier.
TOLERANCE_BINS = 1.5

#: Largest ``|q|`` of an offset seen around two or more carriers, as a fraction of each
#: carrier's distance to the nearest peak brighter than its sidebands (or zero frequency).
SPAN = 0.5

#: Largest ``|q|`` of an offset around the other carriers, once one carrier holds it within
#: :data:`SPAN`: a pair closer to its carrier than any brighter peak (a carrier near
#: Nyquist has its own twin a few bins away, a neighbour that bounds its window).
CONFIRM_SPAN = 1.0

#: Largest ``|q|`` of an offset seen around one carrier only, likewise.
SINGLE_SPAN = 0.25

#: The surface's band around a carrier: this many times its largest offset found.
BAND_FACTOR = 2.0

#: The brightest peaks that may be carriers of sidebands.
MAX_PARENTS = 32

#: The spectrum's amplitude at a point ``(x, y)`` in FFT bins (0: nothing significant).
Level = Callable[[np.ndarray], float]


@dataclass(frozen=True)
class Sideband:
    """A detected peak that is surface content around a carrier.

    Attributes
    ----------
    parent : int
        Index of the carrier it surrounds.
    sign : int
        ``+1`` when it surrounds the carrier as listed, ``-1`` its twin.
    offset : tuple of float
        ``q = carrier - sign * parent carrier``, cycles/pixel (wrapped).
    order : int
        1 for ``+-q``, 2 for a sum or difference of two offsets, 3 for another peak
        inside the surface's band.
    """

    parent: int
    sign: int
    offset: tuple[float, float]
    order: int = 1


def _wrap(delta: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Differences in bins wrapped onto the periodic spectrum of side ``box`` (cols, rows)."""
    return delta - box * np.rint(delta / box)


class _Points:
    """Every peak and its twin on the periodic spectrum, in bins, for neighbour queries."""

    def __init__(self, bins: np.ndarray, box: np.ndarray) -> None:
        self.n = len(bins)
        self.box = box
        self.bins = bins
        #: point k is peak ``k % n``, the twin (negated) for ``k >= n``
        self.signed = np.concatenate([bins, -bins])
        self.tree = cKDTree(self._fold(self.signed), boxsize=box)

    def _fold(self, points: np.ndarray) -> np.ndarray:
        folded = np.mod(points, self.box)
        return np.where(folded >= self.box, 0.0, folded)

    def near(self, targets: np.ndarray) -> list[list[int]]:
        """For each target (bins), the points within :data:`TOLERANCE_BINS` of it."""
        return self.tree.query_ball_point(self._fold(targets.reshape(-1, 2)), r=TOLERANCE_BINS)

    def peak(self, k: int) -> tuple[int, int]:
        """Point ``k`` as ``(peak index, sign)``."""
        return (k, 1) if k < self.n else (k - self.n, -1)


@dataclass(frozen=True)
class _Pair:
    """Sidebands at ``sign * bins[parent] +- q`` (bins), the brighter of amplitude ``level``."""

    parent: int
    sign: int
    q: np.ndarray
    level: float


def surface_sidebands(
    carriers: np.ndarray,
    amplitudes: np.ndarray,
    shape: tuple[int, int],
    level: Level | None = None,
) -> list[Sideband | None]:
    """Return, per peak, the :class:`Sideband` it is, or None for a peak of its own.

    Parameters
    ----------
    carriers : ndarray, shape (n, 2)
        Detected carriers ``(fx, fy)``, cycles/pixel (each physical peak once).
    amplitudes : ndarray, shape (n,)
        Their amplitudes (relative to the mean intensity).
    shape : tuple of int
        Frame shape ``(rows, cols)``.
    level : callable, optional
        The spectrum's amplitude (as ``amplitudes``) at a point ``(x, y)`` in FFT bins,
        0 where nothing significant is there: a pair's other sideband that the
        detection missed (its neighbourhood raised its background) still counts.

    Returns
    -------
    list of (Sideband or None)
        Rules in the module documentation.
    """
    points = np.asarray(carriers, dtype=np.float64).reshape(-1, 2)
    amp = np.asarray(amplitudes, dtype=np.float64).reshape(-1)
    out: list[Sideband | None] = [None] * len(points)
    if len(points) < 3 or not np.isfinite(amp).all():
        return out
    box = np.array([shape[1], shape[0]], dtype=np.float64)
    where = _Points(points * box, box)
    parents = np.argsort(-amp, kind="stable")[:MAX_PARENTS]
    groups = _groups(_pairs(where, amp, parents, level))
    offsets: list[np.ndarray] = []
    while True:  # a confirmed offset's sidebands no longer hem in the others
        explained = np.array([s is not None for s in _classify(where, amp, parents, offsets)])
        found = _confirmed(groups, where, amp, explained, parents=parents, level=level)
        if not found:
            break
        offsets += found
        groups = [g for g in groups if not any(g[0].q is q for q in found)]
    if not offsets:
        return out
    out = _classify(where, amp, parents, offsets, second_order=True)
    return _in_band(where, amp, parents, offsets, out)


def _in_band(
    where: _Points,
    amp: np.ndarray,
    parents: np.ndarray,
    offsets: list[np.ndarray],
    out: list[Sideband | None],
) -> list[Sideband | None]:
    """Rule 4 of the module documentation: weak peaks inside the surface's band of a carrier."""
    band = BAND_FACTOR * max(float(np.hypot(*q)) for q in offsets) + TOLERANCE_BINS
    box = where.box
    for a in parents:
        if out[a] is not None:
            continue
        for sign in (1, -1):
            delta = _wrap(where.signed - sign * where.bins[a], box)
            distance = np.hypot(delta[:, 0], delta[:, 1])
            for k in np.flatnonzero((distance <= band) & (distance >= MIN_OFFSET_BINS)):
                b, twin = where.peak(int(k))
                if b == a or out[b] is not None or amp[b] > amp[a]:
                    continue
                q = _wrap(where.bins[b] - twin * sign * where.bins[a], box)
                out[b] = Sideband(
                    int(a), twin * sign, (float(q[0] / box[0]), float(q[1] / box[1])), 3
                )
    return out


def _classify(
    where: _Points,
    amp: np.ndarray,
    parents: np.ndarray,
    offsets: list[np.ndarray],
    *,
    second_order: bool = False,
) -> list[Sideband | None]:
    """Rule 3 of the module documentation: each peak on a parent's offset, brightest first."""
    out: list[Sideband | None] = [None] * where.n
    if not offsets:
        return out
    steps = [(q, 1) for q in offsets]
    if second_order:
        steps += [
            (q1 + s * q2, 2)
            for i, q1 in enumerate(offsets)
            for q2 in offsets[i:]
            for s in (1, -1)
            if np.hypot(*(q1 + s * q2)) >= MIN_OFFSET_BINS
        ]
    qs = np.array([q for q, _ in steps])
    box = where.box
    for a in parents:
        if out[a] is not None:
            continue
        for sign in (1, -1):
            for s_q in (1, -1):
                targets = sign * where.bins[a] + s_q * qs
                for j, near in enumerate(where.near(targets)):
                    for k in near:
                        b, twin = where.peak(k)
                        if b == a or out[b] is not None or amp[b] > MAX_SIDEBAND_RATIO * amp[a]:
                            continue
                        # point k = twin * bins[b] sits at sign * bins[a] + s_q * q
                        delta = _wrap(where.bins[b] - twin * sign * where.bins[a], box)
                        offset = (float(delta[0] / box[0]), float(delta[1] / box[1]))
                        out[b] = Sideband(int(a), twin * sign, offset, steps[j][1])
    return out


def _pairs(
    where: _Points, amp: np.ndarray, parents: np.ndarray, level: Level | None
) -> list[_Pair]:
    """Every sideband pair around a parent (rule 1 of the module documentation)."""
    box = where.box
    found = []
    for a in parents:
        limit = MAX_SIDEBAND_RATIO * amp[a]
        weaker = np.flatnonzero(amp <= limit)
        if not len(weaker):
            continue
        for sign in (1, -1):
            centre = sign * where.bins[a]
            sides = np.concatenate([where.bins[weaker], -where.bins[weaker]])
            members = np.concatenate([weaker, weaker])
            q = _wrap(sides - centre, box)
            far = np.hypot(q[:, 0], q[:, 1]) >= MIN_OFFSET_BINS
            for j, near in enumerate(where.near(centre - q)):
                b = int(members[j])
                if not far[j]:
                    continue
                mirror = next((amp[k % where.n] for k in near if k % where.n not in (a, b)), None)
                if mirror is None and level is not None:  # not detected: the spectrum there
                    mirror = level(centre - q[j]) or None
                if mirror is None or mirror > limit:
                    continue
                if max(mirror, amp[b]) > PAIR_RATIO * min(mirror, amp[b]):
                    continue
                if where.near(q[j])[0] or where.near(-q[j])[0]:
                    continue  # q is a detected peak's carrier: a lattice offset
                found.append(_Pair(int(a), sign, q[j], float(max(amp[b], mirror))))
    return found


def _clearance(where: _Points, amp: np.ndarray, pair: _Pair, explained: np.ndarray) -> float:
    """Bins from the pair's carrier to zero frequency or the nearest peak brighter than it.

    Peaks ``explained`` as sidebands of offsets already confirmed do not count.
    """
    centre = pair.sign * where.bins[pair.parent]
    delta = _wrap(where.signed - centre, where.box)
    distance = np.hypot(delta[:, 0], delta[:, 1])
    brighter = np.concatenate([amp > pair.level, amp > pair.level]) & ~np.concatenate(
        [explained, explained]
    )
    own = np.zeros(2 * where.n, dtype=bool)
    own[pair.parent if pair.sign > 0 else pair.parent + where.n] = True
    others = distance[brighter & ~own]
    to_dc = float(np.hypot(*_wrap(centre, where.box)))
    return min(to_dc, float(others.min())) if others.size else to_dc


def _groups(pairs: list[_Pair]) -> list[list[_Pair]]:
    """The pairs grouped by offset, ``q`` and ``-q`` together."""
    groups: list[list[_Pair]] = []
    for pair in pairs:
        for group in groups:
            q = group[0].q
            if min(np.hypot(*(pair.q - q)), np.hypot(*(pair.q + q))) < TOLERANCE_BINS:
                group.append(pair)
                break
        else:
            groups.append([pair])
    return groups


def _confirmed(
    groups: list[list[_Pair]],
    where: _Points,
    amp: np.ndarray,
    explained: np.ndarray,
    *,
    parents: np.ndarray,
    level: Level | None,
) -> list[np.ndarray]:
    """The groups' offsets (bins) that pass rule 2 of the module documentation."""
    out = []
    for group in groups:
        size = float(np.hypot(*group[0].q))
        room = {id(p): _clearance(where, amp, p, explained) for p in group}
        wide = {p.parent for p in group if size < SPAN * room[id(p)]}
        clear = {p.parent for p in group if size < CONFIRM_SPAN * room[id(p)]}
        narrow = {p.parent for p in group if size < SINGLE_SPAN * room[id(p)]}
        if wide and len(clear) < 2 and level is not None:
            clear |= _in_spectrum(group[0].q, where, amp, explained, parents=parents, level=level)
        if (wide and len(clear) >= 2) or narrow:
            out.append(group[0].q)
    return out


def _in_spectrum(
    q: np.ndarray,
    where: _Points,
    amp: np.ndarray,
    explained: np.ndarray,
    *,
    parents: np.ndarray,
    level: Level,
) -> set[int]:
    """The carriers with a pair at ``+-q`` in the spectrum, detected or not (rule 2).

    On a surface whose waves fill a band, the local maxima around each carrier fall at
    different places, and a pair may be detected around one carrier only; the same
    offset's pair shows around the others as significant power at both ``c + q`` and
    ``c - q`` (the spectrum is Hermitian: one twin says it for both).
    """
    size = float(np.hypot(*q))
    found = set()
    for a in parents:
        if explained[a]:
            continue
        sides = [level(where.bins[a] + q), level(where.bins[a] - q)]
        low, high = min(sides), max(sides)
        if low <= 0 or high > MAX_SIDEBAND_RATIO * amp[a] or high > PAIR_RATIO * low:
            continue
        pair = _Pair(int(a), 1, q, high)
        if size < CONFIRM_SPAN * _clearance(where, amp, pair, explained):
            found.add(int(a))
    return found
