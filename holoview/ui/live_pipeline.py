"""What the demodulation worker does with each frame (glue over holoview.processing).

Per frame: the display spectrum (at most :data:`SPECTRUM_HZ`), peak detection (at
most :data:`PEAKS_HZ`; carriers drift slowly; each of the two at most a
:data:`SIDE_SHARE` of the worker's time), the labelled peaks followed onto the
detected ones, the model's predicted carriers once two are labelled (and the
detected peaks they match labelled too), the demodulated delta-h map of every
labelled peak, the peaks' displacements (measured at most :data:`COREGISTER_HZ`,
:mod:`holoview.processing.coregister`), the fused map co-registered by them, and
the mean depth series with the evaporation rate.
All the numbers come from :mod:`holoview.processing` and :mod:`holoview.optics`;
this module only decides when to call what, and packs a :class:`LiveResult`.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from holoview.acquire.source import FrameMeta
from holoview.errors import HoloviewError, InputError
from holoview.optics.families import alpha_of
from holoview.processing.coregister import (
    MIN_MAP_SIDE,
    Displacement,
    DisplacementEstimator,
    fuse_coregistered,
)
from holoview.processing.demodulate import DemodResult, Demodulator
from holoview.processing.labelling import label_peaks
from holoview.processing.peaks import Peak, find_peaks
from holoview.processing.spectrum import display_spectrum
from holoview.processing.windows import wrap_frequency
from holoview.ui.settings import ExperimentSettings

logger = logging.getLogger(__name__)

#: Highest rate of the display spectrum, Hz.
SPECTRUM_HZ = 10.0
#: Highest rate of peak detection, Hz.
PEAKS_HZ = 1.0
#: Most of the worker's time the display spectrum and the peak detection may each take
#: (their rates drop below the ones above when a frame is large or the machine slow).
SIDE_SHARE = 0.1
#: FFTW threads of the live worker. One: the GUI thread needs the other core, and a
#: two-thread FFT whose second thread waits for a busy core takes 10-100 times longer.
FFT_THREADS = 1
#: Largest side of the spectrum image handed to the window (block maxima beyond).
SPECTRUM_DISPLAY_MAX = 512
#: A labelled or predicted carrier follows a detected peak within this, cycles/pixel.
FOLLOW_DISTANCE = 0.02
#: Depth series kept for the trends plot, frames (10 minutes at 60 frames/s).
TREND_LENGTH = 36000
#: Highest rate at which depths, rate and PCA are recomputed from the series, Hz.
TREND_HZ = 2.0
#: Highest rate at which maps are added to the displacement estimate, Hz.
COREGISTER_HZ = 2.0
#: Families whose predicted carriers are drawn and matched once two peaks are labelled.
PREDICTED_FAMILIES: tuple[str, ...] = ("RF", "RB1", "FB1", "RB2", "FB2")

Carrier = tuple[float, float]


@dataclass(frozen=True)
class LiveResult:
    """Everything the window draws for one processed frame.

    Arrays are shared, never modified after publication. Heights in metres, phases
    in radians, carriers and radius in cycles per pixel, times in seconds.
    ``shifts_px`` holds the measured displacements ``(dy, dx)`` of the height maps
    against the map ``grid_of``, in camera pixels; the fused map is on that map's grid.
    """

    seq: int
    frame: np.ndarray
    frame_id: int
    t_host: float
    processing_s: float
    spectrum: np.ndarray | None
    peaks: list[Carrier]
    labelled: dict[str, Carrier]
    predicted: dict[str, Carrier]
    radius: float
    heights_m: dict[str, np.ndarray] = field(default_factory=dict)
    fused_m: np.ndarray | None = None
    phases_rad: dict[str, np.ndarray] = field(default_factory=dict)
    shifts_px: dict[str, tuple[float, float]] = field(default_factory=dict)
    grid_of: str | None = None
    trend_times_s: np.ndarray | None = None
    trend_depths_m: dict[str, np.ndarray] = field(default_factory=dict)
    rate_m_per_s: float | None = None
    rate_stderr_m_per_s: float | None = None
    rate_fit: tuple[list[float], list[float]] | None = None
    pca_confidence: float | None = None
    pca_prefactors: dict[str, float] | None = None
    notes: tuple[str, ...] = ()


def block_max(image: np.ndarray, limit: int) -> np.ndarray:
    """Shrink ``image`` by an integer factor with block maxima so no side exceeds ``limit``.

    Maxima keep narrow peaks visible where averaging would blur them away.
    """
    factor = max(1, math.ceil(max(image.shape) / limit))
    if factor == 1:
        return image
    rows, cols = image.shape[0] // factor, image.shape[1] // factor
    out = image[0 : rows * factor : factor, 0 : cols * factor : factor].copy()
    for dy in range(factor):
        for dx in range(factor):
            if dy or dx:
                np.maximum(
                    out, image[dy : rows * factor : factor, dx : cols * factor : factor], out=out
                )
    return out


def fold(carrier: Carrier) -> Carrier:
    """Return where a carrier beyond Nyquist appears in the spectrum (cycles/pixel)."""
    fx, fy = wrap_frequency(np.asarray(carrier, dtype=float))
    return (float(fx), float(fy))


def nearest_peak(
    carrier: Carrier, peaks: list[Peak], distance: float = FOLLOW_DISTANCE
) -> Peak | None:
    """Return the detected peak nearest ``carrier`` within ``distance``, on the twin nearest it.

    A peak found on its other twin is returned flipped, so its carrier is the one
    near ``carrier``. None when no peak is that close.
    """
    best, best_d = None, distance
    for peak in peaks:
        for candidate in (peak, peak.flipped()):
            d = math.dist(candidate.carrier, carrier)
            if d <= best_d:
                best, best_d = candidate, d
    return best


def model_alpha(label: str, e: ExperimentSettings) -> float | None:
    """The model prefactor of ``label``, or None for a label the model does not know."""
    try:
        return alpha_of(label, e.n1, e.n2)
    except InputError:
        return None


class DemodulationStage:
    """Keep a :class:`Demodulator` for the labelled peaks; rebuild it only when needed.

    The demodulator is rebuilt when a label appears or goes, a carrier moves by a
    whole FFT bin, or the radius, window, reference or optics change (a rebuild
    restarts the absolute reference).
    """

    def __init__(self, frame_shape: tuple[int, int], saturation: float | None = None) -> None:
        self.frame_shape = frame_shape
        self.saturation = saturation
        self._demod: Demodulator | None = None
        self._settings: tuple | None = None

    def _needs_rebuild(self, peaks: list[Peak], e: ExperimentSettings) -> bool:
        """True when labels, settings or a carrier (by a whole FFT bin) changed."""
        demod = self._demod
        if demod is None or self._settings != (e.radius, e.window, e.reference, e.wavelength_m):
            return True
        if [(p.label, p.alpha) for p in peaks] != [(p.label, p.alpha) for p in demod.peaks]:
            return True
        rows, cols = self.frame_shape
        return any(
            abs(p.carrier[0] - q.carrier[0]) * cols > 1.0
            or abs(p.carrier[1] - q.carrier[1]) * rows > 1.0
            for p, q in zip(peaks, demod.peaks, strict=True)
        )

    def reset_reference(self) -> None:
        """Make the next frame the absolute reference (maps start from zero again)."""
        if self._demod is not None:
            self._demod.reset_reference()

    def run(
        self, frame: np.ndarray, peaks: list[Peak], e: ExperimentSettings
    ) -> DemodResult | None:
        """Demodulate ``frame`` at ``peaks`` (labelled, with alpha where known); None if none."""
        if not peaks:
            self._demod = None
            return None
        if self._needs_rebuild(peaks, e):
            self._demod = None
            self._demod = Demodulator(
                self.frame_shape,
                peaks,
                window=e.window,
                radius=e.radius,
                reference=e.reference,
                wavelength=e.wavelength_m,
                saturation=self.saturation,
                threads=FFT_THREADS,
            )
            self._settings = (e.radius, e.window, e.reference, e.wavelength_m)
        assert self._demod is not None
        return self._demod.process(frame)


def trusted_heights(result: DemodResult) -> list[np.ndarray]:
    """The frame's delta-h maps (m), NaN where untrusted, for the peaks that have one."""
    return [np.where(r.mask, r.delta_h, np.nan) for r in result.peaks if r.delta_h is not None]


