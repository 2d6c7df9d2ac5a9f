"""After the frames: which peak is which, depth series, fused depth, rates and flags.

Everything here works on the per-frame carrier values a run kept
(:class:`~holoview.headless.run_data.RunData`), through :mod:`holoview.processing`:

- auto mode: :func:`~holoview.processing.naming.identify.identify_peaks` (the carrier lattice,
  with the temporal PCA confirming; off the lattice the PCA with the reference peak's
  label, de-aliasing from the phase steps) names every peak and gives
  its prefactor: the model's for a family, its repeats and second orders, the PCA's
  for a peak the model does not explain (left out of the fusion, as weak ones are). A
  peak with a negative prefactor sits on the other twin and is flipped;
- known prefactors (peaks file, labels): the PCA is computed for information when it
  can be (two peaks, frames that move);
- :func:`holoview.engine.series.summarise` (what the live trends view runs too): depth
  per peak relative to the first frame, aliasing in time, the fusion weighted by each
  series' noise, and the rates with standard errors.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np

from holoview.engine.depth import pca_check, summarise
from holoview.engine.series import JointSetup
from holoview.errors import InputError
from holoview.headless.inputs import Optics
from holoview.headless.run_data import RunData
from holoview.headless.selection import Selection
from holoview.processing.naming.identify import Identification, identify_peaks
from holoview.processing.naming.lattice_geometry import LatticePeak
from holoview.processing.naming.prefactors import PeakKind
from holoview.processing.peaks.detection import Peak
from holoview.processing.series.frame_gaps import lost_between
from holoview.processing.series.phase_series import check_aliasing
from holoview.processing.series.rate_fits import RateFit

logger = logging.getLogger(__name__)

#: A peak flagged ``low_amplitude`` in more than this fraction of the demodulated frames
#: gets the flag.
LOW_AMPLITUDE_SHARE = 0.5

#: Peak kinds of the PCA whose model prefactor is trusted (and fused).
_IDENTIFIED = (PeakKind.FAMILY, PeakKind.REPEAT, PeakKind.SECOND_ORDER)


@dataclass(frozen=True)
class PeakOutcome:
    """One peak after the run.

    Attributes
    ----------
    label : str
    carrier : tuple of float
        ``(fx, fy)``, cycles/pixel, on the stored twin (phase grows with height).
    alpha : float or None
        Prefactor on the stored twin (positive), None when unknown.
    amplitude, snr : float
        From the peak detection on the first frame (NaN for a peak not detected).
    flags : tuple of str
        Sorted: detection flags (``harmonic``, ``sum``, ``overlap``, ``near_nyquist``,
        ``weak``), ``aliased_in_time``, ``phase_step`` (some frame stepped past 0.8 pi),
        ``low_amplitude``, ``not_detected``, and from the PCA ``repeat``,
        ``second_order``, ``unexplained``.
    rate, rate_stderr : float or None
        Fitted depth rate and its standard error, m/s.
    noise_m : float or None
        Noise of the depth series about its line, m (the fusion weight's).
    map_noise_rad, map_noise_m : float or None
        Median over the frames of the per-pixel noise of the peak's map, rad and m
        (reference frames, whose maps are zero, left out).
    used_in_fused : bool
    pca_alpha, explained : float or None
        The PCA's prefactor on the stored twin and the share of the peak's variance
        along the principal component.
    lattice : LatticePeak or None
        Its place on the carrier lattice (point ``(fb1, rf)``, residual in FFT bins,
        kind, coupling), where the identification gave one.
    """

    label: str
    carrier: tuple[float, float]
    alpha: float | None
    amplitude: float
    snr: float
    flags: tuple[str, ...]
    rate: float | None
    rate_stderr: float | None
    noise_m: float | None
    map_noise_rad: float | None
    map_noise_m: float | None
    used_in_fused: bool
    pca_alpha: float | None
    explained: float | None
    lattice: LatticePeak | None = None


@dataclass(frozen=True)
class Analysis:
    """Series and summaries of a run.

    Attributes
    ----------
    peaks : tuple of PeakOutcome
        In demodulation order.
    phases : ndarray, shape (N, M)
        Mean phase per frame and peak, rad, unwrapped in time, from 0 at the first
        frame, on the stored twin.
    heights : ndarray, shape (N, M)
        Mean height change, m (NaN for a peak without alpha).
    fused : ndarray or None, shape (N,)
        Fused mean height change, m.
    fused_spread : ndarray or None, shape (N,)
        Weighted rms deviation of the fused peaks from it, m.
    fit : RateFit or None
        The fused depth's line (None with fewer than three frames or nothing fused).
    vibration, margins, flagged : ndarray or None, shape (N,)
        The joint estimate's reference-arm phase (rad), ambiguity margin (noise
        standard deviations) and frames not resolved with confidence; None without a
        joint estimate.
    pca : dict or None
        ``confidence``, ``reference`` (label), ``prefactors`` and ``explained`` per label,
        ``n_samples``; None when not computed.
    notes : tuple of str
        What a reader of the summary should know.
    """

    peaks: tuple[PeakOutcome, ...]
    phases: np.ndarray
    heights: np.ndarray
    fused: np.ndarray | None
    fused_spread: np.ndarray | None
    fit: RateFit | None
    pca: dict[str, object] | None
    notes: tuple[str, ...]
    vibration: np.ndarray | None = None
    margins: np.ndarray | None = None
    flagged: np.ndarray | None = None


def _auto_names(ident: Identification) -> list[str]:
    """Unique labels: families by name, repeats ``RB1_2``, ..., the rest ``P<index>``."""
    names: list[str | None] = [None] * len(ident.peaks)
    taken: set[str] = set()
    for kinds in ((PeakKind.FAMILY,), (PeakKind.SECOND_ORDER, PeakKind.REPEAT)):
        for p in ident.peaks:
            if p.kind not in kinds or not p.label:
                continue
            name, k = p.label, 1
            while name in taken:
                k += 1
                name = f"{p.label}_{k}"
            names[p.index] = name
            taken.add(name)
    return [name or f"P{i}" for i, name in enumerate(names)]


def _identify(
    phases: np.ndarray, data: RunData, selection: Selection, optics: Optics
) -> Identification:
    assert optics.n2 is not None
    if phases.shape[0] < 3:
        raise InputError("--auto needs at least three frames: the PCA follows the phases in time")
    steps = check_aliasing(data.values).measured_step
    amplitudes = [p.amplitude for p in selection.peaks]
    try:
        return identify_peaks(
            phases,
            optics.n1,
            optics.n2,
            reference=selection.reference,
            reference_label=selection.reference_label,
            amplitudes=amplitudes,
            steps=steps,
            carriers=None if selection.shape is None else [p.carrier for p in selection.peaks],
            shape=selection.shape,
        )
    except InputError as exc:
        raise InputError(
            f"--auto: the PCA cannot identify the peaks ({exc}); label them instead "
            "(--label or --peaks)"
        ) from exc


@dataclass
class Naming:
    """What the peaks are: label, signed alpha on the demodulated twin, fusable, PCA's view.

    Known before the frames for labelled peaks (:func:`name_peaks`); in auto mode from
    the series, after it, and before any map is made (the maps take its prefactors).
    """

    labels: list[str]
    signed: list[float | None]
    fusable: list[bool]
    pca_alpha: list[float | None]
    explained: list[float | None]
    ident: Identification | None = None
    flags: list[set[str]] = field(default_factory=list)

    def joint(self, optics: Optics) -> JointSetup:
        """The joint estimate of these peaks: the fusable ones, their couplings."""
        return JointSetup.of(
            self.labels,
            self.signed,
            wavelength_m=optics.wavelength_m,
            n1=optics.n1,
            n2=optics.n2,
            exclude=[not f for f in self.fusable],
        )

    def peaks(self, selection: Selection) -> tuple[Peak, ...]:
        """The selection's peaks as the maps take them: these labels and signed prefactors."""
        return tuple(
            replace(p, label=label, alpha=alpha)
            for p, label, alpha in zip(selection.peaks, self.labels, self.signed, strict=True)
        )

    @property
    def exclude(self) -> tuple[bool, ...]:
        """Peaks kept out of the fusion: those the identification could not explain."""
        return tuple(not f for f in self.fusable)


