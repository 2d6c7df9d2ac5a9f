"""Model-based labelling: from two labelled peaks, name every detected peak the model explains.

The operator names two peaks (any two of RB1, FB1 and RF, or others that fix the
lattice); the carrier lattice (:func:`holoview.processing.naming.lattice.identify_lattice`, the
one rule) names every detected peak. This module reports it as the model's predictions
matched to the peaks :func:`holoview.processing.peaks.detection.find_peaks` detected, both ways:
what was predicted but not found (RF, RB_j, FB_j, B_l B_j up to ``max_order`` and
their second orders), and what was found but predicted by none of those (beam-splitter
ghosts, intermodulation products, stray reflections). The paper's section 4 notes
that a coarsely aligned bench shows many such extra peaks.

Carriers are in cycles per pixel, ``(fx, fy)``; distances in FFT bins (``fx * cols``,
``fy * rows``). A real frame shows each peak twice, at ``+f`` and ``-f``, and
``find_peaks`` keeps one twin by a convention of its own, so every match is tried on both
twins; ``twin`` says when the detected peak is the negative of the prediction (flip it to
make its phase grow with the height). Predictions past Nyquist are folded back, as the
camera sees them.

The labelled positions are taken on the twin given (the stored twin, where the phase
grows with the height), and the twin matters: with RB1 and FB1, taking FB1's other
twin swaps the predictions of RF and RB2. Labels the lattice that explains the most
peaks contradicts are an error naming the label; ``flip_hint`` names a label whose other
twin would explain a little more. If every anchor was given on the twin whose phase
falls with the height, every ``twin`` is inverted; the sign of a peak's phase against a
known depth change settles that.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from holoview.errors import InputError
from holoview.processing.naming.lattice import (
    DEFAULT_MAX_ORDER,
    LatticeIdentification,
    identify_lattice,
)
from holoview.processing.naming.lattice_geometry import LatticeKind, Point, point_of
from holoview.processing.peaks.snapping import SNAP_BINS

logger = logging.getLogger(__name__)

__all__ = ["DEFAULT_MATCH_BINS", "ModelLabelling", "Prediction", "label_peaks"]

#: Largest distance (FFT bins) between a predicted carrier and a detected peak that match:
#: the sub-bin peak estimates and the lattice agree to well under a bin.
DEFAULT_MATCH_BINS = 1.5


@dataclass(frozen=True)
class Prediction:
    """One family the model places, and the detected peak it landed on.

    Attributes
    ----------
    label : str
        Family label (``"RB2"``, ``"B2B1"``, ``"2RF"``, ...).
    carrier : tuple of float
        Predicted carrier ``(fx, fy)`` in cycles/pixel on the stored twin, folded into
        ``[-0.5, 0.5)``.
    folded : bool
        True when the unfolded prediction lay past Nyquist (the peak is aliased).
    peak : int or None
        Index of the matched detected peak, None when none lies within tolerance.
    distance : float or None
        Distance in FFT bins to the matched peak (on the matching twin).
    twin : bool
        True when the detected peak sits at ``-carrier``.
    """

    label: str
    carrier: tuple[float, float]
    folded: bool
    peak: int | None
    distance: float | None
    twin: bool


@dataclass(frozen=True)
class ModelLabelling:
    """The outcome of :func:`label_peaks`.

    Attributes
    ----------
    anchors : dict of str to int
        The operator's labels and the detected peaks they were snapped to.
    predictions : tuple of Prediction
        Every family placed by the model, anchors included.
    names : tuple of tuple of str
        Per detected peak, every label whose prediction landed on it, first-order
        families first (B_l B_j lands on FB_(l-j), the second order of FB_j on FB_2j).
    missing : tuple of str
        Labels predicted but matching no detected peak (too faint to detect, or absent).
    unexplained : tuple of int
        Detected peaks no prediction explains (ghosts, products, stray reflections).
    flip_hint : tuple of str
        Labels (after the first) whose position, taken on the other twin, would let the
        lattice explain a few more detected peaks: probably clicked on the wrong twin.
    lattice : LatticeIdentification or None
        The lattice identification behind it: per detected peak, its lattice point,
        residual, kind and coupling.
    """

    anchors: dict[str, int]
    predictions: tuple[Prediction, ...]
    names: tuple[tuple[str, ...], ...]
    missing: tuple[str, ...]
    unexplained: tuple[int, ...]
    flip_hint: tuple[str, ...]
    lattice: LatticeIdentification | None = None

    @property
    def labels(self) -> tuple[str | None, ...]:
        """Per detected peak, its first label, or None when unexplained."""
        return tuple(names[0] if names else None for names in self.names)

    def prediction(self, label: str) -> Prediction:
        """Return the prediction named ``label``."""
        for prediction in self.predictions:
            if prediction.label == label:
                return prediction
        raise KeyError(label)


def _priority(label: str) -> tuple[int, str]:
    """Order of labels sharing a peak: first-order RF/RB/FB, then B_l B_j, then orders."""
    if label[0].isdigit():
        return (2, label)
    if label.startswith("B"):
        return (1, label)
    return (0, label)


def _predicted_labels(max_order: int) -> list[str]:
    first = ["RF"] + [f"{kind}{j}" for j in range(1, max_order + 1) for kind in ("RB", "FB")]
    between = [f"B{high}B{low}" for high in range(2, max_order + 1) for low in range(1, high)]
    return first + between + [f"2{label}" for label in first]


def label_peaks(
    carriers: Sequence[tuple[float, float]] | np.ndarray,
    labelled: Mapping[str, tuple[float, float]],
    n1: float,
    n2: float,
    shape: tuple[int, int],
    *,
    max_order: int = 2,
    tolerance: float = DEFAULT_MATCH_BINS,
    snap: float = SNAP_BINS,
) -> ModelLabelling:
    """Label detected peaks from two (or more) labelled ones and the lattice.

    Parameters
    ----------
    carriers : sequence of (fx, fy)
        Detected peak carriers in cycles/pixel (for example ``[p.carrier for p in
        find_peaks(frame)]``), either twin, brightest first.
    labelled : mapping of str to (fx, fy)
        The operator's labels and where they pointed, in cycles/pixel (a click, or a
        detected carrier), on the stored twin of each; each is snapped to the nearest
        detected peak, whose carrier (on the twin pointed at) then anchors the lattice.
        At least two that fix it (e.g. ``"RB1"`` and ``"FB1"``).
    n1, n2 : float
        Refractive indices above the fluid and of the fluid.
    shape : tuple of int
        Frame shape ``(rows, cols)`` in pixels (one FFT bin is ``1 / cols`` by ``1 / rows``
        cycles/pixel).
    max_order : int
        Largest ``j`` of RB_j, FB_j and B_l B_j predicted (second orders included).
    tolerance : float
        Largest distance in FFT bins for a prediction to match a detected peak.
    snap : float
        Largest distance in FFT bins between a labelled position and its peak.

    Returns
    -------
    ModelLabelling

    Raises
    ------
    InputError
        With no detected peaks, a labelled position that matches no detected peak, two
        labels on one peak, labels that do not fix the lattice, or labels the lattice
        contradicts (:func:`~holoview.processing.naming.lattice.identify_lattice`).
    """
    points = np.asarray(carriers, dtype=np.float64).reshape(-1, 2)
    if points.shape[0] == 0:
        raise InputError("no detected peaks to label")
    if isinstance(max_order, bool) or not isinstance(max_order, int) or max_order < 1:
        raise InputError(f"max_order must be a positive integer, got {max_order!r}")
    ident = identify_lattice(
        points,
        shape,
        n1,
        n2,
        labels=labelled,
        max_order=max(max_order, DEFAULT_MAX_ORDER),
        tolerance=tolerance,
        snap=snap,
    )
    on_lattice: dict[Point, tuple[int, float, bool]] = {
        p.lattice: (p.index, float(p.residual_bins or 0.0), p.twin)
        for p in ident.peaks
        if p.lattice is not None and p.kind is not LatticeKind.GHOST
    }
    matrix = ident.basis.matrix
    predictions = []
    per_peak: list[list[str]] = [[] for _ in range(points.shape[0])]
    for label in _predicted_labels(max_order):
        point = point_of(label, n1, n2)
        unfolded = np.asarray(point, dtype=np.float64) @ matrix
        found = on_lattice.get(point)
        predictions.append(
            Prediction(
                label=label,
                carrier=ident.basis.carrier(point),
                folded=bool(np.any(np.abs(unfolded) >= 0.5)),
                peak=None if found is None else found[0],
                distance=None if found is None else found[1],
                twin=bool(found is not None and found[2]),
            )
        )
        if found is not None:
            per_peak[found[0]].append(label)
    names = tuple(tuple(sorted(labels, key=_priority)) for labels in per_peak)
    missing = tuple(p.label for p in predictions if p.peak is None)
    unexplained = tuple(i for i, labels in enumerate(names) if not labels)
    logger.info(
        "model labelling: %d of %d peaks explained; missing %s; unexplained %s",
        points.shape[0] - len(unexplained),
        points.shape[0],
        list(missing),
        list(unexplained),
    )
    return ModelLabelling(
        anchors=dict(ident.anchors),
        predictions=tuple(predictions),
        names=names,
        missing=missing,
        unexplained=unexplained,
        flip_hint=ident.flip_hint,
        lattice=ident,
    )
