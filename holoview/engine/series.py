"""The mean-phase series of a run: every frame's carrier values, and their joint estimate.

Every frame gives one complex value per peak: the spectrum at the peak's exact carrier,
whose phase is the peak's spatially averaged phase (paper section 4.2), measured by the
carrier probe (:class:`holoview.engine.frame_core.CarrierCore`) without a full FFT, so
that the series can take every frame of the camera while the maps take what time is
left. :class:`PhaseSeries` keeps them with each value's phase noise and the frame's
flags, for every frame it is given (the whole run headless; the last
:data:`LIVE_LENGTH` frames live), and marks a peak whose mean phase steps past
:data:`~holoview.processing.maps.mean_phases.PHASE_STEP_LIMIT` between two frames. With
:meth:`PhaseSeries.track_joint` it also estimates every frame jointly over its peaks
(:mod:`holoview.processing.series.joint_estimation`): one height and one reference-arm phase,
each peak's 2 pi ambiguity resolved by all of them together, so a peak that aliases in
time is unwrapped by the others instead of dropped. :mod:`holoview.engine.depth` turns
a series into depths, the fused depth and the rates; the live trends view and
``holoview process`` both call these, so they agree on the same frames.

Times are in s from the series' first frame, phases in rad, depths in m.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from holoview.errors import InputError
from holoview.processing.maps.mean_phases import PHASE_STEP_LIMIT
from holoview.processing.naming.lattice_geometry import point_of
from holoview.processing.series.carrier_probe import CarrierValues
from holoview.processing.series.joint_estimation import JointEstimator
from holoview.processing.series.phase_series import unwrap_in_time

logger = logging.getLogger(__name__)

__all__ = [
    "LIVE_LENGTH",
    "SERIES_FRAME_FLAGS",
    "JointSetup",
    "PhaseSeries",
    "coupling_of",
    "frame_time",
]

#: Frame flags a series counts (the carrier probe's).
SERIES_FRAME_FLAGS = ("nonfinite", "saturated", "damaged")
#: Frames a live series keeps (10 minutes at 60 frames/s).
LIVE_LENGTH = 36000

_ARRAYS = (
    "_t",
    "_frames",
    "_intervals",
    "_values",
    "_noise",
    "_steps",
    "_jphase",
    "_jfused",
    "_jmargin",
)


def coupling_of(label: str | None, n1: float | None, n2: float | None) -> int | None:
    """How many times the reference-arm phase enters a peak: its lattice ``rf`` coordinate.

    RF +1, every RB_j -1, every FB_j 0, 2RB1 -2 (docs/design.md, "The lattice"); None for a
    label the lattice does not place (a custom name, a ghost) or unknown indices.
    """
    if label is None or n1 is None or n2 is None:
        return None
    try:
        return int(point_of(label, n1, n2)[1])
    except InputError:
        return None


def frame_time(t_device: float, t_host: float) -> float:
    """A frame's time, s: the camera's clock where it has one, else the host's arrival time."""
    return t_device if math.isfinite(t_device) else t_host


@dataclass(frozen=True)
class JointSetup:
    """The joint estimate's arguments (:meth:`PhaseSeries.track_joint`), and the peaks fused.

    Built once, by :meth:`of`, for the live trends, ``holoview process`` and its analysis,
    and the maps step (:mod:`holoview.engine.map_step`), which fuses the same peaks'
    maps as the depth.

    Attributes
    ----------
    alphas : tuple of (float or None)
        Each peak's prefactor, signed as the peak was measured.
    couplings : tuple of (int or None)
        Each peak's coupling to the reference-arm phase (:func:`coupling_of`).
    wavelength_m : float or None
        Laser wavelength, m (None: no joint estimate, no heights).
    exclude : tuple of bool
        Peaks left out of the joint estimate and of the fusion.
    """

    alphas: tuple[float | None, ...]
    couplings: tuple[int | None, ...]
    wavelength_m: float | None
    exclude: tuple[bool, ...]

    @classmethod
    def of(
        cls,
        labels: Sequence[str | None],
        alphas: Sequence[float | None],
        *,
        wavelength_m: float | None,
        n1: float | None,
        n2: float | None,
        exclude: Sequence[bool] | None = None,
    ) -> JointSetup:
        """The setup of peaks ``labels`` with prefactors ``alphas`` (None: unknown).

        A peak without alpha is always excluded; ``exclude`` leaves others out too.
        """
        skip = [False] * len(labels) if exclude is None else list(exclude)
        return cls(
            alphas=tuple(alphas),
            couplings=tuple(coupling_of(label, n1, n2) for label in labels),
            wavelength_m=wavelength_m,
            exclude=tuple(bool(e) or a is None for e, a in zip(skip, alphas, strict=True)),
        )

    @property
    def columns(self) -> tuple[int, ...]:
        """The peaks of the joint estimate: an alpha, a coupling, not excluded."""
        if self.wavelength_m is None:
            return ()
        return tuple(
            j
            for j, (c, e) in enumerate(zip(self.couplings, self.exclude, strict=True))
            if c is not None and not e
        )

    def fused(self) -> tuple[bool, ...]:
        """Per peak, whether its maps go into the fused map.

        The joint estimate's peaks, whose depth is the fused depth; with none, every
        peak with an alpha that is not excluded. Known before the frames, so that
        every frame's maps are fused as they are made.
        """
        columns = self.columns
        if columns:
            return tuple(j in columns for j in range(len(self.alphas)))
        return tuple(not e for e in self.exclude)

    def track(self, series: PhaseSeries) -> None:
        """Estimate ``series`` jointly with this setup (nothing without a wavelength)."""
        if self.wavelength_m is not None:
            series.track_joint(
                list(self.alphas), list(self.couplings), self.wavelength_m, list(self.exclude)
            )


