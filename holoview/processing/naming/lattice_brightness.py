"""The model's brightness order of the lattice's peaks: what makes one naming likelier.

The carriers of a naming and of a lattice transformed by a symmetry of the detected
peaks can explain the same peaks (with RF, RB1 and RB2 alone, RB1 is the midpoint of
RF's twin and RB2, so the two may swap), and a wrong naming may turn bright ghosts and
products into first orders. The amplitudes of the model (field sum of
:mod:`holoview.optics.beams`, ``R`` the surface's Fresnel coefficient, ``rho`` the
submerged mirror's amplitude reflectance) order them:

- RB1 (``2 (1 - R^2) rho``) is the brightest peak: five times RF (``2 R``) or more
  once the mirror reflects over 30 % of the power, and brighter than any ghost (a
  ghost's field is a fraction of its arm's); the paper labels the brightest peak RB1
  for this;
- RB_(j+1) is ``rho R`` times RB_j (under 0.2); RB2 is ``(1 - R^2) rho^2`` times RF
  (0.68 to 0.98 for a mirror reflecting 70 to 100 %: not a clear order);
- every FB_j is a cancelling sum (all-pass etalon): FB1 is at most 0.4 times RF;
- a harmonic is weaker than its family, a product than either parent.

:func:`violations` counts named peaks out of that order, and :func:`missing_brighter`
the families a naming expects brighter than a detected peak but finds no peak for.
Brightness is the peaks' amplitude; without amplitudes, the order of the peaks
(brightest first) stands for it, each half the one before.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from holoview.processing.naming.lattice_geometry import Basis, Match, point_of_family

__all__ = ["DC_CLEAR", "NOT_RB1_FIRST", "missing_brighter", "violations"]

#: What a naming whose brightest peak is not RB1 pays (in first orders explained).
NOT_RB1_FIRST = 2

#: Bounds on a dimmer family over a brighter one (model ratio in brackets, for a
#: mirror reflecting 70 % or more, any fluid here): under RB1 (RF 0.24), the next RB_j
#: (``rho R`` 0.2), RB2 over RF (``(1 - R^2) rho^2`` up to 0.98), FB_j under RF (0.4)
#: and RB1 (0.06), a harmonic or product under its parents.
RATIO_UNDER_RB1 = 0.5
RATIO_NEXT_RB = 0.4
RATIO_RB2_RF = 1.3
RATIO_FB = {"RF": 0.6, "RB1": 0.3}
RATIO_PRODUCT = 0.6

#: A family expected but not detected counts against a naming only this far from the
#: zero order (cycles/pixel): :func:`~holoview.processing.peaks.detection.find_peaks` looks no
#: closer than 0.03.
DC_CLEAR = 0.04


def _order(label: str) -> int | None:
    """``j`` of ``"RB<j>"`` / ``"FB<j>"``, else None."""
    return int(label[2:]) if label[:2] in ("RB", "FB") and label[2:].isdigit() else None


def _parents(label: str) -> list[str]:
    """The families a harmonic (``"2RB1"``) or a product (``"RF+FB1"``) comes from."""
    if label[0].isdigit():
        return [label.lstrip("0123456789")]
    for symbol in "+-":
        left, _, right = label.partition(symbol)
        if right:
            return [left, right]
    return []


def _brighter_pairs(names: dict[str, int]) -> list[tuple[str, str, float]]:
    """Pairs ``(brighter, dimmer, ratio)`` among the named peaks: the dimmer one counts
    against the naming above ``ratio`` times the brighter (the model's bound, doubled
    or more for the camera response and amplitude estimates)."""
    pairs: list[tuple[str, str, float]] = []
    chain = sorted(
        (k for k in names if k == "RF" or (k[:2] == "RB" and _order(k) is not None)),
        key=lambda k: 1.5 if k == "RF" else float(k[2:]),
    )
    for a, b in itertools.combinations(chain, 2):
        if a == "RB1":
            pairs.append((a, b, RATIO_UNDER_RB1))
        elif {a, b} == {"RF", "RB2"}:
            pairs.append((a, b, RATIO_RB2_RF))
        else:
            pairs.append((a, b, RATIO_NEXT_RB))
    for k in names:
        if k[:2] == "FB" and _order(k) is not None:
            pairs += [(top, k, RATIO_FB[top]) for top in ("RF", "RB1") if top in names]
        else:
            pairs += [(parent, k, RATIO_PRODUCT) for parent in _parents(k) if parent in names]
    return pairs


def violations(matches: Sequence[Match], brightness: NDArray[np.float64]) -> tuple[int, int]:
    """Named peaks out of the model's brightness order: (clearly, at all).

    Parameters
    ----------
    matches : sequence of Match
    brightness : ndarray, shape (M,)
        Per detected peak, its amplitude (positive, any unit).

    Returns
    -------
    tuple of int
        Pairs whose dimmer member passes its bound (``_brighter_pairs``), plus
        :data:`NOT_RB1_FIRST` when the brightest detected peak is not named RB1; and
        pairs reversed at all.
    """
    names = {m.target.label: m.peak for m in matches}
    clear = reversed_ = 0
    if matches and names.get("RB1") != int(np.argmax(brightness)):
        clear += NOT_RB1_FIRST
    for high, low, ratio in _brighter_pairs(names):
        a, b = brightness[names[high]], brightness[names[low]]
        reversed_ += int(b > a)
        clear += int(b > ratio * a)
    return clear, reversed_


def missing_brighter(
    matches: Sequence[Match], basis: Basis, brightness: NDArray[np.float64]
) -> int:
    """Families the naming expects brighter than a named peak, with no peak where it puts them.

    RB1 for every other peak, RF for every RB_j (j >= 2) and FB_j, RB_(j-1) for RB_j,
    and a harmonic's or product's parents; RF for RB2 only when RB2 stands at least
    twice above the faintest detected peak (the two are close in brightness). A family
    whose carrier falls within :data:`DC_CLEAR` of the zero order is not expected.

    Parameters
    ----------
    matches : sequence of Match
    basis : Basis
    brightness : ndarray, shape (M,)
        Per detected peak, its amplitude.

    Returns
    -------
    int
        How many expected families are missing.
    """
    names = {m.target.label: m.peak for m in matches}
    floor = float(np.min(brightness)) if brightness.size else 0.0
    expected: set[str] = set()
    for k, peak in names.items():
        j = _order(k)
        if k != "RB1":
            expected.add("RB1")
        if k[:2] == "RB" and j is not None and j >= 2:
            expected.add(f"RB{j - 1}")
            if j >= 3 or brightness[peak] >= 2 * floor:
                expected.add("RF")
        elif k[:2] == "FB" and j is not None:
            expected.add("RF")
        expected.update(_parents(k))
    missing = 0
    for label in sorted(expected - set(names)):
        point = point_of_family(label)
        if point is None:
            continue
        if float(np.hypot(*basis.carrier(point))) > DC_CLEAR:
            missing += 1
    return missing
