"""Which family each peak is: by the carrier lattice, with the PCA of its phases.

With the peaks' carriers, names and alphas come from the carrier lattice
(:func:`holoview.processing.naming.lattice.identify_lattice`): exact where a peak sits on it,
its PCA prefactor as the confirmation. The temporal (or spatial) PCA of
:mod:`holoview.processing.naming.pca` gives every peak's prefactor once one peak is labelled
(the reference; the paper's procedure takes the brightest as RB1), and names a peak off
the lattice, or every peak when no carriers are given, by the family whose alpha its
prefactor matches (:func:`holoview.processing.naming.prefactors.classify_prefactors`). On the
lattice, a first order is a ``family``, a harmonic or an intermodulation product a
``second order``, a ghost copy a ``repeat`` of its family (a ghost against its own
arm carries no height: ``weak``).

A peak whose phase steps past pi per frame unwraps in time to a wrong but clean line,
so the temporal PCA gives it a wrong alpha; its carrier does not care. Off the lattice,
given each peak's wrapped step per frame
(:attr:`holoview.processing.series.phase_series.AliasingReport.measured_step`),
:func:`identify_peaks` tries the aliases ``(step + 2 pi k) / (step_ref / alpha_ref)``
of a peak no model alpha explains, and reports a match with ``aliased`` set.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from holoview.errors import InputError
from holoview.optics.families import alpha_of
from holoview.processing.naming.lattice import LatticeIdentification, identify_lattice
from holoview.processing.naming.lattice_geometry import LatticeKind
from holoview.processing.naming.pca import PhasePCA, phase_pca
from holoview.processing.naming.prefactors import (
    DEFAULT_MIN_EXPLAINED,
    DEFAULT_TOLERANCE,
    PeakIdentity,
    PeakKind,
    classify_prefactors,
    model_table,
    nearest_family,
)

logger = logging.getLogger(__name__)

__all__ = ["Identification", "identify_peaks"]


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
    lattice : LatticeIdentification or None
        The carrier lattice's identification, when carriers were given.
    """

    pca: PhasePCA
    reference: int
    reference_label: str
    alphas: np.ndarray
    peaks: tuple[PeakIdentity, ...]
    lattice: LatticeIdentification | None = None

    @property
    def confidence(self) -> float:
        """The PCA confidence ``sg_p`` (0 to 1)."""
        return self.pca.confidence

    def by_label(self) -> dict[str, int]:
        """Map each matched first-order family label to its peak index (repeats left out)."""
        return {p.label: p.index for p in self.peaks if p.kind is PeakKind.FAMILY and p.label}


#: Smallest step per frame (rad) of the reference peak for alias resolution: below it the
#: level hardly moves and the steps carry no trend to de-alias.
MIN_TREND_STEP = 0.05


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
        if alpha != 0 and nearest_family(abs(alpha), table, tolerance) is not None:
            continue
        for turns in (1, -1, 2, -2):
            candidate = (step + 2.0 * np.pi * turns) / per_alpha
            if nearest_family(abs(candidate), table, tolerance) is not None:
                resolved[m], aliased[m] = candidate, True
                logger.info("peak %d aliases in time: alpha %.3f, not %.3f", m, candidate, alpha)
                break
    return resolved, aliased


def _from_lattice(
    lattice: LatticeIdentification,
    by_pca: list[PeakIdentity],
    alphas: np.ndarray,
    explained: np.ndarray,
) -> list[PeakIdentity]:
    """The lattice's names as PCA identities; the PCA's own for peaks off the lattice."""
    kinds = {
        LatticeKind.FIRST_ORDER: PeakKind.FAMILY,
        LatticeKind.SECOND_ORDER: PeakKind.SECOND_ORDER,
        LatticeKind.INTERMODULATION: PeakKind.SECOND_ORDER,
        LatticeKind.GHOST: PeakKind.REPEAT,
    }
    out = []
    for p, own in zip(lattice.peaks, by_pca, strict=True):
        if p.kind is LatticeKind.OFF_LATTICE:
            kind = PeakKind.REPEAT if own.kind is PeakKind.FAMILY else own.kind
            out.append(replace(own, kind=kind))
            continue
        if not p.alpha:  # a ghost against its own arm: no height
            out.append(replace(own, kind=PeakKind.WEAK, label=None, expected_alpha=None))
            continue
        measured = abs(float(alphas[p.index]))
        magnitude = measured if np.isfinite(measured) and measured > 0 else p.alpha
        label = p.label.split("~")[0] if p.kind is LatticeKind.GHOST and p.label else p.label
        out.append(
            PeakIdentity(
                index=p.index,
                alpha=-magnitude if p.twin else magnitude,
                kind=kinds[p.kind],
                label=label,
                expected_alpha=p.alpha,
                flipped=p.twin,
                explained=float(explained[p.index]),
            )
        )
    return out