def fuse_maps(
    result: DemodResult,
    maps: list[np.ndarray],
    displacements: list[Displacement] | None = None,
) -> np.ndarray | None:
    """Fuse the frame's :func:`trusted_heights` ``maps``; None with fewer than two.

    Each peak is weighted by ``1 / noise_height^2``; on a frame with no noise estimate
    (a reference frame) the trusted pixels are averaged. With ``displacements`` (one
    per map) the maps are first co-registered onto the first one's grid, by cubic
    convolution (fast enough for every frame;
    :func:`~holoview.processing.coregister.fuse_coregistered`).
    """
    if len(maps) < 2:
        return None
    noises = [r.noise_height for r in result.peaks if r.delta_h is not None]
    shifts = None if displacements is None else [d.shift for d in displacements]
    return fuse_coregistered(maps, noises, shifts, method="cubic")


class Coregistration:
    """The displacements of the labelled peaks' height maps, measured as frames come.

    A new estimate starts whenever the peaks with height maps or the map shape change;
    maps are added at most :data:`COREGISTER_HZ` times a second. Maps smaller than
    :data:`~holoview.processing.coregister.MIN_MAP_SIDE` are not co-registered.
    """

    def __init__(self) -> None:
        self._estimator: DisplacementEstimator | None = None
        self._key: tuple | None = None
        self._added_at = -math.inf

    def update(
        self, result: DemodResult, maps: list[np.ndarray], now: float
    ) -> list[Displacement] | None:
        """Add the frame's :func:`trusted_heights` ``maps`` when due; one displacement each."""
        if len(maps) < 2 or min(result.box_shape) < MIN_MAP_SIDE:
            return None
        labels = tuple(r.peak.label for r in result.peaks if r.delta_h is not None)
        key = (labels, result.box_shape)
        if key != self._key or self._estimator is None:
            self._estimator = DisplacementEstimator(result.box_shape, len(maps))
            self._key = key
            self._added_at = -math.inf
        if now - self._added_at >= 1.0 / COREGISTER_HZ and not result.flags & {"reference"}:
            self._estimator.add(maps)
            self._added_at = now
        return self._estimator.displacements()


