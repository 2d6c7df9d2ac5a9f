"""Which family each peak is, from its phase prefactor (paper sections 3.2 and 4).

The temporal (or spatial) PCA of :mod:`holoview.processing.pca` gives every peak's
prefactor alpha once one peak is labelled; the paper's procedure labels the brightest
peak RB1 (``alpha = n2 - n1``). Each prefactor is then compared with the model
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
twin (DESIGN.md, twin rule) and is matched on ``|alpha|`` with ``flipped`` set.

A peak whose phase steps past pi per frame unwraps in time to a wrong but clean line,
so the temporal PCA gives it a wrong alpha. Given each peak's wrapped step per frame
(:attr:`holoview.processing.trends.AliasingReport.measured_step`), :func:`identify_peaks`
tries the aliases ``(step + 2 pi k) / (step_ref / alpha_ref)`` of a peak no model alpha
explains, and reports a match with ``aliased`` set.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from enum import StrEnum

import numpy as np
from numpy.typing import ArrayLike

from holoview.errors import InputError
from holoview.optics.families import alpha_of
from holoview.processing.pca import PhasePCA, phase_pca

logger = logging.getLogger(__name__)

__all__ = [
    "Identification",
    "PeakIdentity",
    "PeakKind",
    "classify_prefactors",
    "family_alphas",
    "identify_peaks",
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


@dataclass(frozen=True)
class Identification:
    """The outcome of :func:`identify_peaks`: the PCA, the prefactors and the labels.

    Attributes
    ----------
    pca : PhasePCA
    reference : int
        Index of the labelled peak that fixed the global sign and scale.
    reference_label : str
    alphas : ndarray of float, shape (M,)
        Every peak's prefactor from the PCA (dimensionless); a de-aliased peak's
        prefactor is in its :class:`PeakIdentity`.
    peaks : tuple of PeakIdentity
        One per peak, in the input order.
    """

    pca: PhasePCA
    reference: int
    reference_label: str
    alphas: np.ndarray
    peaks: tuple[PeakIdentity, ...]

    @property
    def confidence(self) -> float:
        """The PCA confidence ``sg_p`` (0 to 1)."""
        return self.pca.confidence

    def by_label(self) -> dict[str, int]:
        """Map each matched first-order family label to its peak index (repeats left out)."""
        return {p.label: p.index for p in self.peaks if p.kind is PeakKind.FAMILY and p.label}


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


def _nearest(value: float, table: dict[str, float], tolerance: float) -> str | None:
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
        for label, alpha in _model_table(n1, n2, max_order).items()
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
        elif (label := _nearest(magnitude, first, tolerance)) is not None:
            kind = PeakKind.REPEAT if label in seen else PeakKind.FAMILY
            seen.add(label)
            expected = first[label]
        elif (label := _nearest(magnitude, second, tolerance)) is not None:
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


#: Smallest step per frame (rad) of the reference peak for alias resolution: below it the
#: level hardly moves and the steps carry no trend to de-alias.
MIN_TREND_STEP = 0.05


def _model_table(n1: float, n2: float, max_order: int) -> dict[str, float]:
    """First-order families and their second orders."""
    first = family_alphas(n1, n2, max_order)
    return first | {f"2{label}": 2.0 * alpha for label, alpha in first.items()}


def _resolve_aliases(
    alphas: np.ndarray,
    steps: np.ndarray,
    *,
    reference: int,
    reference_alpha: float,
    table: dict[str, float],
    tolerance: float,
    eligible: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """De-alias the prefactors of correlated peaks no model alpha explains, from their steps."""
    resolved = alphas.copy()
    aliased = np.zeros(alphas.size, dtype=bool)
    per_alpha = steps[reference] / reference_alpha  # rad per frame per unit alpha
    if not (np.isfinite(per_alpha) and abs(steps[reference]) >= MIN_TREND_STEP):
        logger.info("reference peak hardly moves: no alias resolution")
        return resolved, aliased
    for m, (alpha, step) in enumerate(zip(alphas, steps, strict=True)):
        if not (eligible[m] and np.isfinite(alpha) and np.isfinite(step)):
            continue
        if alpha != 0 and _nearest(abs(alpha), table, tolerance) is not None:
            continue
        for turns in (1, -1, 2, -2):
            candidate = (step + 2.0 * np.pi * turns) / per_alpha
            if _nearest(abs(candidate), table, tolerance) is not None:
                resolved[m], aliased[m] = candidate, True
                logger.info("peak %d aliases in time: alpha %.3f, not %.3f", m, candidate, alpha)
                break
    return resolved, aliased


def identify_peaks(
    phases: ArrayLike,
    n1: float,
    n2: float,
    *,
    reference: int | None = None,
    reference_label: str = "RB1",
    amplitudes: ArrayLike | None = None,
    steps: ArrayLike | None = None,
    max_order: int = 3,
    tolerance: float = DEFAULT_TOLERANCE,
    min_explained: float = DEFAULT_MIN_EXPLAINED,
) -> Identification:
    """Identify peaks by PCA of their phases with one labelled peak.

    Parameters
    ----------
    phases : array_like of float, shape (N, M)
        Unwrapped phases in rad of ``M`` peaks over ``N`` frames (temporal PCA) or
        pixels (spatial PCA); NaN where a peak was not measured.
    n1, n2 : float
        Refractive indices of the medium above the fluid and of the fluid.
    reference : int, optional
        Index of the labelled peak. By default the brightest by ``amplitudes`` (the
        paper's procedure: the brightest peak is RB1).
    reference_label : str
        The labelled peak's family, any label of
        :func:`holoview.optics.families.alpha_of` (``"RB1"``, ``"FB1"``, ``"RF"``,
        ``"B2B1"``, ``"2RB1"``, ...).
    amplitudes : array_like of float, shape (M,), optional
        Peak amplitudes (any unit): choose the reference when it is not given, and order
        the peaks for the family-or-repeat decision (brightest is the family).
    steps : array_like of float, shape (M,), optional
        Each peak's typical wrapped phase step per frame in rad (temporal PCA of a
        steadily moving level). With it, a peak no model alpha explains is tried at
        its temporal aliases (module documentation). Ignored when the reference peak
        moves less than :data:`MIN_TREND_STEP` per frame.
    max_order, tolerance, min_explained
        As in :func:`classify_prefactors`.

    Returns
    -------
    Identification

    Raises
    ------
    InputError
        With fewer than two peaks or frames, no common frames, a label that is not a
        family, or neither ``reference`` nor ``amplitudes``.
    """
    pca = phase_pca(phases)
    n_peaks = pca.component.size
    reference_alpha = alpha_of(reference_label, n1, n2)
    if reference_alpha <= 0:
        raise InputError(f"{reference_label} carries no height (alpha 0): label another peak")
    brightness = None
    if amplitudes is not None:
        brightness = np.asarray(amplitudes, dtype=np.float64)
        if brightness.shape != (n_peaks,):
            raise InputError(f"{brightness.size} amplitudes given for {n_peaks} peaks")
    if reference is None:
        if brightness is None:
            raise InputError("give the labelled peak's index or the peak amplitudes")
        reference = int(np.argmax(brightness))
    alphas = pca.prefactors(reference, reference_alpha)  # checks the index
    reference = int(reference) % n_peaks
    resolved, aliased = alphas.copy(), np.zeros(n_peaks, dtype=bool)
    if steps is not None:
        step = np.asarray(steps, dtype=np.float64)
        if step.shape != (n_peaks,):
            raise InputError(f"{step.size} phase steps given for {n_peaks} peaks")
        resolved, aliased = _resolve_aliases(
            alphas,
            step,
            reference=reference,
            reference_alpha=reference_alpha,
            table=_model_table(n1, n2, max_order),
            tolerance=tolerance,
            eligible=pca.explained >= min_explained,
        )
    order = np.arange(n_peaks) if brightness is None else np.argsort(-brightness, kind="stable")
    # The labelled peak goes first so that it is the family, never a repeat.
    order = np.concatenate([[reference], order[order != reference]])
    ranked = classify_prefactors(
        resolved[order],
        n1,
        n2,
        explained=pca.explained[order],
        max_order=max_order,
        tolerance=tolerance,
        min_explained=min_explained,
    )
    peaks: list[PeakIdentity | None] = [None] * n_peaks
    for rank, identity in zip(order, ranked, strict=True):
        peaks[int(rank)] = replace(identity, index=int(rank), aliased=bool(aliased[rank]))
    logger.info(
        "PCA over %d samples: confidence %.4f; %s",
        pca.n_samples,
        pca.confidence,
        ", ".join(f"{p.index}:{p.label or p.kind}" for p in peaks if p is not None),
    )
    return Identification(
        pca=pca,
        reference=reference,
        reference_label=reference_label,
        alphas=alphas,
        peaks=tuple(p for p in peaks if p is not None),
    )
