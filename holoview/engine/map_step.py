"""One frame's maps: the step the live maps worker, ``holoview process`` and its workers share.

Per frame, in this order, and nowhere else:

1. the demodulated maps of the frame's peaks (:class:`~holoview.engine.frame_core.FrameCore`,
   its mean phases following the carrier probe's values), each trusted where its
   amplitude is (:func:`trusted_maps`: delta-h in m where the peak has alpha, else phase
   in rad, NaN elsewhere);
2. the phase-step rule: a peak whose mean phase moved more than
   :data:`~holoview.processing.maps.mean_phases.PHASE_STEP_LIMIT` since the frame
   demodulated before it is flagged ``phase_step``. That is the step that places the
   map's 2 pi offset (against the previous map in relative mode, the unwrapping in time
   otherwise), so it is the one that says the offset may be a turn off; the live maps
   take the newest frame, and a step between two frames the maps never saw says
   nothing of them. A run that demodulates every frame steps against the previous
   frame: the series' rule there, by construction;
3. co-registration: the maps' displacements against the first peak's
   (:class:`Coregistration`: measured as the frames come live, fixed before the frames
   headless);
4. fusion (:func:`fuse_maps`): the peaks of the fused depth
   (:meth:`~holoview.engine.series.JointSetup.fused`), moved onto the first peak's grid
   (Keys' cubic convolution, :data:`FUSION_METHOD`), weighted by their expected errors
   (:attr:`~holoview.processing.maps.demod_results.PeakResult.error_height`: the noise
   and what the window cuts), a peak that stepped at that frame left out;
5. the measured shifts in camera pixels (:func:`frame_shift`), for the view and the files.

The maps may be on the frame's pixel grid instead of the demodulation box's (the
demodulator's ``grid="frame"``: ``process --maps-grid frame``); every step above is
then on that grid, the displacements measured on box maps and given in frame pixels
(:func:`regridded`): the estimator's significance rules are made for the box's
pixels, whose noise is nearly independent from pixel to pixel.

:class:`MapStep` runs them and returns a :class:`FrameMaps`; a caller decides only
which frames it gives and whether a frame adds to the displacement estimate.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from holoview.engine.frame_core import FrameCore
from holoview.engine.series import JointSetup
from holoview.processing.maps.coregister import (
    MIN_MAP_SIDE,
    Displacement,
    DisplacementEstimator,
    fuse_coregistered,
)
from holoview.processing.maps.demod_results import DemodResult

logger = logging.getLogger(__name__)

__all__ = [
    "FUSION_METHOD",
    "Coregistration",
    "FrameMaps",
    "MapStep",
    "frame_shift",
    "fuse_maps",
    "pixel_step",
    "regridded",
    "trusted_maps",
]

#: How maps are moved onto the first peak's grid before fusion
#: (:func:`~holoview.processing.maps.map_moves.coregister`). Keys' cubic convolution:
#: about a quarter of the cubic B-spline's time on a frame's maps (its prefilter needs
#: every untrusted pixel filled first), an untrusted pixel spoiling the 4 x 4 pixels
#: that read it, as the spline's; 0.2 % rms interpolation error on waves 7 pixels long
#: against 0.04 %. The displacements themselves are measured with the spline.
FUSION_METHOD = "cubic"


def trusted_maps(result: DemodResult) -> list[np.ndarray]:
    """Each peak's map of one frame, float32, NaN where untrusted.

    Delta-h in m where the peak has alpha (and the demodulator a wavelength), else the
    phase in rad.
    """
    return [
        np.where(
            r.mask, r.delta_h if r.delta_h is not None else r.phase, np.float32(np.nan)
        ).astype(np.float32, copy=False)
        for r in result.peaks
    ]


def pixel_step(frame_shape: tuple[int, int], box_shape: tuple[int, int]) -> tuple[float, float]:
    """Frame pixels per map pixel, ``(rows, cols)``: map pixel ``(p, q)`` is at ``(p, q)`` times it.

    Examples
    --------
    >>> pixel_step((1024, 1024), (180, 180))
    (5.688888888888889, 5.688888888888889)
    """
    return frame_shape[0] / box_shape[0], frame_shape[1] / box_shape[1]


def frame_shift(
    displacement: Displacement, frame_shape: tuple[int, int], box_shape: tuple[int, int]
) -> tuple[float, float]:
    """A displacement's shift ``(dy, dx)`` in camera (frame) pixels."""
    step = pixel_step(frame_shape, box_shape)
    return displacement.shift[0] * step[0], displacement.shift[1] * step[1]


def regridded(
    displacements: Sequence[Displacement],
    from_shape: tuple[int, int],
    to_shape: tuple[int, int],
) -> list[Displacement]:
    """Displacements measured on maps of ``from_shape``, in pixels of maps of ``to_shape``.

    Both grids cover the frame (:func:`pixel_step`); the shifts and their standard
    errors scale with the pixel sizes.

    Examples
    --------
    >>> d = Displacement((0.5, -1.0), (0.01, 0.02), True, 40)
    >>> regridded([d], (32, 64), (128, 128))[0].shift
    (2.0, -2.0)
    """
    sy, sx = to_shape[0] / from_shape[0], to_shape[1] / from_shape[1]
    return [
        replace(
            d,
            shift=(d.shift[0] * sy, d.shift[1] * sx),
            stderr=(d.stderr[0] * sy, d.stderr[1] * sx),
        )
        for d in displacements
    ]


