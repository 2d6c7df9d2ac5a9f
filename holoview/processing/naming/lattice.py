"""Peak identification by the carrier lattice: one rule for every peak's name and alpha.

Every first-order family sits on the lattice spanned by ``f_FB1`` and ``f_RF``
(:mod:`holoview.processing.naming.lattice_geometry`), and its prefactor follows exactly from
its two integer coordinates, so a peak's carrier names it: no PCA prefactor, with its
few per cent of noise, is needed where the carriers are precise to a fraction of a bin.
:func:`identify_lattice` returns, per detected peak, its label, lattice coordinates,
residual in FFT bins, alpha, twin, kind and notes.

The basis
---------
- **From labels**: two labelled peaks that fix the lattice (RB1 and FB1, RF and FB1,
  RB1 and RF, RB1 and RB2, ...), each snapped to the detected peak within ``snap``
  bins on the twin given; more labels are checked against it. Labels that disagree
  with each other, or with the lattice that explains the most peaks, are an error that
  names the label (never a silent wrong name); so is a basis of two labels that explains
  none of the other detected peaks (three labels or more that agree check each other).
- **Automatically** (:mod:`holoview.processing.naming.lattice_search`): every pair of the
  brightest detected peaks, read as every pair of RF, RB1, FB1, RB2, FB2 and RB3 that
  spans the lattice, on both relative twins, gives a candidate basis; each is refined
  on the peaks it explains and scored by them (1 per first-order family, 0.5 per
  harmonic, 0.25 per intermodulation product), less one per clear departure from the
  model's brightness order (:mod:`holoview.processing.naming.lattice_brightness`: RB1 the
  brightest, RB1 > RF > RB2 > RB3, FB_j well under RF, a product under its parents, no
  family missing that a detected one says must be brighter). Namings that explain the
  same peaks exist (with RF, RB1 and RB2 only, RF and RB2 may swap: RB1 is the midpoint
  of RF's twin and RB2): among candidates within 0.5 of the best, the PCA of the phases
  decides when ``values`` are given (the naming whose alphas agree with the most peaks'
  PCA prefactors: alpha_FB1 / alpha_RF = n2 / n1), then the brightness order; a
  ``margin`` under 0.75 without the PCA is noted.

A carrier cannot tell a peak from its twin on its own: the whole lattice and its
negative explain the same peaks. Labels fix that sign; so does ``sign_reference`` (a
peak given on its stored twin); otherwise the peak named RB1 (else the brightest first
order) is kept on the twin detected, and ``sign_from`` says so.

Beyond the lattice
------------------
A beam-splitter ghost copies an arm with an extra tilt: its peaks repeat lattice
points shifted by one offset ``g`` (``P + g`` or ``P - g``), with the alpha of ``P``.
An offset that explains two or more of the peaks left over is taken as a ghost
(``"RB1~g0"``; ``"g0"``, alpha 0, is the ghost against its own arm;
:mod:`holoview.processing.naming.lattice_ghosts`). Peaks left over on higher lattice points
(third orders of a saturated camera) are named as intermodulation products. Peaks still
left are off the lattice: the PCA names them by their prefactor alone when it can
(:func:`holoview.processing.naming.prefactors.classify_prefactors`). With ``values``, every
peak also gets its PCA prefactor and whether it agrees with the lattice's alpha.

Carriers are in cycles/pixel, ``(fx, fy)``, residuals in FFT bins (``fx * cols``,
``fy * rows``) on the periodic spectrum.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError
from holoview.processing.naming.lattice_geometry import (
    Basis,
    LatticeKind,
    LatticePeak,
    Match,
    alpha_at,
    check_indices,
    coupling,
    describe,
    higher_points,
    match,
    point_of,
    search_points,
)
from holoview.processing.naming.lattice_ghosts import Ghost, find_ghosts
from holoview.processing.naming.lattice_labels import from_labels, snap_labels
from holoview.processing.naming.lattice_pca import PcaCheck, PcaEvidence
from holoview.processing.naming.lattice_search import (
    Candidate,
    Fitter,
    auto_candidates,
    choose,
    orient,
)
from holoview.processing.peaks.snapping import SNAP_BINS

logger = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_MAX_ORDER",
    "DEFAULT_TOLERANCE_BINS",
    "LatticeIdentification",
    "identify_lattice",
]

#: Largest ``j`` of the first-order families looked for (their products are looked for too).
DEFAULT_MAX_ORDER = 4

#: Largest residual (FFT bins) of a peak on its lattice point. Sub-bin peak estimates
#: land within 0.1 bin on clean frames; broadened peaks (waves, an object) within a bin.
DEFAULT_TOLERANCE_BINS = 1.5


@dataclass(frozen=True)
class LatticeIdentification:
    """The outcome of :func:`identify_lattice`.

    Attributes
    ----------
    basis : Basis
        ``f_FB1`` and ``f_RF`` on their stored twins, refined on every matched peak.
    source : {"labels", "auto"}
    peaks : tuple of LatticePeak
        One per detected peak, in the caller's order.
    ghost_offsets : tuple of (float, float)
        Each ghost's offset, cycles/pixel.
    missing : tuple of str
        First-order families up to ``max_order`` that no detected peak sits on.
    precision_bins : float
        RMS residual of the first-order peaks, FFT bins (NaN with none).
    margin : float
        Automatic basis: the score lead of the naming over the best different one
        (1 is one more first-order family explained; inf when no other naming
        explains anything); inf for labels.
    sign_from : {"labels", "reference", "convention"}
        What fixed the global twin (see the module documentation).
    pca : PcaCheck or None
        The PCA confirmation, when ``values`` were given and the PCA could run.
    anchors : dict of str to int
        Labels mode: each label and the detected peak it was snapped to.
    flip_hint : tuple of str
        Labels mode: labels whose other twin would let the lattice explain more peaks
        (by less than it takes to call them a contradiction).
    notes : tuple of str
    """

    basis: Basis
    source: str
    peaks: tuple[LatticePeak, ...]
    ghost_offsets: tuple[tuple[float, float], ...]
    missing: tuple[str, ...]
    precision_bins: float
    margin: float
    sign_from: str
    pca: PcaCheck | None
    anchors: dict[str, int] = field(default_factory=dict)
    flip_hint: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def by_label(self) -> dict[str, int]:
        """Map each label on the lattice (ghosts included) to its peak index."""
        return {p.label: p.index for p in self.peaks if p.label is not None}

    def peak(self, label: str) -> LatticePeak:
        """Return the peak named ``label`` (KeyError when none is)."""
        for p in self.peaks:
            if p.label == label:
                return p
        raise KeyError(label)

    def predicted(self, label: str, n1: float, n2: float) -> tuple[float, float]:
        """Return where the lattice puts ``label``'s stored twin, cycles/pixel (folded)."""
        return self.basis.carrier(point_of(label, n1, n2))