def _given_names(selection: Selection) -> Naming:
    peaks = selection.peaks
    m = len(peaks)
    return Naming(
        labels=[p.label or f"P{j}" for j, p in enumerate(peaks)],
        signed=[p.alpha for p in peaks],
        fusable=[p.alpha is not None for p in peaks],
        pca_alpha=[None] * m,
        explained=[None] * m,
        flags=[set() for _ in range(m)],
    )


def known_joint(selection: Selection, optics: Optics) -> JointSetup | None:
    """The joint estimate :func:`analyse` will make, when it is known before the frames.

    Known prefactors (labels, an experiment): a run can estimate the frames jointly as
    they come, and :func:`analyse` keeps that estimate. None in auto mode (the PCA
    names the peaks after the run).
    """
    if selection.mode == "auto" or optics.wavelength_m is None:
        return None
    return _given_names(selection).joint(optics)


def name_peaks(data: RunData, selection: Selection, optics: Optics) -> Naming:
    """What each peak is: the selection's labels, or in auto mode the identification's.

    Raises
    ------
    InputError
        In auto mode, when the PCA cannot identify the peaks (too few frames, no motion).
    """
    if selection.mode != "auto":
        return _given_names(selection)
    return _pca_names(_identify(data.series.unwrapped(), data, selection, optics))


