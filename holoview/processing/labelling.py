"""Model-based labelling: from two labelled peaks, name every detected peak the model explains.

The operator names two peaks (any two of RB1, FB1 and RF, or others that fix both
mirror tilts); :func:`holoview.optics.families.infer_carriers` then places every family
(RB_j, FB_j, RF, B_l B_j, the second orders). This module matches those predictions to
the peaks :func:`holoview.processing.peaks.find_peaks` detected and reports both ways:
what was predicted but not found, and what was found but predicted by none (beam-splitter
ghosts, repeats, stray reflections). The paper's section 4 notes that a coarsely aligned
bench shows many such extra peaks.

Carriers are in cycles per pixel, ``(fx, fy)``; distances in FFT bins (``fx * cols``,
``fy * rows``). A real frame shows each peak twice, at ``+f`` and ``-f``, and
``find_peaks`` keeps one twin by a convention of its own, so every match is tried on both
twins; ``twin`` says when the detected peak is the negative of the prediction (flip it to
make its phase grow with the height). Predictions past Nyquist are folded back, as the
camera sees them.

The labelled positions are taken on the twin given (the stored twin, where the phase
grows with the height), and the twin matters: with RB1 and FB1, taking FB1's other
twin swaps the predictions of RF and RB2 (both then land on detected peaks, so the
carriers alone cannot tell). ``flip_hint`` names a label whose other twin would explain
more peaks. If every anchor was given on the twin whose phase falls with the height,
every ``twin`` is inverted; the sign of a peak's phase against a known depth change (or
the PCA of :mod:`holoview.processing.pca`) settles that.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from holoview.errors import InputError
from holoview.optics.families import infer_carriers

logger = logging.getLogger(__name__)

__all__ = ["DEFAULT_MATCH_BINS", "DEFAULT_SNAP_BINS", "ModelLabelling", "Prediction", "label_peaks"]

#: Largest distance (FFT bins) between a predicted carrier and a detected peak that match:
#: the sub-bin peak estimates and the small-angle model agree to well under a bin.
DEFAULT_MATCH_BINS = 1.5

#: Largest distance (FFT bins) between an operator's click and the peak it names.
DEFAULT_SNAP_BINS = 4.0


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
        Detected peaks no prediction explains (ghosts, repeats, stray reflections).
    flip_hint : tuple of str
        Labels (after the first) whose position, taken on the other twin, would let the
        model explain more detected peaks: probably clicked on the wrong twin.
    """

    anchors: dict[str, int]
    predictions: tuple[Prediction, ...]
    names: tuple[tuple[str, ...], ...]
    missing: tuple[str, ...]
    unexplained: tuple[int, ...]
    flip_hint: tuple[str, ...]

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


def _fold(carrier: np.ndarray) -> np.ndarray:
    """Fold carriers (cycles/pixel) into [-0.5, 0.5) per axis."""
    return (carrier + 0.5) % 1.0 - 0.5