class LivePipeline:
    """Turn frames into :class:`LiveResult` objects; used by one thread at a time.

    Commands (:meth:`apply`) change the experiment settings, turn the PCA on or off,
    or restart the series (and the absolute reference) from the next frame.

    Parameters
    ----------
    experiment : ExperimentSettings
        Optics, labelled peaks, window and reference mode.
    frame_shape : tuple of int
        ``(rows, cols)`` of the frames, pixels.
    """

    def __init__(
        self,
        experiment: ExperimentSettings,
        frame_shape: tuple[int, int],
        saturation: float | None = None,
    ) -> None:
        self.experiment = experiment
        self.frame_shape = frame_shape
        self.pca = False
        #: Detect peaks inside :meth:`process`; the live worker turns this off and feeds
        #: :meth:`set_peaks` from its own peak thread instead.
        self.detect_inline = True
        self._seq = 0
        self._spectrum: np.ndarray | None = None
        self._spectrum_at = -math.inf
        self._spectrum_cost = 0.0
        self._peaks_cost = 0.0
        self._peaks: list[Peak] = []
        self._peaks_at = -math.inf
        self._demod = DemodulationStage(frame_shape, saturation)
        self._coregistration = Coregistration()
        self._trends = TrendStage()
        self._trend: TrendSummary | None = None
        self._trend_at = -math.inf
        self._labelling_key: tuple | None = None
        self._matched: dict[str, Peak] = {}
        self._labelling: tuple[list[Peak], dict[str, Carrier], list[str]] = ([], {}, [])

    def apply(self, name: str, value: object) -> None:
        """Apply a command: ``experiment`` (new settings), ``pca`` (bool), ``reset``."""
        if name == "experiment":
            if not isinstance(value, ExperimentSettings):
                raise InputError(f"experiment command needs ExperimentSettings, not {value!r}")
            self.experiment = value
            self._peaks_at = -math.inf  # detect again with the new radius
        elif name == "pca":
            self.pca = bool(value)
        elif name == "reset":
            self._trends.reset()
            self._trend = None
            self._demod.reset_reference()
        else:
            raise InputError(f"unknown command {name!r}")

    def labelled_peaks(self) -> tuple[list[Peak], dict[str, Carrier], list[str]]:
        """Return the peaks to demodulate, the model's predicted carriers, and notes.

        Operator labels follow the detected peak nearest them. With two labels the
        model (:func:`holoview.processing.labelling.label_peaks`) places the other
        families of :data:`PREDICTED_FAMILIES`, and the detected peaks they land on
        are labelled too. Notes say what the operator should know (a label that
        matches no peak, a label probably on the wrong twin).
        """
        e = self.experiment
        notes: list[str] = []
        chosen: list[Peak] = []
        for p in e.peaks:
            found = nearest_peak((p.fx, p.fy), self._peaks)
            if found is None:
                notes.append(f"{p.label}: no peak detected near its position any more")
            base = found or Peak(carrier=fold((p.fx, p.fy)), amplitude=float("nan"), snr=0.0)
            chosen.append(base.relabelled(p.label, model_alpha(p.label, e)))
        known = {p.label: p.carrier for p in chosen if p.alpha is not None}
        predicted: dict[str, Carrier] = {}
        if len(known) < 2 or not self._peaks:
            return chosen, predicted, notes
        try:
            model = label_peaks(
                [p.carrier for p in self._peaks], known, e.n1, e.n2, self.frame_shape
            )
        except InputError as exc:
            notes.append(f"model labelling: {exc}")
            return chosen, predicted, notes
        for name in model.flip_hint:
            notes.append(f"{name} is probably on the wrong twin: label its twin instead")
        taken = set(known)
        kept: dict[str, Peak] = {}
        for prediction in model.predictions:
            name = prediction.label
            if name not in PREDICTED_FAMILIES:
                continue
            predicted[name] = prediction.carrier
            if prediction.folded:
                notes.append(f"{name} lies past Nyquist: it appears folded back")
            if name in taken:
                continue
            if prediction.peak is not None:
                peak = self._peaks[prediction.peak]
                peak = peak.flipped() if prediction.twin else peak
            else:
                # a faint peak missed by one detection keeps its last match, so the
                # set of maps does not flicker
                peak = self._matched.get(name)
                if peak is None or math.dist(peak.carrier, prediction.carrier) > FOLLOW_DISTANCE:
                    continue
            kept[name] = peak
            chosen.append(peak.relabelled(name, model_alpha(name, e)))
            taken.add(name)
        self._matched = kept
        return chosen, predicted, notes

    def peaks_due(self, now: float | None = None) -> bool:
        """Whether peak detection is due (at most :data:`PEAKS_HZ`, :data:`SIDE_SHARE`)."""
        now = time.monotonic() if now is None else now
        return now - self._peaks_at >= max(1.0 / PEAKS_HZ, self._peaks_cost / SIDE_SHARE)

    def peaks_started(self) -> None:
        """Note that a detection started now (on another thread)."""
        self._peaks_at = time.monotonic()

    def peaks_done(self, cost_s: float) -> None:
        """Note what the last detection cost, seconds (it spaces the next one)."""
        self._peaks_at = time.monotonic()
        self._peaks_cost = cost_s

    def set_peaks(self, peaks: list[Peak]) -> None:
        """Use newly detected peaks from the next frame on."""
        self._peaks = list(peaks)

    def process(self, frame: np.ndarray, meta: FrameMeta) -> LiveResult:
        """Process one frame; raise HoloviewError for a problem the operator can fix."""
        start = time.perf_counter()
        now = time.monotonic()
        e = self.experiment
        if now - self._spectrum_at >= max(1.0 / SPECTRUM_HZ, self._spectrum_cost / SIDE_SHARE):
            tick = time.perf_counter()
            self._spectrum = block_max(
                display_spectrum(frame, threads=FFT_THREADS), SPECTRUM_DISPLAY_MAX
            )
            self._spectrum_cost = time.perf_counter() - tick
            self._spectrum_at = now
        if self.detect_inline and self.peaks_due(now):
            tick = time.perf_counter()
            self.set_peaks(find_peaks(frame, radius=e.radius, threads=FFT_THREADS))
            self.peaks_done(time.perf_counter() - tick)
        key = (id(self._peaks), e)
        if key != self._labelling_key:
            self._labelling = self.labelled_peaks()
            self._labelling_key = key
        peaks, predicted, notes = self._labelling
        demod = self._demod.run(frame, peaks, e)
        heights: dict[str, np.ndarray] = {}
        phases: dict[str, np.ndarray] = {}
        shifts: dict[str, tuple[float, float]] = {}
        grid_of = None
        fused = None
        trend = None
        if demod is not None:
            for r in demod.peaks:
                name = r.peak.label or "?"
                phases[name] = r.phase
                if r.delta_h is not None:
                    heights[name] = r.delta_h
            trusted = trusted_heights(demod)
            displacements = self._coregistration.update(demod, trusted, now)
            fused = fuse_maps(demod, trusted, displacements)
            if displacements is not None:
                grid_of = next(iter(heights))
                step = (
                    demod.frame_shape[0] / demod.box_shape[0],
                    demod.frame_shape[1] / demod.box_shape[1],
                )
                for name, d in zip(heights, displacements, strict=True):
                    if d.measured:
                        shifts[name] = (d.shift[0] * step[0], d.shift[1] * step[1])
            self._trends.add(
                meta.t_host, {r.peak.label or "?": r.carrier_value for r in demod.peaks}
            )
            if now - self._trend_at >= 1.0 / TREND_HZ:
                alphas = {p.label: p.alpha for p in peaks if p.label and p.alpha is not None}
                self._trend_at = now
                try:
                    self._trend = self._trends.summary(alphas, e.wavelength_m, e.n1, e.n2, self.pca)
                except HoloviewError as exc:
                    logger.debug("trends not available: %s", exc)
                    self._trend = None
            trend = self._trend
        self._seq += 1
        return LiveResult(
            seq=self._seq,
            frame=frame,
            frame_id=meta.frame_id,
            t_host=meta.t_host,
            processing_s=time.perf_counter() - start,
            spectrum=self._spectrum,
            peaks=[p.carrier for p in self._peaks],
            labelled={p.label: p.carrier for p in peaks if p.label},
            predicted=predicted,
            radius=e.radius if demod is None else demod.radius,
            heights_m=heights,
            fused_m=fused,
            phases_rad=phases,
            shifts_px=shifts,
            grid_of=grid_of,
            trend_times_s=None if trend is None else trend.times_s,
            trend_depths_m={} if trend is None else trend.depths_m,
            rate_m_per_s=None if trend is None else trend.rate_m_per_s,
            rate_stderr_m_per_s=None if trend is None else trend.rate_stderr_m_per_s,
            rate_fit=None if trend is None else trend.rate_fit,
            pca_confidence=None if trend is None else trend.pca_confidence,
            pca_prefactors=None if trend is None else trend.pca_prefactors,
            notes=tuple(notes),
        )