def _joint_key(
    alphas: Sequence[float | None],
    couplings: Sequence[int | None],
    wavelength_m: float,
    exclude: Sequence[bool],
) -> tuple[object, ...]:
    return (tuple(alphas), tuple(couplings), float(wavelength_m), tuple(bool(e) for e in exclude))


class PhaseSeries:
    """Per-frame carrier values, their phase noise and the frames' flags, for fixed peaks.

    Parameters
    ----------
    labels : sequence of str
        The peaks, in the probe's order.
    capacity : int
        Frames to allocate at first (the arrays grow by doubling).
    max_length : int, optional
        Keep only about the newest ``max_length`` frames (live; the oldest tenth goes
        when it is full); unbounded by default.

    Attributes
    ----------
    frame_flags : dict of str to int
        Frames flagged ``nonfinite`` or ``damaged`` (values NaN) and ``saturated`` so far.
    step_counts : ndarray of int
        Per peak, frames whose mean phase stepped past the limit so far.
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
        self._intervals = np.ones(n, dtype=np.int64)
        self._values = np.zeros((n, m), dtype=np.complex128)
        self._noise = np.zeros((n, m))
        self._steps = np.zeros((n, m), dtype=bool)
        self._jphase = np.full((n, m), np.nan)
        self._jfused = np.full((n, 2), np.nan)  # height (m), reference-arm phase (rad)
        self._jmargin = np.full((n, 2), np.inf)  # height margin, flagged (1.0) or not
        self._n = 0
        self._t0: float | None = None
        self._last = np.full(m, np.nan + 0j)
        self._joint: JointEstimator | None = None
        self._joint_key: tuple[object, ...] | None = None
        self._joint_columns: np.ndarray = np.zeros(0, dtype=np.int64)
        self._joint_signs: np.ndarray = np.ones(0)
        self._joint_couplings: np.ndarray = np.zeros(0)
        self.frame_flags = dict.fromkeys(SERIES_FRAME_FLAGS, 0)
        self.step_counts = np.zeros(m, dtype=np.int64)

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
        """A series holding given per-frame arrays (times in s from 0; no flags counted).

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
        series.step_counts = np.count_nonzero(series._steps[:n], axis=0)
        if n:
            series._last = series._values[n - 1].copy()
        return series

    def __len__(self) -> int:
        return self._n

    def _make_room(self) -> None:
        size = self._t.shape[0]
        if self._n < size:
            return
        if self.max_length is not None and size >= self.max_length:
            keep = self.max_length - max(1, self.max_length // 10)
            self._joint_key = None  # a new estimate over the frames kept would differ
            for name in _ARRAYS:
                array = getattr(self, name)
                array[:keep] = array[self._n - keep : self._n]
            self._n = keep
            return
        grow = size if self.max_length is None else min(size, self.max_length - size)
        for name in _ARRAYS:
            array = getattr(self, name)
            fill = np.nan if array.dtype.kind in "fc" else 0  # no value yet: NaN where it can be
            setattr(self, name, np.concatenate([array, np.full_like(array[:grow], fill)]))

    def add(self, t_s: float, frame: int, measured: CarrierValues, *, intervals: int = 1) -> None:
        """Add one frame: its time (s, any origin), input index and carrier values, and
        the frame intervals since the frame before (more than one after lost frames).

        A frame flagged ``nonfinite`` has NaN values; the step of a peak is measured
        against its last finite value.
        """
        values = np.asarray(measured.values, dtype=np.complex128)
        if values.shape != (len(self.labels),):
            raise InputError(
                f"a frame of {values.size} carrier values added to a series of "
                f"{len(self.labels)} peaks"
            )
        self._make_room()
        if self._t0 is None:
            self._t0 = t_s
        i = self._n
        self._t[i] = t_s - self._t0
        self._frames[i] = frame
        self._intervals[i] = max(1, intervals)
        self._values[i] = values
        self._noise[i] = measured.noise
        for flag in measured.flags:
            if flag in self.frame_flags:
                self.frame_flags[flag] += 1
        with np.errstate(invalid="ignore"):
            stepped = np.abs(np.angle(values * np.conj(self._last))) > PHASE_STEP_LIMIT
        self._steps[i] = stepped
        self.step_counts += stepped
        finite = np.isfinite(values)
        self._last[finite] = values[finite]
        self._n += 1
        if self._joint is not None:
            self._joint_update(i)

    def track_joint(
        self,
        alphas: Sequence[float | None],
        couplings: Sequence[int | None],
        wavelength_m: float,
        exclude: Sequence[bool] | None = None,
    ) -> None:
        """Estimate the frames jointly (:mod:`holoview.processing.series.joint_estimation`).

        The peaks with an alpha and a coupling (and not in ``exclude``) give, frame by
        frame, one height and one reference-arm phase, each peak's 2 pi ambiguity
        resolved by all of them together: the frames so far now, the later ones as
        they are added. Each value's phase noise is the probe's where it has one.

        Parameters
        ----------
        alphas : sequence of (float or None)
            Each peak's prefactor, signed as the peak was measured (negative: the peak
            was measured on the twin whose phase falls with the height).
        couplings : sequence of (int or None)
            Each peak's coupling to the reference-arm phase (:func:`coupling_of`).
        wavelength_m : float
            Laser wavelength, m.
        exclude : sequence of bool, optional
            Peaks left out of the joint estimate.

        Nothing is done when every frame held was estimated, from the first, with the
        same arguments (a run that knew its prefactors before its frames came).
        """
        skip = list(exclude) if exclude is not None else [False] * len(self.labels)
        key = _joint_key(alphas, couplings, wavelength_m, skip)
        if key == self._joint_key:
            return
        self._joint_key = key
        known = [
            (j, a, c)
            for j, (a, c) in enumerate(zip(alphas, couplings, strict=True))
            if a is not None and c is not None and not skip[j]
        ]
        self._joint = None
        self._jphase[:] = np.nan
        self._jfused[:] = np.nan
        self._jmargin[:] = np.inf
        if not known:
            return
        self._joint_columns = np.array([j for j, _, _ in known], dtype=np.int64)
        self._joint_signs = np.array([math.copysign(1.0, a) for _, a, _ in known])
        self._joint_couplings = np.array([c for _, _, c in known], dtype=np.float64)
        self._joint = JointEstimator(
            [abs(a) for _, a, _ in known], [c for _, _, c in known], wavelength_m
        )
        for i in range(self._n):
            self._joint_update(i)

    def _joint_update(self, i: int) -> None:
        assert self._joint is not None
        cols = self._joint_columns
        values = self._values[i, cols]
        values = np.where(self._joint_signs < 0, np.conj(values), values)
        sigma = self._noise[i, cols]
        usable = bool(np.all(np.isfinite(sigma) & (sigma > 0)))
        frame = self._joint.update(
            values, sigma if usable else None, intervals=int(self._intervals[i])
        )
        self._jphase[i, cols] = frame.phases
        self._jfused[i] = (frame.height, frame.vibration)
        self._jmargin[i] = (frame.margin, 1.0 if frame.flagged else 0.0)

    def truncate(self, n: int) -> None:
        """Keep the first ``n`` frames only (an interrupted run)."""
        self._n = min(self._n, max(0, n))

    @property
    def times(self) -> np.ndarray:
        """Frame times, s, from 0 at the first frame added (a view)."""
        return self._t[: self._n]

    @property
    def intervals(self) -> np.ndarray:
        """Per frame, the frame intervals since the one before (a view)."""
        return self._intervals[: self._n]

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
        """Phase noise of each carrier value, rad (a view; NaN where not estimated)."""
        return self._noise[: self._n]

    @property
    def phase_steps(self) -> np.ndarray:
        """Whether each peak's mean phase stepped past the limit at each frame (a view)."""
        return self._steps[: self._n]

    @property
    def joint_columns(self) -> tuple[int, ...]:
        """The peaks in the joint estimate (:meth:`track_joint`); empty without one."""
        return tuple(int(j) for j in self._joint_columns) if self._joint is not None else ()

    def joint(self) -> tuple[np.ndarray, ...] | None:
        """The joint estimate's per-frame arrays, or None without one.

        Returns
        -------
        tuple of ndarray
            ``phases`` (N, M), each joint peak's phase on its stored twin, rad, NaN for
            the others; ``height`` (N,), m, and ``vibration`` (N,), the reference-arm
            phase, rad, both since the series' first frame; ``margin`` (N,), noise
            standard deviations; ``flagged`` (N,) bool: the ambiguity not resolved.
        """
        if self._joint is None:
            return None
        n = self._n
        return (
            self._jphase[:n],
            self._jfused[:n, 0],
            self._jfused[:n, 1],
            self._jmargin[:n, 0],
            self._jmargin[:n, 1] > 0,
        )

    @property
    def joint_couplings(self) -> np.ndarray:
        """The joint peaks' couplings to the reference-arm phase (empty without one)."""
        return self._joint_couplings if self._joint is not None else np.zeros(0)

    def unwrapped(self) -> np.ndarray:
        """Mean phase per frame and peak, rad, unwrapped in time from the first frame.

        NaN where a frame was not demodulated.
        """
        if len(self) < 2:
            return np.where(np.isfinite(self.values), 0.0, np.nan).real
        phases = unwrap_in_time(self.values)
        return np.where(np.isfinite(self.values), phases, np.nan)
