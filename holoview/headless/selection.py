"""Which peaks a headless run demodulates, and what each is called.

Three ways, as the operator would at the bench (DESIGN.md, paper section 4):

- a **peaks file** (JSON, ``{"peaks": [{"label": "RB1", "carrier": [fx, fy]}, ...]}``,
  optional ``"alpha"``): each carrier snaps to the detected peak within
  :data:`~holoview.processing.labelling.DEFAULT_SNAP_BINS` bins on the twin given,
  alpha comes from the label unless given. Entries with neither a label nor an alpha
  (``holoview peaks --json`` lists every detected peak) are skipped;
- **two labels and the model** (:func:`holoview.processing.labelling.label_peaks`):
  every first-order family (RF, RB_j, FB_j) the model places on a detected peak, on
  the twin it says;
- **auto**: the N strongest detected peaks, named ``P0``, ``P1``, ... by decreasing
  amplitude until the temporal PCA names them (:mod:`holoview.headless.pipeline`),
  with the brightest as RB1 unless an anchor names another peak. The PCA fixes
  every sign from the reference peak's twin: without an anchor, that is the twin
  :func:`~holoview.processing.peaks.find_peaks` keeps (``fx > 0``), so every height
  may come out with the opposite sign; an anchor on the right twin settles it.

Carriers are in cycles/pixel, ``(fx, fy)``, on the stored twin (phase grows with height).
"""

from __future__ import annotations

import json
import logging
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from holoview.errors import InputError
from holoview.headless.inputs import Optics
from holoview.optics.families import alpha_of
from holoview.processing.labelling import DEFAULT_SNAP_BINS, ModelLabelling, label_peaks
from holoview.processing.peaks import Peak
from holoview.processing.windows import wrap_frequency

logger = logging.getLogger(__name__)

#: Largest ``j`` of the families the model places in the labels mode.
MAX_ORDER = 3

#: A label usable as a CSV value and an HDF5 name (``fused`` is reserved).
LABEL_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+~-]{0,31}")

#: First-order family labels: the peaks the labels mode demodulates.
FIRST_ORDER = re.compile(r"RF|RB[1-9]\d*|FB[1-9]\d*")

#: The three ways of choosing peaks.
MODES = ("file", "labels", "auto")

Carrier = tuple[float, float]


@dataclass(frozen=True)
class PeakEntry:
    """A peak as the user names it: a label, a carrier (cycles/pixel), maybe an alpha."""

    label: str | None
    carrier: Carrier
    alpha: float | None = None


@dataclass(frozen=True)
class Selection:
    """The peaks to demodulate and how they were chosen.

    Attributes
    ----------
    mode : {"file", "labels", "auto"}
    peaks : tuple of Peak
        In demodulation order, each with a unique label; alpha None in auto mode (the
        PCA gives it after the run).
    reference : int or None
        Auto mode: index of the peak whose label and twin fix the PCA's scale and sign.
    reference_label : str
        Its family (``"RB1"`` unless an anchor says otherwise).
    labelling : ModelLabelling or None
        The model labelling (labels mode).
    shape : tuple of int or None
        Auto mode: the frame ``(rows, cols)``, for the lattice to name the peaks.
    """

    mode: str
    peaks: tuple[Peak, ...]
    reference: int | None = None
    reference_label: str = "RB1"
    labelling: ModelLabelling | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)
    shape: tuple[int, int] | None = None


def check_label(label: str, where: str) -> str:
    """Return ``label`` if it can name a series, a CSV row and an HDF5 dataset."""
    if not isinstance(label, str) or not LABEL_PATTERN.fullmatch(label) or label == "fused":
        raise InputError(
            f"{where}: label {label!r} is not usable (a letter or digit, then letters, "
            "digits and _.+~-, at most 32 characters, not 'fused')"
        )
    return label