def _pca_names(ident: Identification) -> Naming:
    """Labels and prefactors from the PCA identification (module docstring), and flags."""
    m = len(ident.peaks)
    naming = Naming(
        labels=_auto_names(ident),
        signed=[None] * m,
        fusable=[False] * m,
        pca_alpha=[p.alpha for p in ident.peaks],
        explained=[p.explained for p in ident.peaks],
        ident=ident,
        flags=[set() for _ in range(m)],
    )
    flags = naming.flags
    for j, p in enumerate(ident.peaks):
        if p.aliased:
            flags[j].add("aliased_in_time")
        if p.kind in _IDENTIFIED and p.expected_alpha is not None:
            naming.signed[j] = math.copysign(p.expected_alpha, p.alpha)
            naming.fusable[j] = True
            if p.kind is PeakKind.REPEAT:
                flags[j].add("repeat")
            if p.kind is PeakKind.SECOND_ORDER:
                flags[j].add("second_order")
        else:
            if math.isfinite(p.alpha) and p.alpha != 0:
                naming.signed[j] = p.alpha
            flags[j].add("weak" if p.kind is PeakKind.WEAK else "unexplained")
    return naming


def _run_flags(selection: Selection, data: RunData) -> list[set[str]]:
    """Detection flags of each peak, and those the run raised often enough."""
    flags: list[set[str]] = [set(p.flags) for p in selection.peaks]
    for j, p in enumerate(selection.peaks):
        if not p.amplitude >= 0:
            flags[j].add("not_detected")
        counts = data.peak_flags[j]
        if counts["phase_step"]:
            flags[j].add("phase_step")
        if counts["low_amplitude"] > LOW_AMPLITUDE_SHARE * data.demodulated:
            flags[j].add("low_amplitude")
    return flags


def _lattice_of(selection: Selection, naming: Naming, j: int) -> LatticePeak | None:
    """Peak ``j``'s place on the lattice: the auto identification's, else the selection's."""
    ident = naming.ident
    if ident is not None and ident.lattice is not None:
        return ident.lattice.peaks[j]
    return selection.lattice[j] if j < len(selection.lattice) else None


def _lost_note(intervals: np.ndarray, times: np.ndarray, frames: np.ndarray) -> str | None:
    """The frames the camera lost (steps of several frame intervals), in one note."""
    lost, gaps = lost_between(intervals)
    if not gaps.size:
        return None
    longest = int(gaps[np.argmax(intervals[gaps])])
    return (
        f"{lost} frames lost in {gaps.size} gap{'' if gaps.size == 1 else 's'} (the longest, "
        f"{int(intervals[longest]) - 1} frames, after frame {int(frames[longest - 1])} at "
        f"{float(times[longest - 1]):.4g} s): the height steps across each are resolved over "
        "the frame intervals it spans"
    )


