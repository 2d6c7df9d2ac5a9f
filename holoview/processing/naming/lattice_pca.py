"""The PCA as the lattice's confirmation: per-peak agreement, and names off the lattice.

The temporal PCA of the peaks' phases (:mod:`holoview.processing.naming.pca`) gives every
peak's prefactor up to one scale. The lattice gives every peak on it an exact alpha, so
the scale is the one that makes the most well-correlated peaks agree (each such peak's
ratio is tried as the scale, as in a consensus fit); a peak agrees when its PCA
prefactor is within :data:`PCA_TOLERANCE` of the lattice's alpha. The count of peaks
that agree, less those that do not, tells namings apart that the carriers cannot
(alpha_FB1 / alpha_RF = n2 / n1); a peak that disagrees is flagged, not renamed: a
peak that steps past pi per frame unwraps to a wrong line and a wrong PCA prefactor,
while its carrier stays exact. A peak off the lattice gets the model family whose
alpha its PCA prefactor matches (:func:`holoview.processing.naming.prefactors.classify_prefactors`'s
rule), if any.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from holoview.errors import InputError
from holoview.processing.naming.lattice_geometry import LatticeKind, LatticePeak, Match
from holoview.processing.naming.pca import PhasePCA, phase_pca
from holoview.processing.naming.prefactors import (
    DEFAULT_MIN_EXPLAINED,
    DEFAULT_TOLERANCE,
    model_table,
    nearest_family,
)
from holoview.processing.series.phase_series import unwrap_in_time

logger = logging.getLogger(__name__)

__all__ = ["PCA_TOLERANCE", "PcaCheck", "PcaEvidence"]

#: Largest relative difference between a peak's PCA prefactor and its lattice alpha for
#: the two to agree: the PCA's few per cent on clean series, well under the 40 % between
#: RF and RB2 or the 200 % between RF and RB1 that the carriers may confuse.
PCA_TOLERANCE = 0.1

#: Largest first-order j of the model families a peak off the lattice is compared with.
OFF_LATTICE_ORDER = 3


@dataclass(frozen=True)
class PcaCheck:
    """The PCA's verdict on one naming.

    Attributes
    ----------
    pca : PhasePCA
    scale : float
        Component entry per unit alpha on the detected twins.
    prefactors : ndarray, shape (M,)
        Each detected peak's PCA prefactor on the twin detected (NaN where the PCA's
        share of its variance is below 0.8).
    agree, disagree : int
        Well-correlated peaks on the lattice whose PCA prefactor agrees with their alpha,
        and those whose does not.
    """

    pca: PhasePCA
    scale: float
    prefactors: NDArray[np.float64]
    agree: int
    disagree: int

    @property
    def net(self) -> int:
        """``agree - disagree``."""
        return self.agree - self.disagree

    @property
    def confidence(self) -> float:
        """The PCA confidence ``sg_p`` (0 to 1)."""
        return self.pca.confidence

    def annotate(self, peaks: list[LatticePeak], n1: float, n2: float) -> list[LatticePeak]:
        """Add each peak's PCA prefactor and agreement; name peaks off the lattice."""
        table = model_table(n1, n2, OFF_LATTICE_ORDER)
        out = []
        for p in peaks:
            value = float(self.prefactors[p.index])
            if not np.isfinite(value):
                out.append(p)
                continue
            on_stored = -value if p.twin else value
            if p.kind is not LatticeKind.OFF_LATTICE:
                if not p.alpha:  # a ghost's own-arm term: it should not move
                    moves = abs(on_stored) > PCA_TOLERANCE
                    moving = f"PCA prefactor {on_stored:.3f}: it moves with the surface"
                    out.append(
                        replace(
                            p,
                            pca_alpha=on_stored,
                            pca_agrees=not moves,
                            notes=(*p.notes, moving) if moves else p.notes,
                        )
                    )
                    continue
                agrees = abs(on_stored / p.alpha - 1.0) <= PCA_TOLERANCE
                notes = p.notes
                if not agrees:
                    notes = (
                        *notes,
                        f"PCA prefactor {on_stored:.3f} disagrees with the lattice's "
                        f"{p.alpha:.3f} (aliasing in time, or a wrong name)",
                    )
                out.append(replace(p, pca_alpha=on_stored, pca_agrees=agrees, notes=notes))
                continue
            family = nearest_family(abs(value), table, DEFAULT_TOLERANCE)
            if family is None:
                note = f"off the lattice; PCA prefactor {value:.3f} matches no family"
                out.append(replace(p, pca_alpha=value, notes=(*p.notes, note)))
                continue
            twin = value < 0
            carrier = (-p.carrier[0], -p.carrier[1]) if twin else p.carrier
            note = (
                f"off the lattice; PCA prefactor {abs(value):.3f} is {family}'s "
                "(a copy from another surface?)"
            )
            out.append(
                replace(
                    p,
                    alpha=table[family],
                    twin=twin,
                    carrier=carrier,
                    pca_alpha=abs(value),
                    pca_label=family,
                    notes=(*p.notes, note),
                )
            )
        return out


@dataclass(frozen=True)
class PcaEvidence:
    """The PCA of the detected peaks' phases, computed once for every naming tried."""

    pca: PhasePCA

    @classmethod
    def from_series(
        cls, series: np.ndarray | None, n_peaks: int, notes: list[str]
    ) -> PcaEvidence | None:
        """Unwrap the series in time and run the PCA; None (with a note) when it cannot."""
        if series is None:
            return None
        array = np.asarray(series)
        if array.ndim != 2 or array.shape[1] != n_peaks:
            raise InputError(f"values must be (frames, {n_peaks} peaks), got shape {array.shape}")
        try:
            phases = unwrap_in_time(array)
            pca = phase_pca(np.where(np.isfinite(array), phases, np.nan))
        except InputError as exc:
            notes.append(f"PCA not available: {exc}")
            logger.info("PCA not available: %s", exc)
            return None
        return cls(pca)

    def check(self, matches: tuple[Match, ...] | list[Match], n_peaks: int) -> PcaCheck:
        """The scale that makes the most peaks agree, and the per-peak prefactors."""
        v = self.pca.component
        good = self.pca.explained >= DEFAULT_MIN_EXPLAINED
        signed = np.full(n_peaks, np.nan)
        for m in matches:
            if m.target.alpha > 0:
                signed[m.peak] = -m.target.alpha if m.twin else m.target.alpha
        usable = good & np.isfinite(signed)
        best, scale = (-1, 0), float("nan")
        for k in np.flatnonzero(usable):
            trial = v[k] / signed[k]
            ratio = v[usable] / (trial * signed[usable])
            agree = int(np.count_nonzero(np.abs(ratio - 1.0) <= PCA_TOLERANCE))
            key = (agree, -int(k))
            if key > best:
                best, scale = key, trial
        if not np.isfinite(scale):
            scale = float(np.max(np.abs(v)))
        ratio = v[usable] / (scale * signed[usable])
        agreeing = np.abs(ratio - 1.0) <= PCA_TOLERANCE
        if np.any(agreeing):
            scale *= float(np.median(ratio[agreeing]))
        agree = int(np.count_nonzero(agreeing))
        prefactors = np.where(good, v / scale, np.nan)
        return PcaCheck(self.pca, scale, prefactors, agree, int(usable.sum()) - agree)