def check_carrier(carrier: object, where: str) -> Carrier:
    """Return a carrier ``(fx, fy)`` in cycles/pixel, or raise naming what is wrong."""
    try:
        fx, fy = (float(v) for v in carrier)  # type: ignore[union-attr]
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"{where}: carrier must be [fx, fy] in cycles/pixel, got {carrier!r}"
        ) from exc
    if not (math.isfinite(fx) and math.isfinite(fy)):
        raise InputError(f"{where}: carrier ({fx}, {fy}) is not finite")
    if abs(fx) > 0.5 or abs(fy) > 0.5:
        raise InputError(
            f"{where}: carrier ({fx:g}, {fy:g}) is outside the spectrum "
            "(|fx|, |fy| <= 0.5 cycles/pixel)"
        )
    if fx == 0 and fy == 0:
        raise InputError(f"{where}: carrier (0, 0) is zero frequency, not a carrier")
    return fx, fy


def parse_assignment(text: str, option: str) -> tuple[str, Carrier]:
    """Parse ``LABEL=fx,fy`` (cycles/pixel), as ``--label`` and ``--anchor`` take it."""
    label, sep, rest = text.partition("=")
    parts = rest.split(",")
    if not sep or len(parts) != 2:
        raise InputError(f"{option} takes LABEL=fx,fy (e.g. RB1=-0.2,0.06), got {text!r}")
    where = f"{option} {text}"
    try:
        carrier = (float(parts[0]), float(parts[1]))
    except ValueError as exc:
        raise InputError(f"{where}: fx and fy must be numbers (cycles/pixel)") from exc
    return check_label(label.strip(), where), check_carrier(carrier, where)