@dataclass(frozen=True)
class TrendSummary:
    """Depth series and rate for the trends view (metres, seconds)."""

    times_s: np.ndarray
    depths_m: dict[str, np.ndarray]
    rate_m_per_s: float | None
    rate_stderr_m_per_s: float | None
    rate_fit: tuple[list[float], list[float]] | None
    pca_confidence: float | None = None
    pca_prefactors: dict[str, float] | None = None


class TrendStage:
    """Keep each labelled peak's mean complex value per frame; derive depths and the rate.

    The mean phase is unwrapped in time, converted to depth with the model alpha
    of each label, fused with weights from each series' noise, and fitted with a
    line (all by :mod:`holoview.processing.trends`). The series restarts whenever
    the set of labels changes.
    """

    def __init__(self, length: int = TREND_LENGTH) -> None:
        self.length = length
        self.reset()

    def reset(self) -> None:
        """Forget the series."""
        self._labels: tuple[str, ...] = ()
        self._t0: float | None = None
        self._times: list[float] = []
        self._values: list[np.ndarray] = []

    def add(self, t_host: float, values: dict[str, complex]) -> None:
        """Add one frame: ``values`` maps each label to its mean complex field value."""
        labels = tuple(values)
        if labels != self._labels:
            self.reset()
            self._labels = labels
        if self._t0 is None:
            self._t0 = t_host
        self._times.append(t_host - self._t0)
        self._values.append(np.array([values[k] for k in labels], dtype=np.complex128))
        if len(self._times) > self.length:
            del self._times[0], self._values[0]

    def summary(
        self,
        alphas: dict[str, float],
        wavelength_m: float,
        n1: float,
        n2: float,
        pca: bool = False,
    ) -> TrendSummary | None:
        """Return the depth series, fused depth and rate; None with fewer than 3 frames.

        Parameters
        ----------
        alphas : dict of str to float
            Model prefactor of each label (labels without one are left out).
        wavelength_m : float
            Laser wavelength, metres.
        n1, n2 : float
            Refractive indices above and below the surface (for the PCA's model alphas).
        pca : bool
            Also identify the peaks by temporal PCA (confidence and prefactors).
        """
        from holoview.processing.identify import identify_peaks
        from holoview.processing.trends import (
            depth_series,
            fit_rate,
            fuse_depths,
            series_noise,
            unwrap_in_time,
        )

        usable = [i for i, k in enumerate(self._labels) if k in alphas]
        if len(self._times) < 3 or not usable:
            return None
        times = np.asarray(self._times)
        values = np.asarray(self._values)
        phases = unwrap_in_time(values)
        names = [self._labels[i] for i in usable]
        depths = depth_series(phases[:, usable], [alphas[k] for k in names], wavelength_m)
        series = {k: depths[:, j] for j, k in enumerate(names)}
        rate = stderr = fit_line = None
        noise = series_noise(depths, times)
        if np.any(np.isfinite(noise) & (noise > 0)):
            fused = fuse_depths(depths, noise)
            series["fused"] = fused.depth
            fit = fit_rate(times, fused.depth)
            rate, stderr = fit.rate, fit.stderr
            ends = [float(times[0]), float(times[-1])]
            fit_line = (ends, [fit.intercept + fit.rate * t for t in ends])
        confidence = prefactors = None
        if pca and len(self._labels) >= 2 and names:
            reference_label = "RB1" if "RB1" in names else names[0]
            try:
                ident = identify_peaks(
                    phases,
                    n1,
                    n2,
                    reference=self._labels.index(reference_label),
                    reference_label=reference_label,
                )
            except InputError as exc:
                logger.debug("PCA identification not available: %s", exc)
            else:
                confidence = ident.confidence
                prefactors = {k: float(a) for k, a in zip(self._labels, ident.alphas, strict=True)}
        return TrendSummary(times, series, rate, stderr, fit_line, confidence, prefactors)
