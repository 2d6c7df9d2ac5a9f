"""Which family a measured prefactor is: the model's alphas and the classification.

The temporal (or spatial) PCA of :mod:`holoview.processing.naming.pca` gives every peak's
prefactor alpha once one peak is labelled. Each prefactor is compared with the model
(``n1`` for RF, ``j n2`` for FB_j, ``j n2 - n1`` for RB_j; B_l B_j has the alpha of
FB_(l-j) and is reported as that family):

- a **family** match: the first peak (in the caller's order, brightest first) whose
  alpha lies within the tolerance of a family's;
- a **repeat** (ghost): a later peak with the alpha of a family already matched, as
  beam-splitter reflections make (the paper's holograms 1, 2, 3, 8, ... in the water data);
- a **second order**: alpha within the tolerance of twice a family's (camera
  nonlinearity, saturation). The second order of FB_j has the alpha and the carrier of
  FB_(2j), so it is reported as that family;
- **weak**: the principal component carries too little of the peak's variance; set
  aside without a label (the paper's grey points);
- **unexplained**: correlated with the surface, but no model alpha fits.

A negative alpha means the peak's phase decreases with the height: it sits on the other
twin (docs/design.md, twin rule) and is matched on ``|alpha|`` with ``flipped`` set.

A peak's carrier names it exactly where it sits on the carrier lattice
(:mod:`holoview.processing.naming.lattice`); this classification by alpha alone is for peaks
off the lattice and for series without carriers.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import ArrayLike

from holoview.errors import InputError
from holoview.optics.families import alpha_of

__all__ = [
    "DEFAULT_MIN_EXPLAINED",
    "DEFAULT_TOLERANCE",
    "PeakIdentity",
    "PeakKind",
    "classify_prefactors",
    "family_alphas",
    "model_table",
    "nearest_family",
]

#: Default relative tolerance on alpha for a match: 3 %, above the 2 % accuracy the PCA
#: reaches on clean recordings and below half the smallest relative gap (about 12 %)
#: between distinct model alphas up to third order for water and isopropanol.
DEFAULT_TOLERANCE = 0.03

#: Default share of a peak's variance the principal component must carry for the peak
#: to count as correlated with the surface (a correlation coefficient of about 0.9).
DEFAULT_MIN_EXPLAINED = 0.8


class PeakKind(StrEnum):
    """What a peak was identified as."""

    FAMILY = "family"
    REPEAT = "repeat"
    SECOND_ORDER = "second order"
    WEAK = "weak"
    UNEXPLAINED = "unexplained"


@dataclass(frozen=True)
class PeakIdentity:
    """The identification of one peak.

    Attributes
    ----------
    index : int
        Position of the peak in the caller's list.
    alpha : float
        Measured prefactor (dimensionless), signed: negative on the other twin.
    kind : PeakKind
    label : str or None
        The family (``"RB1"``), for a repeat the family it repeats, for a second order
        ``"2RB1"``; None when weak or unexplained.
    expected_alpha : float or None
        The model alpha of the label (positive), None without a label.
    flipped : bool
        True when the measured alpha is negative (the peak sits on the other twin).
    explained : float
        Share of the peak's variance carried by the principal component (0 to 1).
    aliased : bool
        True when the peak's phase steps past pi per frame and ``alpha`` is the
        de-aliased prefactor (see :func:`identify_peaks`), not the PCA's.
    """

    index: int
    alpha: float
    kind: PeakKind
    label: str | None
    expected_alpha: float | None
    flipped: bool
    explained: float
    aliased: bool = False

    @property
    def mismatch(self) -> float | None:
        """Relative difference ``|alpha| / expected_alpha - 1``, None without a label."""
        if self.expected_alpha is None:
            return None
        return abs(self.alpha) / self.expected_alpha - 1.0


def family_alphas(n1: float, n2: float, max_order: int = 3) -> dict[str, float]:
    """Return the model prefactor of every first-order family up to ``max_order``.

    Parameters
    ----------
    n1, n2 : float
        Refractive indices of the medium above the fluid (air) and of the fluid.
    max_order : int
        Largest number ``j`` of internal passes for RB_j and FB_j.

    Returns
    -------
    dict of str to float
        ``{"RF": n1, "RB1": n2 - n1, "FB1": n2, ...}``, all positive (twin rule).
    """
    if max_order < 1:
        raise InputError(f"max_order must be at least 1, got {max_order}")
    labels = ["RF"] + [f"{kind}{j}" for j in range(1, max_order + 1) for kind in ("RB", "FB")]
    return {label: alpha_of(label, n1, n2) for label in labels}


def nearest_family(value: float, table: dict[str, float], tolerance: float) -> str | None:
    """The label whose alpha is nearest to ``value`` in relative terms, if within tolerance."""
    best, best_error = None, tolerance
    for label, alpha in table.items():
        error = abs(value / alpha - 1.0)
        if error <= best_error:
            best, best_error = label, error
    return best


def classify_prefactors(
    alphas: ArrayLike,
    n1: float,
    n2: float,
    *,
    explained: ArrayLike | None = None,
    max_order: int = 3,
    tolerance: float = DEFAULT_TOLERANCE,
    min_explained: float = DEFAULT_MIN_EXPLAINED,
) -> tuple[PeakIdentity, ...]:
    """Classify measured prefactors against the model families.

    Parameters
    ----------
    alphas : array_like of float, shape (M,)
        Measured prefactors (dimensionless, signed), in the order that decides which of
        two peaks with the same alpha is the family and which the repeat: brightest first.
    n1, n2 : float
        Refractive indices of the medium above the fluid and of the fluid.
    explained : array_like of float, shape (M,), optional
        Share of each peak's variance along the principal component; peaks below
        ``min_explained`` are classified weak. All correlated when omitted.
    max_order : int
        Largest j of the RB_j and FB_j families compared.
    tolerance : float
        Largest relative difference ``| |alpha| / model - 1 |`` for a match.
    min_explained : float
        See ``explained``.

    Returns
    -------
    tuple of PeakIdentity
        One per peak, in the input order.
    """
    values = np.asarray(alphas, dtype=np.float64)
    if values.ndim != 1:
        raise InputError(f"prefactors must be a 1-D array, got shape {values.shape}")
    shares = np.ones_like(values) if explained is None else np.asarray(explained, dtype=np.float64)
    if shares.shape != values.shape:
        raise InputError(f"explained has shape {shares.shape}, prefactors {values.shape}")
    if not 0 < tolerance < 0.5:
        raise InputError(f"tolerance must be between 0 and 0.5, got {tolerance}")
    first = family_alphas(n1, n2, max_order)
    # Second orders of FB_j coincide with FB_2j, which the first-order table matches first.
    second = {
        label: alpha
        for label, alpha in model_table(n1, n2, max_order).items()
        if label not in first
    }
    seen: set[str] = set()
    result = []
    for index, (alpha, share) in enumerate(zip(values, shares, strict=True)):
        magnitude = abs(float(alpha))
        flipped = bool(alpha < 0)
        kind, label, expected = PeakKind.UNEXPLAINED, None, None
        if not np.isfinite(alpha) or share < min_explained or magnitude == 0.0:
            kind = PeakKind.WEAK
        elif (label := nearest_family(magnitude, first, tolerance)) is not None:
            kind = PeakKind.REPEAT if label in seen else PeakKind.FAMILY
            seen.add(label)
            expected = first[label]
        elif (label := nearest_family(magnitude, second, tolerance)) is not None:
            kind = PeakKind.SECOND_ORDER
            expected = second[label]
        result.append(
            PeakIdentity(
                index=index,
                alpha=float(alpha),
                kind=kind,
                label=label,
                expected_alpha=expected,
                flipped=flipped,
                explained=float(share),
            )
        )
    return tuple(result)


def model_table(n1: float, n2: float, max_order: int) -> dict[str, float]:
    """First-order families and their second orders."""
    first = family_alphas(n1, n2, max_order)
    return first | {f"2{label}": 2.0 * alpha for label, alpha in first.items()}