class Coregistration:
    """The displacements of a frame's maps against the first peak's.

    Measured over the frames :meth:`add_maps` is given (a new estimate whenever the
    peaks or the map shape change), or ``fixed`` for good: a run measures them over
    frames spread over it before it fuses any. Maps smaller than
    :data:`~holoview.processing.maps.coregister.MIN_MAP_SIDE` and single maps are not
    co-registered; reference frames (zero maps) are not added.

    Parameters
    ----------
    fixed : (labels, box_shape, displacements), optional
        Displacements measured elsewhere for those peaks and map shape; nothing is added.
    """

    def __init__(
        self, fixed: tuple[Sequence[str | None], tuple[int, int], Sequence[Displacement]] | None
    ) -> None:
        self._estimator: DisplacementEstimator | None = None
        self._key: tuple[object, ...] | None = None
        self._fixed: list[Displacement] | None = None
        if fixed is not None:
            labels, box_shape, displacements = fixed
            self._key = (tuple(labels), tuple(box_shape))
            self._fixed = list(displacements) or None

    def add_maps(
        self,
        labels: Sequence[str | None],
        box_shape: tuple[int, int],
        maps: Sequence[np.ndarray],
        *,
        reference: bool = False,
    ) -> None:
        """Add one frame's :func:`trusted_maps`, of peaks ``labels``, to the estimate.

        ``reference``: the frame was a reference frame (its maps are zero: not added).
        """
        if self._fixed is not None or len(maps) < 2 or min(box_shape) < MIN_MAP_SIDE:
            return
        key = (tuple(labels), tuple(box_shape))
        if key != self._key or self._estimator is None:
            shape = (int(box_shape[0]), int(box_shape[1]))
            self._estimator = DisplacementEstimator(shape, len(maps))
            self._key = key
        if not reference:
            self._estimator.add(list(maps))

    def displacements(
        self, labels: Sequence[str | None] | None = None, box_shape: tuple[int, int] | None = None
    ) -> list[Displacement] | None:
        """One displacement per map (map pixels), or None before an estimate exists.

        With ``labels`` and ``box_shape``, None also when the estimate is of other peaks
        or another map shape.
        """
        if labels is not None and (tuple(labels), box_shape) != self._key:
            return None
        if self._fixed is not None:
            return list(self._fixed)
        if self._estimator is None:
            return None
        return self._estimator.displacements()


def fuse_maps(
    maps: Sequence[np.ndarray | None],
    noise_m: Sequence[float | None],
    stepped: Sequence[bool],
    displacements: Sequence[Displacement] | None = None,
) -> np.ndarray | None:
    """Return the fused delta-h map of one frame (m), co-registered; None with fewer than two.

    Parameters
    ----------
    maps : sequence of (ndarray or None)
        Each peak's delta-h map, m, NaN where untrusted (None: the peak is not fused).
    noise_m : sequence of (float or None)
        Each peak's expected per-pixel height error on that frame, m (its noise and what
        its window cuts: the weight is its inverse square; None or 0 on a reference
        frame: plain means).
    stepped : sequence of bool
        Whether the peak's mean phase stepped at this frame (the phase-step rule, module
        documentation): such peaks are left out, unless every one did.
    displacements : sequence of Displacement, optional
        One per peak (:class:`Coregistration`): the maps are moved onto the first's grid
        with :data:`FUSION_METHOD`.
    """
    present = {j: m for j, m in enumerate(maps) if m is not None}
    chosen = list(present)
    steady = [j for j in chosen if not stepped[j]]
    chosen = steady or chosen
    if len(chosen) < 2:
        return None
    shifts = None if displacements is None else [displacements[j].shift for j in chosen]
    return fuse_coregistered(
        [present[j] for j in chosen],
        [np.nan if noise_m[j] is None else noise_m[j] for j in chosen],
        shifts,
        method=FUSION_METHOD,
    )


@dataclass
class FrameMaps:
    """One frame's maps and what a run counts of them (:meth:`MapStep.process`).

    Attributes
    ----------
    demodulated : bool
        The frame went through the demodulator (False: damaged in transfer).
    maps : list of ndarray
        Each peak's :func:`trusted_maps` (empty for a frame not demodulated or not finite).
    fused : ndarray or None
        The fused delta-h map, m (None: fewer than two peaks to fuse).
    noise : tuple of float
        Each peak's per-pixel phase noise, rad.
    peak_flags : tuple of frozenset of str
        Each peak's flags (``phase_step``: the phase-step rule).
    flags : frozenset of str
        The frame's flags (``no_signal``, ``reference``, ``nonfinite``, ...).
    shifts_px : dict of str to (float, float)
        Each peak's measured displacement against the first peak, camera pixels
        ``(dy, dx)`` (peaks whose displacement is not measured are left out).
    grid_of : str or None
        The peak whose grid the fused map is on (None: not co-registered).
    result : DemodResult or None
        The demodulator's whole result (the live view draws its phases); not kept by a
        run, never sent between processes.
    """

    demodulated: bool
    maps: list[np.ndarray] = field(default_factory=list)
    fused: np.ndarray | None = None
    noise: tuple[float, ...] = ()
    peak_flags: tuple[frozenset[str], ...] = ()
    flags: frozenset[str] = frozenset()
    shifts_px: dict[str, tuple[float, float]] = field(default_factory=dict)
    grid_of: str | None = None
    result: DemodResult | None = field(default=None, repr=False, compare=False)


