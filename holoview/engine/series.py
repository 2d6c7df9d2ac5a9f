"""The mean-phase series of a run and what follows from it: depths, fused depth, rates.

Per frame, each demodulated peak gives its carrier value (a complex number whose phase
is the peak's spatially averaged phase, paper section 4.2), its per-pixel phase noise
and its flags; :class:`PhaseSeries` keeps them for every frame it is given (the whole
run headless; the last :data:`LIVE_LENGTH` frames live). :func:`summarise` turns a
series into depths per peak, the fused depth and the rates, through
:func:`holoview.processing.trends.track_depth` (unwrapping in time, the aliasing check,
noise-weighted fusion, line fits); :func:`pca_check` is the temporal PCA of peaks whose
prefactors are known, for information. The live trends view and ``holoview process``
both call these, so they agree on the same frames.

Times are in s from the series' first frame, phases in rad, depths in m.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from holoview.errors import InputError
from holoview.processing.demodulate import DemodResult
from holoview.processing.pca import phase_pca
from holoview.processing.trends import RateFit, track_depth, unwrap_in_time

logger = logging.getLogger(__name__)

__all__ = [
    "COUNTED_FRAME_FLAGS",
    "COUNTED_PEAK_FLAGS",
    "DepthSummary",
    "PhaseSeries",
    "frame_time",
    "pca_check",
    "summarise",
]

#: Per-frame peak flags counted over a series.
COUNTED_PEAK_FLAGS = ("phase_step", "low_amplitude", "overlap")
#: Frame-level flags counted over a series.
COUNTED_FRAME_FLAGS = ("nonfinite", "no_signal", "saturated")
#: Frames a live series keeps (10 minutes at 60 frames/s).
LIVE_LENGTH = 36000


def frame_time(t_device: float, t_host: float) -> float:
    """A frame's time, s: the camera's clock where it has one, else the host's arrival time."""
    return t_device if math.isfinite(t_device) else t_host