def analyse(data: RunData, selection: Selection, optics: Optics, naming: Naming) -> Analysis:
    """Convert the series to depths, fuse, fit rates, set flags (the peaks ``naming`` says).

    The joint estimate is :meth:`Naming.joint` (a run that knew it before its frames
    made it as they came: nothing is done again).
    """
    wavelength = optics.wavelength_m
    assert wavelength is not None
    flags = _run_flags(selection, data)
    for j, more in enumerate(naming.flags):
        flags[j] |= more
    labels, signed = naming.labels, naming.signed
    # a peak with a negative prefactor is stored on its other twin (docs/design.md)
    signs = [-1.0 if (a is not None and a < 0) else 1.0 for a in signed]
    alphas = [abs(a) if a is not None else None for a in signed]
    joint = naming.joint(optics)
    joint.track(data.series)
    summary = summarise(data.series, signed, wavelength, exclude=list(joint.exclude))
    notes = [*selection.notes, *data.notes]
    if summary.note is not None:
        notes.append(summary.note)
        logger.warning("%s", summary.note)
    lost = _lost_note(data.series.intervals, data.series.times, data.series.frames)
    if lost is not None:
        notes.append(lost)
        logger.warning("%s", lost)
    flagged, margins = summary.flagged, summary.margins
    if flagged is not None and margins is not None and flagged.any():
        count, smallest = int(flagged.sum()), float(np.min(margins))
        note = (
            f"{count} frames' phase ambiguity not resolved with confidence (smallest margin "
            f"{smallest:.2f} noise standard deviations; their best solution is used)"
        )
        notes.append(note)
        logger.info("%s", note)
    for j, aliased in enumerate(summary.aliased):
        if aliased:
            flags[j].add("aliased_in_time")
    if naming.ident is not None:
        pca_info: dict[str, object] | None = {
            "confidence": naming.ident.confidence,
            "reference": labels[naming.ident.reference],
            "prefactors": {
                labels[j]: float(a * signs[j])
                for j, a in enumerate(naming.pca_alpha)
                if a is not None
            },
            "explained": {
                labels[j]: float(e) for j, e in enumerate(naming.explained) if e is not None
            },
            "n_samples": naming.ident.pca.n_samples,
        }
    else:
        pca_info = pca_check(summary.phases, labels, alphas)
    live = np.where(data.noise_rad > 0, data.noise_rad, np.nan)
    outcomes = []
    for j, p in enumerate(selection.peaks):
        column = live[:, j][np.isfinite(live[:, j])]
        map_noise = float(np.median(column)) if column.size else None
        carrier = p.carrier if signs[j] > 0 else p.flipped().carrier
        pca_alpha = naming.pca_alpha[j]
        fit = summary.peak_fits[j]
        alpha = alphas[j]
        outcomes.append(
            PeakOutcome(
                label=labels[j],
                carrier=(float(carrier[0]), float(carrier[1])),
                alpha=alpha,
                amplitude=float(p.amplitude),
                snr=float(p.snr),
                flags=tuple(sorted(flags[j])),
                rate=None if fit is None else fit.rate,
                rate_stderr=None if fit is None else fit.stderr,
                noise_m=summary.noise_m[j],
                map_noise_rad=map_noise,
                map_noise_m=None
                if map_noise is None or alpha is None
                else map_noise * wavelength / (4 * np.pi * alpha),
                used_in_fused=summary.used[j],
                pca_alpha=None if pca_alpha is None else float(pca_alpha * signs[j]),
                explained=naming.explained[j],
                lattice=_lattice_of(selection, naming, j),
            )
        )
    return Analysis(
        peaks=tuple(outcomes),
        phases=summary.phases,
        heights=summary.heights,
        fused=summary.fused,
        fused_spread=summary.fused_spread,
        fit=summary.fit,
        pca=pca_info,
        notes=tuple(notes),
        vibration=summary.vibration,
        margins=summary.margins,
        flagged=summary.flagged,
    )