def _check_inputs(
    carriers: ArrayLike, shape: tuple[int, int], tolerance: float, snap: float
) -> tuple[NDArray[np.float64], tuple[int, int]]:
    points = np.asarray(carriers, dtype=np.float64).reshape(-1, 2)
    if not np.all(np.isfinite(points)):
        raise InputError("detected carriers must be finite (fx, fy) pairs")
    try:
        rows, cols = (int(n) for n in shape)
    except (TypeError, ValueError) as exc:
        raise InputError(f"frame shape must be (rows, cols), got {shape!r}") from exc
    if rows < 2 or cols < 2:
        raise InputError(f"frame shape must be (rows, cols) of at least 2, got {shape}")
    if not (tolerance > 0 and snap > 0):
        raise InputError(f"tolerances must be positive bins, got {tolerance} and {snap}")
    if points.shape[0] < 2:
        raise InputError(
            f"{points.shape[0]} detected peak: the lattice needs at least two peaks on it"
        )
    return points, (rows, cols)


def identify_lattice(
    carriers: ArrayLike,
    shape: tuple[int, int],
    n1: float,
    n2: float,
    *,
    labels: Mapping[str, tuple[float, float]] | None = None,
    values: ArrayLike | None = None,
    amplitudes: ArrayLike | None = None,
    sign_reference: int | None = None,
    max_order: int = DEFAULT_MAX_ORDER,
    tolerance: float = DEFAULT_TOLERANCE_BINS,
    snap: float = SNAP_BINS,
) -> LatticeIdentification:
    """Name every detected peak by its place on the carrier lattice.

    Parameters
    ----------
    carriers : array_like, shape (M, 2)
        Detected carriers ``(fx, fy)``, cycles/pixel, either twin (for example
        ``[p.carrier for p in find_peaks(frame)]``).
    shape : tuple of int
        Frame ``(rows, cols)``, pixels.
    n1, n2 : float
        Refractive indices above the surface and of the fluid, ``n2 > n1``.
    labels : mapping of str to (fx, fy), optional
        Operator labels and where they point, on the stored twin of each; two or more
        fix the basis (module documentation). Without them the basis is found
        automatically.
    values : array_like, shape (N, M), optional
        Per frame, each detected peak's complex carrier value (or wrapped phase, rad)
        on the twin given in ``carriers``: the PCA confirmation.
    amplitudes : array_like, shape (M,), optional
        Peak amplitudes (any unit) for the brightness order; by default the carriers
        are taken as sorted brightest first, as
        :func:`~holoview.processing.peaks.detection.find_peaks`
        returns them.
    sign_reference : int, optional
        A peak given on its stored twin: fixes the global twin of an automatic basis.
    max_order : int
        Largest ``j`` of the first-order families looked for.
    tolerance : float
        Largest residual of a peak on its lattice point, FFT bins.
    snap : float
        Largest distance of a labelled position from its peak, FFT bins.

    Returns
    -------
    LatticeIdentification

    Raises
    ------
    InputError
        Fewer than two detected peaks or none on a lattice, ``n2 <= n1``, labels that do
        not fix the lattice or contradict it or each other, a basis of two labels that
        explains none of the other peaks, or a label or carrier that is not valid.

    Examples
    --------
    Five peaks of a 512 x 512 frame (as :func:`~holoview.processing.peaks.detection.find_peaks`
    would give them, brightest first), two of them labelled:

    >>> carriers = [(-0.2005, 0.0601), (0.1504, 0.0903), (-0.0501, 0.1504),
    ...             (-0.2506, 0.2105), (-0.1002, 0.3008)]
    >>> labels = {"RB1": (-0.2005, 0.0601), "FB1": (-0.0501, 0.1504)}
    >>> ident = identify_lattice(carriers, (512, 512), 1.0, 1.333, labels=labels)
    >>> [(p.label, round(p.alpha, 3)) for p in ident.peaks]
    [('RB1', 0.333), ('RF', 1.0), ('FB1', 1.333), ('RB2', 1.666), ('FB2', 2.666)]
    """
    check_indices(n1, n2)
    points_c, frame = _check_inputs(carriers, shape, tolerance, snap)
    n_peaks = points_c.shape[0]
    if amplitudes is None:
        brightness = 0.5 ** np.arange(n_peaks, dtype=np.float64)
    else:
        brightness = np.asarray(amplitudes, dtype=np.float64)
        if brightness.shape != (n_peaks,):
            raise InputError(f"{brightness.size} amplitudes given for {n_peaks} peaks")
        if not np.all(np.isfinite(brightness) & (brightness > 0)):
            raise InputError("peak amplitudes must be positive and finite")
    if sign_reference is not None and not 0 <= sign_reference < n_peaks:
        raise InputError(f"sign reference {sign_reference} is not one of the {n_peaks} peaks")
    fitter = Fitter(points_c, frame, search_points(n1, n2, max_order), tolerance, brightness)
    notes: list[str] = []
    evidence = PcaEvidence.from_series(
        None if values is None else np.asarray(values), n_peaks, notes
    )
    if labels:
        anchors = snap_labels(labels, points_c, frame, n1=n1, n2=n2, snap=snap)
        if len(anchors) < 2:
            raise InputError(
                f"label at least two peaks (e.g. RB1 and FB1); got {[a.label for a in anchors]}"
            )
        chosen, hints = from_labels(anchors, fitter, n1, n2)
        notes += [f"{h} is probably labelled on the wrong twin" for h in hints]
        source, sign_from, margin = "labels", "labels", math.inf
        anchors_by_label = {a.label: a.peak for a in anchors}
    else:
        candidates = auto_candidates(fitter, n1, n2)
        if not candidates or candidates[0].score < 2:
            raise InputError(
                "no two detected peaks span a lattice that explains them: fewer than two "
                "lattice peaks (label two peaks, e.g. RB1 and FB1)"
            )
        chosen, margin = choose(candidates, evidence, n_peaks, notes)
        source = "auto"
        chosen, sign_from = orient(chosen, sign_reference)
        anchors_by_label, hints = {}, ()
    check = None if evidence is None else evidence.check(chosen.matches, n_peaks)
    ident = _assemble(
        chosen,
        fitter,
        source=source,
        sign_from=sign_from,
        margin=margin,
        check=check,
        n1=n1,
        n2=n2,
        max_order=max_order,
        notes=notes,
    )
    return replace(ident, anchors=anchors_by_label, flip_hint=hints)