class PhaseSeries:
    """Per-frame carrier values, noise and flags of a fixed list of peaks.

    Parameters
    ----------
    labels : sequence of str
        The peaks, in the demodulator's order.
    capacity : int
        Frames to allocate at first (the arrays grow by doubling).
    max_length : int, optional
        Keep only the newest ``max_length`` frames (live); unbounded by default.

    Attributes
    ----------
    frame_flags : dict of str to int
        Frames flagged ``nonfinite``, ``no_signal``, ``saturated`` so far.
    peak_flags : list of dict of str to int
        Per peak, frames flagged ``phase_step``, ``low_amplitude``, ``overlap`` so far.
    """

    def __init__(
        self, labels: Sequence[str], capacity: int = 1024, max_length: int | None = None
    ) -> None:
        self.labels = tuple(labels)
        self.max_length = max_length
        m = len(self.labels)
        n = max(1, capacity if max_length is None else min(capacity, max_length))
        self._t = np.zeros(n)
        self._frames = np.zeros(n, dtype=np.int64)
        self._values = np.zeros((n, m), dtype=np.complex128)
        self._noise = np.zeros((n, m))
        self._steps = np.zeros((n, m), dtype=bool)
        self._n = 0
        self._t0: float | None = None
        self.frame_flags = dict.fromkeys(COUNTED_FRAME_FLAGS, 0)
        self.peak_flags = [dict.fromkeys(COUNTED_PEAK_FLAGS, 0) for _ in range(m)]

    @classmethod
    def from_arrays(
        cls,
        labels: Sequence[str],
        *,
        times: np.ndarray,
        frames: np.ndarray,
        values: np.ndarray,
        noise_rad: np.ndarray,
        phase_steps: np.ndarray,
    ) -> PhaseSeries:
        """A series holding given per-frame arrays (times in s from 0; flag counts empty).

        Raises
        ------
        InputError
            When the arrays' shapes disagree with each other or with ``labels``.
        """
        n, m = len(times), len(labels)
        shapes = {
            "frames": (np.shape(frames), (n,)),
            "values": (np.shape(values), (n, m)),
            "noise_rad": (np.shape(noise_rad), (n, m)),
            "phase_steps": (np.shape(phase_steps), (n, m)),
        }
        for name, (got, want) in shapes.items():
            if got != want:
                raise InputError(f"{name} has shape {got}, expected {want}")
        series = cls(labels, capacity=n)
        series._t[:n] = times
        series._frames[:n] = frames
        series._values[:n] = values
        series._noise[:n] = noise_rad
        series._steps[:n] = phase_steps
        series._n = n
        series._t0 = 0.0
        return series

    def __len__(self) -> int:
        return self._n

    def _make_room(self) -> None:
        size = self._t.shape[0]
        if self._n < size:
            return
        if self.max_length is not None and size >= self.max_length:
            keep = self.max_length // 2
            for name in ("_t", "_frames", "_values", "_noise", "_steps"):
                array = getattr(self, name)
                array[:keep] = array[self._n - keep : self._n]
            self._n = keep
            return
        grow = size if self.max_length is None else min(size, self.max_length - size)
        for name in ("_t", "_frames", "_values", "_noise", "_steps"):
            array = getattr(self, name)
            setattr(self, name, np.concatenate([array, np.zeros_like(array[:grow])]))

    def add(self, t_s: float, frame: int, result: DemodResult) -> None:
        """Add one frame: its time (s, any origin), input index and demodulation.

        A frame with no peak results (flagged ``nonfinite``) gets NaN values.
        """
        if result.peaks and len(result.peaks) != len(self.labels):
            raise InputError(
                f"a frame of {len(result.peaks)} peaks added to a series of {len(self.labels)}"
            )
        self._make_room()
        if self._t0 is None:
            self._t0 = t_s
        i = self._n
        self._t[i] = t_s - self._t0
        self._frames[i] = frame
        for flag in result.flags:
            if flag in self.frame_flags:
                self.frame_flags[flag] += 1
        if not result.peaks:
            self._values[i] = np.nan
            self._noise[i] = np.nan
            self._steps[i] = False
        for j, r in enumerate(result.peaks):
            self._values[i, j] = r.carrier_value
            self._noise[i, j] = r.noise
            self._steps[i, j] = "phase_step" in r.flags
            for flag in r.flags:
                if flag in self.peak_flags[j]:
                    self.peak_flags[j][flag] += 1
        self._n += 1

    def truncate(self, n: int) -> None:
        """Keep the first ``n`` frames only (an interrupted run)."""
        self._n = min(self._n, max(0, n))

    @property
    def times(self) -> np.ndarray:
        """Frame times, s, from 0 at the first frame added (a view)."""
        return self._t[: self._n]

    @property
    def frames(self) -> np.ndarray:
        """Input frame indices (a view)."""
        return self._frames[: self._n]

    @property
    def values(self) -> np.ndarray:
        """Carrier value per frame and peak, counts (a view; NaN: not demodulated)."""
        return self._values[: self._n]

    @property
    def noise_rad(self) -> np.ndarray:
        """Per-pixel phase noise of each map, rad (0 on a reference frame; a view)."""
        return self._noise[: self._n]

    @property
    def phase_steps(self) -> np.ndarray:
        """Whether each peak's mean phase stepped past the limit at each frame (a view)."""
        return self._steps[: self._n]

    def unwrapped(self) -> np.ndarray:
        """Mean phase per frame and peak, rad, unwrapped in time from the first frame.

        NaN where a frame was not demodulated.
        """
        if len(self) < 2:
            return np.where(np.isfinite(self.values), 0.0, np.nan).real
        phases = unwrap_in_time(self.values)
        return np.where(np.isfinite(self.values), phases, np.nan)


@dataclass(frozen=True)
class DepthSummary:
    """Depths and rates of a series.

    Attributes
    ----------
    times : ndarray, shape (N,)
        Frame times, s.
    phases : ndarray, shape (N, M)
        Mean phase per peak, rad, unwrapped in time from 0 at the first frame, on the
        twins the alphas' signs give (phase grows with the height).
    heights : ndarray, shape (N, M)
        Mean height change per peak, m (NaN for a peak without alpha).
    fused, fused_spread : ndarray or None, shape (N,)
        Noise-weighted mean height change of the fused peaks and their weighted rms
        deviation from it, m.
    fit : RateFit or None
        Line through the fused depth (m/s).
    peak_fits : tuple of (RateFit or None)
        Line through each peak's depth.
    noise_m : tuple of (float or None)
        Each peak's depth noise about its line, m (its fusion weight's).
    used : tuple of bool
        Whether each peak is in the fused depth.
    aliased : tuple of bool
        Whether each peak's phase steps near pi per frame (aliasing in time).
    note : str or None
        Why there is no fused depth, when there is none.
    """

    times: np.ndarray
    phases: np.ndarray
    heights: np.ndarray
    fused: np.ndarray | None
    fused_spread: np.ndarray | None
    fit: RateFit | None
    peak_fits: tuple[RateFit | None, ...]
    noise_m: tuple[float | None, ...]
    used: tuple[bool, ...]
    aliased: tuple[bool, ...]
    note: str | None = None


