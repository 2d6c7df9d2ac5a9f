"""Which peaks a headless run demodulates, and what each is called.

Two ways, as the operator would at the bench (docs/design.md, paper section 4):

- an **experiment** (:mod:`holoview.engine.experiment`: the one a recording carries,
  a file given with ``--experiment``, or ``--label``): its labels snap to the peaks
  detected in the first frame and, with two or more of the model's families, the
  model adds the others (:func:`holoview.engine.resolve.resolve_peaks`, the rule the
  live window follows);
- **auto**: the N strongest detected peaks, named ``P0``, ``P1``, ... by decreasing
  amplitude until the temporal PCA names them (:mod:`holoview.headless.analysis`),
  with the brightest as RB1 unless an anchor names another peak. The PCA fixes
  every sign from the reference peak's twin: without an anchor, that is the twin
  :func:`~holoview.processing.peaks.detection.find_peaks` keeps (``fx > 0``), so every height
  may come out with the opposite sign; an anchor on the right twin settles it.

Carriers are in cycles/pixel, ``(fx, fy)``, on the stored twin (phase grows with height).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from holoview.engine.experiment import Experiment, check_carrier, check_label, is_model_label
from holoview.engine.resolve import own_peak
from holoview.errors import InputError
from holoview.processing.naming.labelling import ModelLabelling
from holoview.processing.naming.lattice import LatticeIdentification
from holoview.processing.naming.lattice_geometry import LatticePeak
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.snapping import SNAP_BINS, snap

logger = logging.getLogger(__name__)

Carrier = tuple[float, float]


@dataclass(frozen=True)
class Selection:
    """The peaks to demodulate and how they were chosen.

    Attributes
    ----------
    mode : {"experiment", "auto"}
    peaks : tuple of Peak
        In demodulation order (brightest first), each with a unique label; alpha None
        in auto mode (the PCA gives it after the run).
    source : str
        Where the peaks came from: ``"recording"`` (the experiment the recording
        carries), ``"experiment file"``, ``"labels"`` (``--label``), ``"auto"``.
    reference : int or None
        Auto mode: index of the peak whose label and twin fix the PCA's scale and sign.
    reference_label : str
        Its family (``"RB1"`` unless an anchor says otherwise).
    labelling : ModelLabelling or None
        The model labelling (an experiment with two or more of the model's families).
    notes : tuple of str
        What a reader of the results should know.
    lattice : tuple of (LatticePeak or None)
        Per peak, its place on the carrier lattice, where the model labelling gave one.
    shape : tuple of int or None
        Auto mode: the frame ``(rows, cols)``, for the lattice to name the peaks.
    """

    mode: str
    peaks: tuple[Peak, ...]
    source: str = "auto"
    reference: int | None = None
    reference_label: str = "RB1"
    labelling: ModelLabelling | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)
    shape: tuple[int, int] | None = None
    lattice: tuple[LatticePeak | None, ...] = ()


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


def select_from_experiment(
    experiment: Experiment,
    detected: Sequence[Peak],
    shape: tuple[int, int],
    source: str,
) -> Selection:
    """The experiment's peaks, snapped to the detected ones, plus the model's families.

    Raises
    ------
    InputError
        When the experiment names no peak, the carrier lattice contradicts a label (any
        source), a label (of a file or ``--label``; not of the recording's own
        experiment, which may have drifted) lies on no detected peak, or a label that is
        not one of the model's families comes without an alpha.
    """
    from holoview.engine.resolve import resolve_peaks

    if not experiment.peaks:
        raise InputError(f"the {source} names no peak to process")
    resolution = resolve_peaks(experiment, detected, shape)
    try:
        resolution.strict(unmatched=source != "recording")
    except InputError as exc:
        if source == "recording":
            raise InputError(
                f"the experiment the recording carries: {exc}; name the peaks with --label, "
                "--experiment or --auto N"
            ) from exc
        raise InputError(f"the {source}: {exc}") from exc
    for peak in resolution.peaks:
        if peak.alpha is None and is_model_label(peak.label or ""):
            experiment.require("n1", "n2")
        if peak.alpha is None:
            raise InputError(
                f"peak {peak.label}: not one of the model's families (RF, RB1, FB1, ...) and "
                "no alpha given; give its alpha in the experiment file"
            )
    for note in resolution.notes:
        logger.info("%s", note)
    return Selection(
        "experiment",
        resolution.peaks,
        source=source,
        labelling=resolution.labelling,
        notes=resolution.notes,
        lattice=resolution.lattice,
    )


def select_auto(
    count: int,
    detected: Sequence[Peak],
    shape: tuple[int, int],
    anchor: tuple[str, Carrier] | None = None,
) -> Selection:
    """The ``count`` strongest detected peaks, named ``P0``, ``P1``, ... for the PCA.

    The surface's sidebands (flag ``"surface"``) are not peaks: they are left out.

    With an anchor ``(label, carrier)``, the detected peak nearest the carrier (on the
    twin given) is the PCA's reference with that label, and is kept among the peaks.
    """
    if count < 2:
        raise InputError(f"--auto needs at least 2 peaks for the PCA, got {count}")
    detected = [p for p in detected if "surface" not in p.flags]  # sidebands: not peaks
    if len(detected) < 2:
        raise InputError(
            f"--auto {count}: only {len(detected)} significant peak detected; the PCA needs two"
        )
    indices = list(range(min(count, len(detected))))
    reference, label = 0, "RB1"
    flip_reference = False
    if anchor is not None:
        label, carrier = anchor
        found = snap(carrier, [p.carrier for p in detected], shape)
        if found is None:
            raise InputError(
                f"--anchor {label}: no detected peak within {SNAP_BINS:g} bins of "
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
    notes: tuple[str, ...] = ()
    if anchor is None:
        notes = (
            "auto: the brightest peak was taken as RB1 on the twin with fx > 0; if the "
            "heights have the wrong sign, give --anchor RB1=fx,fy on the other twin",
        )
    return Selection(
        "auto",
        tuple(peaks),
        "auto",
        reference=reference,
        reference_label=label,
        notes=notes,
        shape=(int(shape[0]), int(shape[1])),
    )


def describe_peaks(
    detected: Sequence[Peak],
    lattice: LatticeIdentification | None,
    labelling: ModelLabelling | None = None,
) -> list[dict[str, Any]]:
    """Per detected peak, what ``holoview peaks`` reports (JSON-ready).

    Keys: ``index``, ``label`` (its name on the carrier lattice, or None), ``labels``
    (every model label landing on it, first-order families first; the lattice's name
    without a model labelling), ``carrier`` ([fx, fy] cycles/pixel, on the stored twin
    when the lattice says so), ``twin`` (True when that is the detected peak's other
    twin; None without a lattice), ``lattice`` ([fb1, rf]: the carrier is ``fb1 f_FB1 +
    rf f_RF``; None off the lattice), ``residual_bins`` (distance to that lattice point,
    FFT bins), ``kind``, ``coupling`` (to the reference-arm phase), ``amplitude``,
    ``snr``, ``flags``, ``alpha`` (exact on the lattice; else None), ``sideband``.

    A surface sideband (flag ``"surface"``) that the lattice places on none of its
    points has ``kind`` ``"surface"``, no label, and ``sideband``: ``of`` (its
    carrier's name), ``of_index``, ``q_cpp`` (its offset ``[qx, qy]``, cycles/pixel),
    ``order`` and ``text`` ("sideband of RB1 at q = (...)"); None for other peaks.
    """
    rows = []
    for i, peak in enumerate(detected):
        named = None if lattice is None else lattice.peaks[i]
        if "surface" in peak.flags and not own_peak(peak, named):
            rows.append(_sideband_row(i, peak, detected, lattice, labelling))
            continue
        twin = None if named is None else named.twin
        carrier = peak.flipped().carrier if twin else peak.carrier
        label = None if named is None else named.label
        if labelling is not None:
            names = list(labelling.names[i])
        else:
            names = [] if label is None else [label]
        rows.append(
            {
                "index": i,
                "label": label,
                "labels": names,
                "carrier": [float(carrier[0]), float(carrier[1])],
                "twin": twin,
                "lattice": None if named is None or named.lattice is None else list(named.lattice),
                "residual_bins": None if named is None else named.residual_bins,
                "kind": None if named is None else str(named.kind),
                "coupling": None if named is None else named.coupling,
                "amplitude": float(peak.amplitude),
                "snr": float(peak.snr),
                "flags": sorted(peak.flags),
                "alpha": None if named is None else named.alpha,
                "sideband": None,
            }
        )
    return rows


def _sideband_row(
    i: int,
    peak: Peak,
    detected: Sequence[Peak],
    lattice: LatticeIdentification | None,
    labelling: ModelLabelling | None,
) -> dict[str, Any]:
    """:func:`describe_peaks`' row of a surface sideband."""
    parent = snap(peak.sideband_of or peak.carrier, [p.carrier for p in detected], (1, 1), 1e-6)
    of_index = None if parent is None else parent[0]
    name = None
    if of_index is not None:
        if labelling is not None and labelling.names[of_index]:
            name = labelling.names[of_index][0]
        elif lattice is not None and lattice.peaks[of_index].label:
            name = lattice.peaks[of_index].label
    name = name or (f"peak {of_index}" if of_index is not None else "a carrier")
    q = peak.surface_offset or (0.0, 0.0)
    return {
        "index": i,
        "label": None,
        "labels": [],
        "carrier": [float(peak.carrier[0]), float(peak.carrier[1])],
        "twin": None,
        "lattice": None,
        "residual_bins": None,
        "kind": "surface",
        "coupling": None,
        "amplitude": float(peak.amplitude),
        "snr": float(peak.snr),
        "flags": sorted(peak.flags),
        "alpha": None,
        "sideband": {
            "of": name,
            "of_index": of_index,
            "q_cpp": [q[0], q[1]],
            "order": peak.sideband_order,
            "text": f"sideband of {name} at q = ({q[0]:+.4f}, {q[1]:+.4f}) cycles/px",
        },
    }