def _distances(points: np.ndarray, target: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Bin distances from each point (N, 2) to ``target`` (2,), on the periodic spectrum."""
    rows, cols = shape
    delta = _fold(points - target)
    return np.hypot(delta[:, 0] * cols, delta[:, 1] * rows)


def _priority(label: str) -> tuple[int, str]:
    """Order of labels sharing a peak: first-order RF/RB/FB, then B_l B_j, then orders."""
    if label[0].isdigit():
        return (2, label)
    if label.startswith("B"):
        return (1, label)
    return (0, label)


def _match(
    predicted: Mapping[str, tuple[float, float]],
    carriers: np.ndarray,
    shape: tuple[int, int],
    tolerance: float,
) -> list[Prediction]:
    """Match each prediction to the nearest detected peak on either twin."""
    result = []
    for label, carrier in predicted.items():
        unfolded = np.asarray(carrier, dtype=np.float64)
        stored = _fold(unfolded)
        direct = _distances(carriers, stored, shape)
        mirrored = _distances(carriers, -stored, shape)
        best = int(np.argmin(np.minimum(direct, mirrored)))
        distance = float(min(direct[best], mirrored[best]))
        matched = distance <= tolerance
        result.append(
            Prediction(
                label=label,
                carrier=(float(stored[0]), float(stored[1])),
                folded=bool(np.any(np.abs(unfolded) >= 0.5)),
                peak=best if matched else None,
                distance=distance if matched else None,
                twin=bool(matched and mirrored[best] < direct[best]),
            )
        )
    return result


def label_peaks(
    carriers: Sequence[tuple[float, float]] | np.ndarray,
    labelled: Mapping[str, tuple[float, float]],
    n1: float,
    n2: float,
    shape: tuple[int, int],
    *,
    max_order: int = 2,
    tolerance: float = DEFAULT_MATCH_BINS,
    snap: float = DEFAULT_SNAP_BINS,
) -> ModelLabelling:
    """Label detected peaks from two (or more) labelled ones and the model.

    Parameters
    ----------
    carriers : sequence of (fx, fy)
        Detected peak carriers in cycles/pixel (for example ``[p.carrier for p in
        find_peaks(frame)]``), either twin.
    labelled : mapping of str to (fx, fy)
        The operator's labels and where they pointed, in cycles/pixel (a click, or a
        detected carrier), on the stored twin of each; each is snapped to the nearest
        detected peak, whose carrier (on the twin pointed at) then anchors the model.
        At least two that fix both tilts (e.g. ``"RB1"`` and ``"FB1"``).
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
        labels on one peak, or labels that do not fix both tilts.
    """
    points = np.asarray(carriers, dtype=np.float64).reshape(-1, 2)
    if points.shape[0] == 0:
        raise InputError("no detected peaks to label")
    if not np.all(np.isfinite(points)):
        raise InputError("detected carriers must be finite (fx, fy) pairs")
    rows, cols = (int(n) for n in shape)
    if rows < 2 or cols < 2:
        raise InputError(f"frame shape must be (rows, cols) of at least 2, got {shape}")
    if not (tolerance > 0 and snap > 0):
        raise InputError(f"tolerances must be positive bins, got {tolerance} and {snap}")
    anchors: dict[str, int] = {}
    anchor_carriers: dict[str, np.ndarray] = {}
    for label, position in labelled.items():
        click = np.asarray(position, dtype=np.float64)
        if click.shape != (2,) or not np.all(np.isfinite(click)):
            raise InputError(f"labelled position of {label!r} must be finite (fx, fy)")
        direct = _distances(points, click, (rows, cols))
        mirrored = _distances(points, -click, (rows, cols))
        nearest = int(np.argmin(np.minimum(direct, mirrored)))
        if min(direct[nearest], mirrored[nearest]) > snap:
            raise InputError(
                f"labelled peak {label} at ({click[0]:+.4f}, {click[1]:+.4f}) cycles/pixel "
                f"matches no detected peak within {snap:g} bins"
            )
        if nearest in anchors.values():
            other = next(k for k, v in anchors.items() if v == nearest)
            raise InputError(f"labels {other} and {label} name the same detected peak")
        anchors[label] = nearest
        sign = 1.0 if direct[nearest] <= mirrored[nearest] else -1.0
        anchor_carriers[label] = sign * points[nearest]
    if len(anchors) < 2:
        raise InputError(f"label at least two peaks (e.g. RB1 and FB1); got {sorted(anchors)}")
    given = {name: (float(c[0]), float(c[1])) for name, c in anchor_carriers.items()}
    best = _match(
        infer_carriers(given, n1, n2, max_order=max_order), points, (rows, cols), tolerance
    )
    explained = len({m.peak for m in best if m.peak is not None})
    # The twins matter: with RB1 and FB1, flipping FB1 swaps the predictions of RF and
    # RB2. Report the labels whose flip alone would explain more detected peaks.
    flip_hint = []
    for name in list(given)[1:]:
        flipped = dict(given)
        flipped[name] = (-given[name][0], -given[name][1])
        other = _match(
            infer_carriers(flipped, n1, n2, max_order=max_order), points, (rows, cols), tolerance
        )
        if len({m.peak for m in other if m.peak is not None}) > explained:
            flip_hint.append(name)
    per_peak: list[list[str]] = [[] for _ in range(points.shape[0])]
    for match in best:
        if match.peak is not None:
            per_peak[match.peak].append(match.label)
    names_per_peak = tuple(tuple(sorted(labels, key=_priority)) for labels in per_peak)
    missing = tuple(m.label for m in best if m.peak is None)
    unexplained = tuple(i for i, labels in enumerate(names_per_peak) if not labels)
    for label, index in anchors.items():
        if label not in names_per_peak[index]:
            logger.warning("labelled peak %s is not where the model puts it", label)
    logger.info(
        "model labelling: %d of %d peaks explained; missing %s; unexplained %s",
        points.shape[0] - len(unexplained),
        points.shape[0],
        list(missing),
        list(unexplained),
    )
    return ModelLabelling(
        anchors=anchors,
        predictions=tuple(best),
        names=names_per_peak,
        missing=missing,
        unexplained=unexplained,
        flip_hint=tuple(flip_hint),
    )