_AMBIGUOUS_GHOST = (
    "ghost naming ambiguous: another offset explains as many peaks with other names "
    "(a ghost's RB1 copy and its own-arm term may swap; the PCA tells them apart)"
)


def _record(
    i: int,
    carrier: tuple[float, float],
    found: Match | None,
    ghost: Ghost | None,
    *,
    n1: float,
    n2: float,
) -> LatticePeak:
    """One detected peak's record: on the lattice, a ghost, or off the lattice."""
    if found is not None:
        t = found.target
        return LatticePeak(
            index=i,
            label=t.label,
            kind=t.kind,
            lattice=t.point,
            ghost=None,
            residual_bins=found.residual_bins,
            alpha=t.alpha,
            twin=found.twin,
            carrier=(-carrier[0], -carrier[1]) if found.twin else carrier,
            coupling=coupling(t.point),
        )
    if ghost is not None:
        own = ghost.point == (0, 0)
        base = "" if own else describe(ghost.point, n1, n2)[0]
        return LatticePeak(
            index=i,
            label=f"g{ghost.index}" if own else f"{base}~g{ghost.index}",
            kind=LatticeKind.GHOST,
            lattice=ghost.point,
            ghost=(ghost.index, ghost.multiple),
            residual_bins=ghost.residual_bins,
            alpha=0.0 if own else alpha_at(ghost.point, n1, n2),
            twin=ghost.twin,
            carrier=(-carrier[0], -carrier[1]) if ghost.twin else carrier,
            coupling=coupling(ghost.point),
            notes=(("a ghost against its own arm: no height",) if own else ())
            + ((_AMBIGUOUS_GHOST,) if ghost.ambiguous else ()),
        )
    return LatticePeak(
        index=i,
        label=None,
        kind=LatticeKind.OFF_LATTICE,
        lattice=None,
        ghost=None,
        residual_bins=None,
        alpha=None,
        twin=False,
        carrier=carrier,
        coupling=None,
    )