class MapStep:
    """Frame -> trusted maps -> phase steps -> co-registration -> fusion -> pixel shifts.

    Parameters
    ----------
    core : FrameCore
        The demodulator's keeper (peaks and settings; its experiment's ``n1``, ``n2``
        and wavelength place the peaks on the lattice).
    coregistration : Coregistration, optional
        Where the displacements come from (default: measured over the frames added).
    exclude : sequence of bool, optional
        Peaks kept out of the fused map besides those without alpha (a run's peaks the
        identification could not explain), in the demodulator's order.
    """

    def __init__(
        self,
        core: FrameCore,
        coregistration: Coregistration | None = None,
        exclude: Sequence[bool] | None = None,
    ) -> None:
        self.core = core
        self.coregistration = coregistration or Coregistration(None)
        self._exclude = None if exclude is None else tuple(exclude)
        self._fused_key: tuple[object, ...] | None = None
        self._fused: tuple[bool, ...] = ()

    def fused_peaks(self) -> tuple[bool, ...]:
        """Per demodulated peak, whether its maps go into the fused map (empty before one)."""
        demod = self.core.build()
        if demod is None:
            return ()
        e = self.core.experiment
        key = (demod.peaks, e.n1, e.n2, e.wavelength_m)
        if key != self._fused_key:
            exclude = self._exclude if self._exclude is not None else None
            joint = JointSetup.of(
                [p.label for p in demod.peaks],
                [p.alpha for p in demod.peaks],
                wavelength_m=e.wavelength_m,
                n1=e.n1,
                n2=e.n2,
                exclude=exclude,
            )
            self._fused, self._fused_key = joint.fused(), key
        return self._fused

    def process(
        self,
        frame: np.ndarray,
        values: Sequence[complex] | np.ndarray | None = None,
        *,
        damaged: bool = False,
        estimate: bool = False,
        fuse: bool = True,
        shifts: bool = True,
    ) -> FrameMaps:
        """The maps of ``frame`` (not modified), advancing the demodulator's reference.

        Parameters
        ----------
        frame : ndarray
            The hologram, counts.
        values : sequence of complex, optional
            Its peaks' carrier values (the carrier probe's, counts), when the caller
            measured them already (else the core measures them).
        damaged : bool
            The frame was damaged in transfer: not demodulated, the reference untouched.
        estimate : bool
            Add this frame's maps to the displacement estimate first.
        fuse : bool
            Make the fused map.
        shifts : bool
            Give each map's displacement in camera pixels (``shifts_px``, ``grid_of``);
            without it and without ``fuse``, the displacements are not looked up.

        Returns
        -------
        FrameMaps
            ``demodulated`` False for a damaged frame; no maps for a non-finite one.

        Raises
        ------
        InputError
            Peaks or settings that cannot work (:meth:`FrameCore.build`).
        """
        if damaged:
            return FrameMaps(demodulated=False)
        result = self.core.process(frame, values)
        if result is None:
            return FrameMaps(demodulated=False)
        peaks = result.peaks
        if not peaks:  # a non-finite frame
            return FrameMaps(demodulated=True, flags=result.flags, result=result)
        maps = trusted_maps(result)
        labels = tuple(r.peak.label for r in peaks)
        if estimate:
            self.coregistration.add_maps(
                labels, result.box_shape, maps, reference="reference" in result.flags
            )
        displacements = None
        if fuse or shifts:
            displacements = self.coregistration.displacements(labels, result.box_shape)
        fused = None
        if fuse:
            chosen = self.fused_peaks()
            fused = fuse_maps(
                [
                    m if use and r.delta_h is not None else None
                    for m, r, use in zip(maps, peaks, chosen, strict=True)
                ],
                [r.error_height for r in peaks],
                ["phase_step" in r.flags for r in peaks],
                displacements,
            )
        shifted: dict[str, tuple[float, float]] = {}
        grid_of = None
        if shifts and displacements is not None:
            grid_of = labels[0] or "?"
            for r, d in zip(peaks, displacements, strict=True):
                if d.measured:
                    shifted[r.peak.label or "?"] = frame_shift(
                        d, result.frame_shape, result.box_shape
                    )
        return FrameMaps(
            demodulated=True,
            maps=maps,
            fused=fused,
            noise=tuple(r.noise for r in peaks),
            peak_flags=tuple(r.flags for r in peaks),
            flags=result.flags,
            shifts_px=shifted,
            grid_of=grid_of,
            result=result,
        )