def summarise(
    series: PhaseSeries,
    alphas: Sequence[float | None],
    wavelength_m: float,
    *,
    exclude: Sequence[bool] | None = None,
) -> DepthSummary:
    """Depth per peak, fused depth and rates of a series.

    Parameters
    ----------
    series : PhaseSeries
        The frames.
    alphas : sequence of (float or None)
        Each peak's prefactor, signed as the peak was demodulated (a negative alpha: the
        peak's phase falls with the height; its phases are stored negated). None: no
        height for that peak.
    wavelength_m : float
        Laser wavelength, m.
    exclude : sequence of bool, optional
        Peaks left out of the fused depth besides those aliasing in time.
    """
    n, m = series.values.shape
    signs = np.array([-1.0 if (a is not None and a < 0) else 1.0 for a in alphas])
    phases = series.unwrapped() * signs + 0.0  # no negative zeros in files
    values = np.where(signs < 0, np.conj(series.values), series.values)
    magnitudes = [abs(a) if a is not None else None for a in alphas]
    heights = np.full((n, m), np.nan)
    for j, a in enumerate(magnitudes):
        if a is not None:
            heights[:, j] = phases[:, j] * wavelength_m / (4 * np.pi * a)
    known = [j for j, a in enumerate(magnitudes) if a is not None]
    skip = list(exclude) if exclude is not None else [False] * m
    fits: list[RateFit | None] = [None] * m
    noise: list[float | None] = [None] * m
    used = [False] * m
    aliased = [False] * m
    fused = spread = None
    fit = None
    note = None
    if n >= 3 and known:
        try:
            track = track_depth(
                values[:, known],
                series.times,
                [magnitudes[j] for j in known],
                wavelength_m,
                exclude=[skip[j] for j in known],
            )
        except InputError as exc:
            note = f"no fused depth: {exc}"
        else:
            fused, spread, fit = track.fused.depth, track.fused.spread, track.fit
            for k, j in enumerate(known):
                fits[j] = track.peak_fits[k]
                value = float(track.fused.noise[k])
                noise[j] = value if math.isfinite(value) else None
                used[j] = bool(track.fused.used[k])
                aliased[j] = bool(track.aliasing.aliased[k])
    elif known and any(not skip[j] for j in known):
        chosen = [j for j in known if not skip[j]]
        finite = np.isfinite(heights[:, chosen])
        total = np.where(finite, heights[:, chosen], 0.0).sum(axis=1)
        count = finite.sum(axis=1)
        fused = np.where(count > 0, total / np.maximum(count, 1), np.nan)
        used = [j in chosen for j in range(m)]
    return DepthSummary(
        times=series.times.copy(),
        phases=phases,
        heights=heights,
        fused=fused,
        fused_spread=spread,
        fit=fit,
        peak_fits=tuple(fits),
        noise_m=tuple(noise),
        used=tuple(used),
        aliased=tuple(aliased),
        note=note,
    )


def pca_check(
    phases: np.ndarray, labels: Sequence[str], alphas: Sequence[float | None]
) -> dict[str, object] | None:
    """Temporal PCA of peaks with known prefactors, against the brightest with one.

    Parameters
    ----------
    phases : ndarray, shape (N, M)
        Unwrapped mean phases, rad (:attr:`DepthSummary.phases`).
    labels : sequence of str
        The peaks' labels, brightest first.
    alphas : sequence of (float or None)
        Their prefactors (the first known one fixes the PCA's scale).

    Returns
    -------
    dict or None
        ``confidence`` (the principal component's share), ``reference`` (label),
        ``prefactors`` and ``explained`` per label, ``n_samples``; None with fewer than
        two peaks or three frames, no known prefactor, or no motion to analyse.
    """
    known = [j for j, a in enumerate(alphas) if a is not None]
    if len(labels) < 2 or phases.shape[0] < 3 or not known:
        return None
    try:
        pca = phase_pca(phases)
        reference = known[0]
        prefactors = pca.prefactors(reference, abs(float(alphas[reference])))  # type: ignore[arg-type]
    except InputError as exc:
        logger.debug("no PCA: %s", exc)
        return None
    return {
        "confidence": pca.confidence,
        "reference": labels[reference],
        "prefactors": dict(zip(labels, map(float, prefactors), strict=True)),
        "explained": dict(zip(labels, map(float, pca.explained), strict=True)),
        "n_samples": pca.n_samples,
    }
