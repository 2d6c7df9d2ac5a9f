"""Which peaks to demodulate: an experiment's labels snapped to detected peaks, plus the model's.

One rule, used by the live window (a click, a label following a drifting peak) and by
``holoview process`` (a carrier from an experiment file, ``--label``, a recording's
experiment): a carrier names the detected peak nearest it on either twin, within
:data:`~holoview.processing.peaks.snapping.SNAP_BINS` FFT bins on the periodic spectrum
(:func:`holoview.processing.peaks.snapping.snap`). The detected peak is taken on the twin the
carrier points at, so a label keeps the twin it was given (docs/design.md: the twin where
the phase grows with the height).

With two or more labels of the model's families (RB1 and FB1, say), the model
(:func:`holoview.processing.naming.labelling.label_peaks`) places every first-order family up
to :data:`MAX_ORDER`, and the detected peaks it lands on are demodulated too, with the
model's alpha (:func:`resolve_peaks`). Labels the lattice contradicts (a label on
another family's peak, on the wrong twin, two labels for one family:
:class:`~holoview.processing.naming.lattice_labels.LabelContradictionError`) are a problem
naming the label, first among the notes live and an error headless
(:meth:`Resolution.strict`), never a quiet note.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from holoview.engine.experiment import Experiment
from holoview.errors import InputError
from holoview.processing.fourier.windows import wrap_frequency
from holoview.processing.naming.labelling import ModelLabelling, label_peaks
from holoview.processing.naming.lattice_geometry import LatticeKind, LatticePeak
from holoview.processing.naming.lattice_labels import LabelContradictionError
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.snapping import SNAP_BINS, bin_distance, snap

__all__ = [
    "MAX_ORDER",
    "ON_LATTICE",
    "PRODUCT_SNAP_BINS",
    "Resolution",
    "on_lattice",
    "own_peak",
    "resolve_peaks",
    "snap_peak",
]

#: Largest ``j`` of the first-order families (RB_j, FB_j) the model adds.
MAX_ORDER = 3

#: First-order family labels: the peaks the model adds to the labelled ones.
FIRST_ORDER = re.compile(r"RF|RB[1-9]\d*|FB[1-9]\d*")

Carrier = tuple[float, float]


def snap_peak(
    carrier: Carrier, detected: Sequence[Peak], shape: tuple[int, int]
) -> tuple[int, Peak] | None:
    """Return ``(index, peak)``: the detected peak :func:`snap` names, on ``carrier``'s twin.

    A peak of its own is named before a surface sideband (flag ``"surface"``) within
    reach: a label names a carrier, not the surface's content around it.
    """
    own = [i for i, p in enumerate(detected) if "surface" not in p.flags]
    found = snap(carrier, [detected[i].carrier for i in own], shape)
    if found is not None:
        found = (own[found[0]], found[1])
    else:
        found = snap(carrier, [p.carrier for p in detected], shape)
    if found is None:
        return None
    index, twin = found
    return index, detected[index].flipped() if twin else detected[index]


def _folded(carrier: Carrier) -> Carrier:
    fx, fy = wrap_frequency(np.asarray(carrier, dtype=np.float64))
    return float(fx), float(fy)


#: Lattice kinds that name a peak of its own: a surface sideband placed there is not one.
ON_LATTICE = (LatticeKind.FIRST_ORDER, LatticeKind.SECOND_ORDER, LatticeKind.INTERMODULATION)

#: FFT bins within which an intermodulation point makes a surface sideband a peak of its
#: own. Products of the carriers sit on their points as the carriers do (a few hundredths
#: of a bin on a wavy surface); the waves' sidebands fill the band around a carrier, where
#: high-order points lie a bin or two apart and a sideband lands near one by chance (on the
#: tests' travelling waves, at 0.6 to 1.4 bins, moving from frame to frame).
PRODUCT_SNAP_BINS = 0.5


def own_peak(peak: Peak, point: LatticePeak | None) -> bool:
    """Whether the lattice makes a detected peak one of its own rather than a sideband.

    A first- or second-order point always does; an intermodulation point does unless
    detection calls the peak the surface's sideband (flag ``"surface"``) and it lies
    farther than :data:`PRODUCT_SNAP_BINS` from the point. Ghosts and off-lattice peaks
    do not.
    """
    if point is None or point.kind not in ON_LATTICE:
        return False
    if "surface" in peak.flags and point.kind is LatticeKind.INTERMODULATION:
        return point.residual_bins is not None and point.residual_bins <= PRODUCT_SNAP_BINS
    return True


def on_lattice(labelling: ModelLabelling | None, detected: Sequence[Peak]) -> list[bool] | None:
    """Per detected peak, whether the model's lattice makes it a peak of its own
    (:func:`own_peak`); None without a lattice."""
    if labelling is None or labelling.lattice is None:
        return None
    points = labelling.lattice.peaks
    if len(points) != len(detected):
        return None
    return [own_peak(peak, point) for peak, point in zip(detected, points, strict=True)]


@dataclass(frozen=True)
class Resolution:
    """The peaks to demodulate and what the operator should know about them.

    Attributes
    ----------
    peaks : tuple of Peak
        Labelled, with alpha where known (the label's, or given), brightest first; a
        labelled carrier on no detected peak is demodulated where given (amplitude NaN).
    predicted : dict of str to (float, float)
        The model's carrier of every first-order family, cycles/pixel, folded into the
        spectrum (for drawing).
    unmatched : tuple of str
        Labels whose carrier lies on no detected peak (or on one another label named).
    problems : tuple of str
        One line per unmatched label, and the contradiction (also in ``notes``).
    contradiction : str or None
        The line naming a label the carrier lattice contradicts (None: none).
    notes : tuple of str
        One line per thing to know (unmatched labels, a label on the probable wrong
        twin, a family past Nyquist, a model that cannot place the families).
    labelling : ModelLabelling or None
        The model labelling, when two or more labels are the model's families.
    lattice : tuple of (LatticePeak or None)
        Per peak, its place on the carrier lattice (point, residual, kind, coupling):
        with the model labelling, for the peaks on a detected peak; else None.
    """

    peaks: tuple[Peak, ...]
    predicted: dict[str, Carrier] = field(default_factory=dict)
    unmatched: tuple[str, ...] = ()
    problems: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    labelling: ModelLabelling | None = None
    contradiction: str | None = None
    lattice: tuple[LatticePeak | None, ...] = ()

    @property
    def labelled(self) -> dict[str, Carrier]:
        """Each demodulated peak's carrier by label."""
        return {p.label: p.carrier for p in self.peaks if p.label}

    def strict(self, *, unmatched: bool = True) -> Resolution:
        """Return self, or raise InputError naming the labels that are wrong.

        A label the lattice contradicts is always an error; with ``unmatched``, so is a
        label on no detected peak (a recording's own experiment may have drifted).
        """
        if unmatched and self.problems:
            raise InputError("; ".join(self.problems))
        if self.contradiction is not None:
            raise InputError(self.contradiction)
        return self


def resolve_peaks(
    experiment: Experiment,
    detected: Sequence[Peak],
    shape: tuple[int, int],
    *,
    previous: Mapping[str, Peak] | None = None,
    max_order: int = MAX_ORDER,
) -> Resolution:
    """Snap the experiment's labels to detected peaks and add the model's families.

    Parameters
    ----------
    experiment : Experiment
        Labelled peaks and the indices n1, n2 (for the model and the alphas).
    detected : sequence of Peak
        Peaks :func:`~holoview.processing.peaks.detection.find_peaks` detected.
    shape : tuple of int
        Frame shape ``(rows, cols)``, pixels.
    previous : mapping of str to Peak, optional
        The peaks of the last resolution, by label (live): a faint peak missed by this
        detection keeps its last match while its label (or the model) still points
        within :data:`SNAP_BINS` of it, so the set of maps does not flicker.
    max_order : int
        Largest ``j`` of the families the model adds.

    Returns
    -------
    Resolution
    """
    problems: list[str] = []
    unmatched: list[str] = []
    chosen: list[Peak] = []
    taken: dict[int, str] = {}
    for lp in experiment.peaks:
        alpha = experiment.alpha(lp)
        found = snap_peak(lp.carrier, detected, shape)
        if found is not None and found[0] in taken:
            unmatched.append(lp.label)
            problems.append(f"{lp.label}: names the same detected peak as {taken[found[0]]}")
            continue
        kept = (previous or {}).get(lp.label)
        if (
            found is None
            and kept is not None
            and bin_distance(np.subtract(kept.carrier, lp.carrier), shape) <= SNAP_BINS
        ):
            chosen.append(kept.relabelled(lp.label, alpha))
            continue
        if found is None:
            unmatched.append(lp.label)
            problems.append(
                f"{lp.label}: no detected peak within {SNAP_BINS:g} bins of "
                f"({lp.fx:+.4f}, {lp.fy:+.4f}) cycles/pixel; demodulated where given"
            )
            peak = Peak(carrier=_folded(lp.carrier), amplitude=math.nan, snr=0.0)
        else:
            taken[found[0]] = lp.label
            peak = found[1]
        chosen.append(peak.relabelled(lp.label, alpha))
    predicted: dict[str, Carrier] = {}
    labelling = None
    contradiction = None
    anchors = {
        p.label: p.carrier for p in chosen if p.label is not None and p.label not in unmatched
    }
    family_anchors = {k: c for k, c in anchors.items() if experiment.alpha_of_label(k)}
    cannot = ""
    if len(family_anchors) >= 2 and detected and experiment.n1 and experiment.n2:
        try:
            labelling = label_peaks(
                [p.carrier for p in detected],
                family_anchors,
                experiment.n1,
                experiment.n2,
                shape,
                max_order=max_order,
            )
        except LabelContradictionError as exc:
            contradiction = str(exc)
            problems.append(contradiction)
        except InputError as exc:
            cannot = f"the model cannot place the other families: {exc}"
    notes = list(problems)
    if cannot:
        notes.append(cannot)
    if labelling is not None:
        notes += [
            f"{k} is probably on the wrong twin: label its twin instead"
            for k in labelling.flip_hint
        ]
        names = {p.label for p in chosen}
        for prediction in labelling.predictions:
            name = prediction.label
            if not FIRST_ORDER.fullmatch(name):
                continue
            predicted[name] = prediction.carrier
            if prediction.folded:
                notes.append(f"{name} lies past Nyquist: it appears folded back")
            if name in names:
                continue
            if prediction.peak is not None and prediction.peak not in taken:
                peak = detected[prediction.peak]
                peak = peak.flipped() if prediction.twin else peak
                taken[prediction.peak] = name
            else:
                last = (previous or {}).get(name)
                if (
                    last is None
                    or bin_distance(np.subtract(last.carrier, prediction.carrier), shape)
                    > SNAP_BINS
                ):
                    continue
                peak = last
            chosen.append(peak.relabelled(name, experiment.alpha_of_label(name)))
            names.add(name)
    chosen.sort(key=lambda p: -p.amplitude if p.amplitude == p.amplitude else math.inf)
    on_lattice: dict[str, LatticePeak] = {}
    if labelling is not None and labelling.lattice is not None:
        detected_of = {name: index for index, name in taken.items()}
        for name, index in detected_of.items():
            on_lattice[name] = labelling.lattice.peaks[index]
    return Resolution(
        peaks=tuple(chosen),
        predicted=predicted,
        unmatched=tuple(unmatched),
        problems=tuple(problems),
        notes=tuple(notes),
        labelling=labelling,
        lattice=tuple(on_lattice.get(p.label or "") for p in chosen),
        contradiction=contradiction,
    )