def load_peaks_file(path: str | Path) -> list[PeakEntry]:
    """Read a peaks file: ``{"peaks": [{"label": ..., "carrier": [fx, fy], "alpha": ...}]}``.

    Raises
    ------
    InputError
        For a missing file, invalid JSON, a missing ``peaks`` list, an entry without
        a carrier, a carrier outside the spectrum, a bad label or alpha, or a label
        given twice.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"peaks file {p}: cannot be read ({exc.strerror or exc})") from exc
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"peaks file {p}: not valid JSON ({exc.msg}, line {exc.lineno})") from exc
    items = document.get("peaks") if isinstance(document, dict) else None
    if not isinstance(items, list) or not items:
        raise InputError(
            f'peaks file {p}: expected {{"peaks": [{{"label": ..., "carrier": ...}}]}}'
        )
    entries: list[PeakEntry] = []
    seen: set[str] = set()
    for i, item in enumerate(items):
        where = f"peaks file {p}, peak {i}"
        if not isinstance(item, dict) or "carrier" not in item:
            raise InputError(f'{where}: expected an object with "carrier": [fx, fy]')
        label = item.get("label")
        if label is not None:
            check_label(label, where)
            if label in seen:
                raise InputError(f"{where}: label {label} is given twice")
            seen.add(label)
        alpha = item.get("alpha")
        if alpha is not None:
            if isinstance(alpha, bool) or not isinstance(alpha, int | float):
                raise InputError(f"{where}: alpha must be a number, got {alpha!r}")
            if not (math.isfinite(alpha) and alpha != 0):
                raise InputError(f"{where}: alpha must be finite and nonzero, got {alpha}")
        entries.append(PeakEntry(label, check_carrier(item["carrier"], where), alpha))
    return entries


def _bin_distance(a: np.ndarray, b: Carrier, shape: tuple[int, int]) -> np.ndarray:
    delta = wrap_frequency(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64))
    return np.hypot(delta[..., 0] * shape[1], delta[..., 1] * shape[0])


def snap(
    carrier: Carrier,
    detected: Sequence[Peak],
    shape: tuple[int, int],
    tolerance: float = DEFAULT_SNAP_BINS,
) -> tuple[int, bool] | None:
    """Return ``(index, twin)`` of the detected peak nearest ``carrier`` on either twin.

    ``twin`` is True when ``carrier`` points at the detected peak's other twin. None
    when no detected peak lies within ``tolerance`` FFT bins.
    """
    if not detected:
        return None
    points = np.array([p.carrier for p in detected], dtype=np.float64)
    direct = _bin_distance(points, carrier, shape)
    mirrored = _bin_distance(points, (-carrier[0], -carrier[1]), shape)
    best = int(np.argmin(np.minimum(direct, mirrored)))
    if min(direct[best], mirrored[best]) > tolerance:
        return None
    return best, bool(mirrored[best] < direct[best])


def _model_alpha(label: str, optics: Optics, where: str) -> float:
    if optics.n2 is None:
        raise InputError(f"{where}: alpha of {label} needs the fluid's index: give --n2 or --fluid")
    try:
        return alpha_of(label, optics.n1, optics.n2)
    except InputError as exc:
        raise InputError(f"{where}: {exc}; give its alpha") from exc


def select_from_entries(
    entries: Sequence[PeakEntry], detected: Sequence[Peak], shape: tuple[int, int], optics: Optics
) -> Selection:
    """Peaks from a peaks file: snapped to detected peaks, alpha from the label or given."""
    peaks: list[Peak] = []
    notes: list[str] = []
    taken: dict[int, str] = {}
    skipped = 0
    for i, entry in enumerate(entries):
        where = f"peak {i}" + (f" ({entry.label})" if entry.label else "")
        if entry.label is None and entry.alpha is None:
            skipped += 1
            continue
        label = entry.label or f"P{i}"
        alpha = entry.alpha if entry.alpha is not None else _model_alpha(label, optics, where)
        found = snap(entry.carrier, detected, shape)
        if found is None:
            notes.append(
                f"{label}: no detected peak near ({entry.carrier[0]:+.4f}, "
                f"{entry.carrier[1]:+.4f}); demodulated where given"
            )
            peak = Peak(entry.carrier, math.nan, math.nan)
        else:
            index, twin = found
            if index in taken:
                raise InputError(f"{where}: names the same detected peak as {taken[index]}")
            taken[index] = label
            peak = detected[index].flipped() if twin else detected[index]
        peaks.append(peak.relabelled(label, alpha))
    if skipped:
        logger.warning("%d peaks in the file have neither a label nor an alpha: skipped", skipped)
    if not peaks:
        raise InputError("the peaks file names no peak to process (give each a label)")
    for note in notes:
        logger.warning(note)
    return Selection("file", tuple(peaks), notes=tuple(notes))


def select_by_model(
    labels: Mapping[str, Carrier],
    detected: Sequence[Peak],
    shape: tuple[int, int],
    optics: Optics,
    *,
    max_order: int = MAX_ORDER,
) -> Selection:
    """Peaks the model names from two (or more) labelled ones: every first-order family found."""
    if len(labels) < 2:
        raise InputError(
            "--label needs at least two peaks (e.g. --label RB1=fx,fy --label FB1=fx,fy)"
        )
    optics.require("n2")
    assert optics.n2 is not None
    if not detected:
        raise InputError("no significant peak was detected in the first frame")
    model = label_peaks(
        [p.carrier for p in detected],
        dict(labels),
        optics.n1,
        optics.n2,
        shape,
        max_order=max_order,
    )
    chosen: dict[str, tuple[int, bool]] = {}
    for label, index in model.anchors.items():
        found = snap(labels[label], [detected[index]], shape)
        chosen[label] = (index, bool(found and found[1]))
    for prediction in model.predictions:
        if prediction.peak is None or not FIRST_ORDER.fullmatch(prediction.label):
            continue
        if prediction.label in chosen or prediction.peak in {i for i, _ in chosen.values()}:
            continue
        chosen[prediction.label] = (prediction.peak, prediction.twin)
    notes = [f"{name} is probably labelled on the wrong twin" for name in model.flip_hint]
    notes += [
        f"{name}: predicted, not detected" for name in model.missing if FIRST_ORDER.fullmatch(name)
    ]
    for note in notes:
        logger.info(note)
    peaks = []
    for label, (index, twin) in chosen.items():
        peak = detected[index].flipped() if twin else detected[index]
        peaks.append(peak.relabelled(label, _model_alpha(label, optics, f"--label {label}")))
    peaks.sort(key=lambda p: -p.amplitude)
    return Selection("labels", tuple(peaks), labelling=model, notes=tuple(notes))


def select_auto(
    count: int,
    detected: Sequence[Peak],
    shape: tuple[int, int],
    anchor: tuple[str, Carrier] | None = None,
) -> Selection:
    """The ``count`` strongest detected peaks, named ``P0``, ``P1``, ... for the PCA.

    With an anchor ``(label, carrier)``, the detected peak nearest the carrier (on the
    twin given) is the PCA's reference with that label, and is kept among the peaks.
    """
    if count < 2:
        raise InputError(f"--auto needs at least 2 peaks for the PCA, got {count}")
    if len(detected) < 2:
        raise InputError(
            f"--auto {count}: only {len(detected)} significant peak detected; the PCA needs two"
        )
    indices = list(range(min(count, len(detected))))
    reference, label = 0, "RB1"
    flip_reference = False
    if anchor is not None:
        label, carrier = anchor
        found = snap(carrier, detected, shape)
        if found is None:
            raise InputError(
                f"--anchor {label}: no detected peak within {DEFAULT_SNAP_BINS:g} bins of "
                f"({carrier[0]:+.4f}, {carrier[1]:+.4f}) cycles/pixel"
            )
        index, flip_reference = found
        if index not in indices:
            indices[-1] = index
        reference = indices.index(index)
    peaks = []
    for rank, index in enumerate(indices):
        peak = detected[index]
        if rank == reference and flip_reference:
            peak = peak.flipped()
        peaks.append(peak.relabelled(f"P{rank}"))
    if len(indices) < count:
        logger.warning("--auto %d: only %d significant peaks detected", count, len(indices))
    notes = ()
    if anchor is None:
        notes = (
            "auto: the brightest peak was taken as RB1 on the twin with fx > 0; if the "
            "heights have the wrong sign, give --anchor RB1=fx,fy on the other twin",
        )
    return Selection(
        "auto",
        tuple(peaks),
        reference=reference,
        reference_label=label,
        notes=notes,
        shape=(int(shape[0]), int(shape[1])),
    )


def describe_peaks(
    detected: Sequence[Peak], labelling: ModelLabelling | None, optics: Optics
) -> list[dict[str, Any]]:
    """Per detected peak, what ``holoview peaks`` reports (JSON-ready).

    Keys: ``index``, ``label`` (first model label or None), ``labels`` (every model
    label landing on it), ``carrier`` ([fx, fy] cycles/pixel, on the stored twin when
    the model says so), ``twin`` (True when that is the detected peak's other twin;
    None without the model), ``amplitude``, ``snr``, ``flags``, ``alpha`` (the model's,
    for a label; else None).
    """
    twins: dict[int, bool] = {}
    if labelling is not None:
        for prediction in labelling.predictions:
            if prediction.peak is not None and prediction.peak not in twins:
                twins[prediction.peak] = prediction.twin
    rows = []
    for i, peak in enumerate(detected):
        names = list(labelling.names[i]) if labelling is not None else []
        twin = twins.get(i, False) if labelling is not None else None
        carrier = peak.flipped().carrier if twin else peak.carrier
        label = names[0] if names else None
        alpha = None
        if label is not None and optics.n2 is not None:
            alpha = alpha_of(label, optics.n1, optics.n2)
        rows.append(
            {
                "index": i,
                "label": label,
                "labels": names,
                "carrier": [float(carrier[0]), float(carrier[1])],
                "twin": twin,
                "amplitude": float(peak.amplitude),
                "snr": float(peak.snr),
                "flags": sorted(peak.flags),
                "alpha": alpha,
            }
        )
    return rows