def identify_peaks(
    phases: ArrayLike,
    n1: float,
    n2: float,
    *,
    reference: int | None = None,
    reference_label: str = "RB1",
    amplitudes: ArrayLike | None = None,
    steps: ArrayLike | None = None,
    carriers: ArrayLike | None = None,
    shape: tuple[int, int] | None = None,
    max_order: int = 3,
    tolerance: float = DEFAULT_TOLERANCE,
    min_explained: float = DEFAULT_MIN_EXPLAINED,
) -> Identification:
    """Identify peaks by the carrier lattice and the PCA of their phases.

    Parameters
    ----------
    phases : array_like of float, shape (N, M)
        Unwrapped phases in rad of ``M`` peaks over ``N`` frames (temporal PCA) or
        pixels (spatial PCA); NaN where a peak was not measured.
    n1, n2 : float
        Refractive indices of the medium above the fluid and of the fluid.
    reference : int, optional
        Index of the labelled peak. By default the brightest by ``amplitudes`` (the
        paper's procedure: the brightest peak is RB1). With carriers, its twin (as
        given) fixes the lattice's global twin, and its name comes from the lattice
        where it sits on it.
    reference_label : str
        The labelled peak's family, any label of
        :func:`holoview.optics.families.alpha_of` (``"RB1"``, ``"FB1"``, ``"RF"``,
        ``"B2B1"``, ``"2RB1"``, ...): its alpha fixes the PCA's scale when the peak is
        off the lattice or no carriers are given.
    amplitudes : array_like of float, shape (M,), optional
        Peak amplitudes (any unit): choose the reference when it is not given, order
        the peaks for the family-or-repeat decision (brightest is the family), and
        the lattice's brightness order.
    steps : array_like of float, shape (M,), optional
        Each peak's typical wrapped phase step per frame in rad (temporal PCA of a
        steadily moving level). With it, a peak no model alpha explains is tried at
        its temporal aliases (module documentation). Ignored when the reference peak
        moves less than :data:`MIN_TREND_STEP` per frame.
    carriers : array_like, shape (M, 2), optional
        Each peak's carrier ``(fx, fy)``, cycles/pixel, on the twin its phases were
        measured on: names the peaks by the lattice.
    shape : tuple of int, optional
        Frame ``(rows, cols)``, pixels; needed with ``carriers``.
    max_order, tolerance, min_explained
        As in :func:`classify_prefactors`.

    Returns
    -------
    Identification

    Raises
    ------
    InputError
        With fewer than two peaks or frames, no common frames, a label that is not a
        family, neither ``reference`` nor ``amplitudes``, carriers without a shape, or
        carriers the lattice cannot name
        (:func:`~holoview.processing.naming.lattice.identify_lattice`).
    """
    pca = phase_pca(phases)
    n_peaks = pca.component.size
    brightness = None
    if amplitudes is not None:
        brightness = np.asarray(amplitudes, dtype=np.float64)
        if brightness.shape != (n_peaks,):
            raise InputError(f"{brightness.size} amplitudes given for {n_peaks} peaks")
    if reference is None:
        if brightness is None:
            raise InputError("give the labelled peak's index or the peak amplitudes")
        reference = int(np.argmax(brightness))
    if not -n_peaks <= reference < n_peaks:
        raise InputError(f"reference peak {reference} is not one of the {n_peaks} peaks")
    reference = int(reference) % n_peaks
    lattice = None
    if carriers is not None:
        if shape is None:
            raise InputError("carriers need the frame shape (rows, cols) to be named")
        lattice = identify_lattice(
            carriers,
            shape,
            n1,
            n2,
            values=phases,
            amplitudes=brightness,
            sign_reference=reference,
        )
        on = lattice.peaks[reference]
        if on.label is not None and on.alpha and on.kind is not LatticeKind.OFF_LATTICE:
            if on.label != reference_label:
                logger.info(
                    "the reference peak is %s on the lattice, not %s", on.label, reference_label
                )
            reference_label = on.label
    reference_alpha = (
        lattice.peaks[reference].alpha
        if lattice is not None and lattice.peaks[reference].label == reference_label
        else alpha_of(reference_label, n1, n2)
    )
    if not reference_alpha or reference_alpha <= 0:
        raise InputError(f"{reference_label} carries no height (alpha 0): label another peak")
    alphas = pca.prefactors(reference, reference_alpha)
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
            table=model_table(n1, n2, max_order),
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
    by_pca: list[PeakIdentity] = [ranked[0]] * n_peaks
    for rank, identity in zip(order, ranked, strict=True):
        by_pca[int(rank)] = replace(identity, index=int(rank), aliased=bool(aliased[rank]))
    peaks = by_pca if lattice is None else _from_lattice(lattice, by_pca, alphas, pca.explained)
    logger.info(
        "PCA over %d samples: confidence %.4f; %s",
        pca.n_samples,
        pca.confidence,
        ", ".join(f"{p.index}:{p.label or p.kind}" for p in peaks),
    )
    return Identification(
        pca=pca,
        reference=reference,
        reference_label=reference_label,
        alphas=alphas,
        peaks=tuple(peaks),
        lattice=lattice,
    )