def _assemble(
    chosen: Candidate,
    fitter: Fitter,
    *,
    source: str,
    sign_from: str,
    margin: float,
    check: PcaCheck | None,
    n1: float,
    n2: float,
    max_order: int,
    notes: list[str],
) -> LatticeIdentification:
    """Per-peak records from the chosen candidate, ghosts and the PCA."""
    c = fitter.carriers
    by_peak = {m.peak: m for m in chosen.matches}
    higher = higher_points(n1, n2, max_order, fitter.points)
    for m in match(
        chosen.basis, c, fitter.shape, higher, fitter.tolerance, exclude=frozenset(by_peak)
    ):
        by_peak[m.peak] = m
    leftover = [i for i in range(c.shape[0]) if i not in by_peak]
    offsets, ghosts = find_ghosts(
        chosen.basis,
        fitter,
        leftover,
        max_order=max_order,
        higher=higher,
        matched=list(chosen.matches),
    )
    peaks = [
        _record(i, (float(c[i, 0]), float(c[i, 1])), by_peak.get(i), ghosts.get(i), n1=n1, n2=n2)
        for i in range(c.shape[0])
    ]
    if check is not None:
        peaks = check.annotate(peaks, n1, n2)
    named = {p.lattice for p in peaks if p.kind is LatticeKind.FIRST_ORDER}
    missing = tuple(
        p.label
        for p in fitter.points
        if p.kind is LatticeKind.FIRST_ORDER
        and max(p.point[0], 1) <= max_order
        and p.point not in named
    )
    residuals = [
        p.residual_bins
        for p in peaks
        if p.kind is LatticeKind.FIRST_ORDER and p.residual_bins is not None
    ]
    precision = float(np.sqrt(np.mean(np.square(residuals)))) if residuals else math.nan
    logger.info(
        "lattice (%s, sign by %s): %s; missing %s",
        source,
        sign_from,
        ", ".join(f"{p.index}:{p.label or 'off'}" for p in peaks),
        list(missing),
    )
    return LatticeIdentification(
        basis=chosen.basis,
        source=source,
        peaks=tuple(peaks),
        ghost_offsets=tuple(offsets),
        missing=missing,
        precision_bins=precision,
        margin=margin,
        sign_from=sign_from,
        pca=check,
        notes=tuple(notes),
    )
