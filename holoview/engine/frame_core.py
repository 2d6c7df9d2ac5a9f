"""The per-frame core: one frame in, demodulated maps, co-registration and fusion out.

The live worker (:mod:`holoview.live`) and ``holoview process``
(:mod:`holoview.headless`) run every frame through the same pieces, so the two give
the same numbers on the same frames:

- :class:`CarrierCore` measures the peaks' carrier values of every frame (the mean-phase
  series' input) with a :class:`~holoview.processing.series.carrier_probe.CarrierProbe`: a
  separable DFT at the exact carriers, a quarter of a full FFT's time;
- :class:`FrameCore` keeps one :class:`~holoview.processing.maps.demodulate.Demodulator`
  for a set of peaks and an experiment's settings (window, radius, reference,
  unwrapping), rebuilt only when they change: the maps, their mean phases following
  the carrier probe's values (the series' own), so that a process holding a run's
  values can tell a worker where the maps' 2 pi offsets stand; its windows are
  matched to the spectrum it was given (:meth:`FrameCore.match`), or at the bound, or
  given;
- :func:`matching_positions`: the frames of a run its windows are matched to, and
  :func:`mean_positions`, those whose change is averaged to judge waves against the
  noise of many frames.

What follows from the maps (trusted maps, phase steps, co-registration, fusion) is
:mod:`holoview.engine.map_step`; the mean-phase series, depths and rates are
:mod:`holoview.engine.series`.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from holoview.engine.experiment import Experiment
from holoview.processing.fourier.frames import DamagedFrameError, frame_damage
from holoview.processing.fourier.windows import DEFAULT_TAPER
from holoview.processing.maps.demod_results import DemodResult
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.matched import Window
from holoview.processing.peaks.radii import (
    UNMEASURED_REASON,
    distinct_neighbours,
    peak_radii,
    peak_windows,
)
from holoview.processing.peaks.surface_spectrum import MEAN_FRAMES, SurfaceSpectrum
from holoview.processing.series.carrier_probe import CarrierProbe, CarrierValues

logger = logging.getLogger(__name__)

__all__ = [
    "FFT_THREADS",
    "MATCHING_FRAMES",
    "CarrierCore",
    "FrameCore",
    "matching_positions",
    "mean_positions",
    "series_key",
]

#: FFTW threads per frame. One: on a two-core machine the other core reads frames (or
#: runs the GUI), and a two-thread FFT whose second thread waits for a busy core took
#: 450 ms instead of 10 ms per 1024 x 1024 frame.
FFT_THREADS = 1


Carrier = tuple[float, float]

#: Frames of a run after its first that its windows are matched to (absolute maps).
MATCHING_FRAMES = 3


def matching_positions(reference: str, n: int) -> list[int]:
    """Positions in a run of ``n`` frames whose maps its windows are matched to.

    Against the run's first frame (position 0): synthetic phases, none (the first frame
    alone); relative maps, the second frame; absolute maps, :data:`MATCHING_FRAMES`
    frames spread over the run (a third, two thirds, the last), the changes of the
    surface from the reference that its maps show.
    """
    if reference == "synthetic" or n < 2:
        return []
    if reference == "relative":
        return [1]
    positions = {max(1, n * k // MATCHING_FRAMES) for k in range(1, MATCHING_FRAMES)}
    return sorted(positions | {n - 1})


def mean_positions(reference: str, n: int) -> list[int]:
    """Positions in a run of ``n`` frames whose change is averaged (the waves' test).

    Up to :data:`~holoview.processing.peaks.surface_spectrum.MEAN_FRAMES` frames after
    the first, evenly spread over the run (each against the first frame; relative
    maps, against the frame before it); none for synthetic phases or under three
    frames (no variance over frames to measure).
    """
    if reference == "synthetic" or n < 3:
        return []
    count = min(MEAN_FRAMES, n - 1)
    return sorted({int(p) for p in np.linspace(1, n - 1, count).round()})


def series_key(peaks: Sequence[Peak]) -> tuple[object, ...]:
    """What identifies a series: each peak's label, alpha and carrier (a new key, a new series)."""
    return tuple((p.label, p.alpha, p.carrier) for p in peaks)


class CarrierCore:
    """Measure the carrier values of frame after frame for a set of peaks.

    Parameters
    ----------
    frame_shape : tuple of int
        ``(rows, cols)`` of the frames, pixels.
    saturation : float, optional
        Raw value at which the camera saturates (counts): such frames are flagged.

    Notes
    -----
    The probe is rebuilt when :func:`series_key` of the peaks changes: give it the
    demodulator's peaks, which change only when the demodulator is rebuilt, so a
    carrier that drifts by less than a bin keeps its series going.
    """

    def __init__(self, frame_shape: tuple[int, int], saturation: float | None = None) -> None:
        self.frame_shape = (int(frame_shape[0]), int(frame_shape[1]))
        self.saturation = saturation
        self.peaks: tuple[Peak, ...] = ()
        self._probe: CarrierProbe | None = None

    @property
    def key(self) -> tuple[object, ...]:
        """:func:`series_key` of the peaks measured."""
        return series_key(self.peaks)

    def configure(self, peaks: Sequence[Peak]) -> bool:
        """Measure ``peaks`` from the next frame; return whether they changed.

        Raises
        ------
        InputError
            A carrier the probe cannot measure (outside the spectrum, at zero frequency).
        """
        peaks = tuple(peaks)
        if series_key(peaks) == self.key and (self._probe is not None or not peaks):
            return False
        self._probe = None
        self.peaks = peaks
        if peaks:
            self._probe = CarrierProbe(self.frame_shape, peaks, saturation=self.saturation)
        return True

    def measure(self, frame: np.ndarray) -> CarrierValues | None:
        """The carrier values of ``frame`` (not modified); None when there is no peak.

        A frame damaged in transfer (rows lost,
        :func:`~holoview.processing.fourier.frames.frame_damage`)
        gives NaN values and the flag ``"damaged"``: its values would be wrong, not noisy.
        """
        if self._probe is None:
            return None
        if frame_damage(np.asarray(frame)) is not None:
            nan = np.full(len(self.peaks), np.nan)
            return CarrierValues(nan + 0j, nan, math.nan, frozenset({"damaged"}))
        return self._probe.measure(frame)


def _carriers(peaks: Sequence[Peak]) -> tuple[tuple[float, float], ...]:
    return tuple((float(p.carrier[0]), float(p.carrier[1])) for p in peaks)


class FrameCore:
    """Demodulate frames at a set of peaks with an experiment's settings.

    Parameters
    ----------
    frame_shape : tuple of int
        ``(rows, cols)`` of the frames, pixels.
    experiment : Experiment
        Window, radius, reference, unwrapping and wavelength.
    peaks : sequence of Peak
        The peaks to demodulate, labelled, with alpha where known.
    saturation : float, optional
        Raw value at which the camera saturates (counts).
    threads : int
        FFTW threads per frame.
    background : ndarray, optional
        An object-free hologram (counts, ``frame_shape``): with an absolute reference
        the maps are taken against it rather than against the first frame
        (:meth:`~holoview.processing.maps.demodulate.Demodulator.set_background`).
    neighbours : sequence of (fx, fy)
        The detected peaks that bound windows, cycles/pixel
        (:func:`~holoview.processing.peaks.radii.window_neighbours`): the automatic
        windows reach none (the demodulated ones among them are recognised and dropped).
    spectrum : SurfaceSpectrum, optional
        The spectrum the windows are matched to (:meth:`match`).
    windows : sequence of Window, optional
        The windows of the peaks, decided elsewhere (a run's, in its workers): used as
        they are while the peaks' carriers are these.
    grid : {"box", "frame"}
        Where the maps are: the demodulation box's grid or the frame's pixels
        (:class:`~holoview.processing.maps.demodulate.Demodulator`).

    Notes
    -----
    The demodulator is rebuilt (which restarts the absolute and relative reference)
    when a label or alpha appears, goes or changes, a carrier moves by a whole FFT bin,
    a neighbour moves a window's bound by a whole bin, the windows are matched to
    another spectrum, or the window, radius, reference, unwrapping or wavelength change.
    A rebuild for any reason but the peaks keeps the carriers in use: the peaks (and the
    series measured at them) change only with a label, an alpha or a whole bin.
    """

    def __init__(
        self,
        frame_shape: tuple[int, int],
        experiment: Experiment,
        peaks: Sequence[Peak] = (),
        *,
        saturation: float | None = None,
        threads: int = FFT_THREADS,
        background: np.ndarray | None = None,
        neighbours: Sequence[tuple[float, float]] = (),
        spectrum: SurfaceSpectrum | None = None,
        windows: Sequence[Window] | None = None,
        grid: str = "box",
    ) -> None:
        self.frame_shape = (int(frame_shape[0]), int(frame_shape[1]))
        self.grid = grid
        self.saturation = saturation
        self.threads = threads
        self.background = background
        self.experiment = experiment
        self.peaks: tuple[Peak, ...] = tuple(peaks)
        self.neighbours = tuple(neighbours)
        #: the spectrum the windows are matched to (None: not measured)
        self.spectrum = spectrum
        self._fixed = None if windows is None else (_carriers(self.peaks), tuple(windows))
        self._chosen: dict[str, Window] | None = None
        self._bounds_checked: tuple[Demodulator, tuple[Carrier, ...], bool] | None = None
        self._demod: Demodulator | None = None
        self._probe = CarrierCore(self.frame_shape, saturation)

    def configure(
        self,
        experiment: Experiment,
        peaks: Sequence[Peak],
        neighbours: Sequence[tuple[float, float]] | None = None,
    ) -> None:
        """Use ``experiment``, ``peaks`` (and detected ``neighbours``) from the next frame.

        The demodulator is rebuilt only if needed (class notes).
        """
        self.experiment = experiment
        self.peaks = tuple(peaks)
        if neighbours is not None:
            self.neighbours = tuple(neighbours)

    def match(
        self, spectrum: SurfaceSpectrum | None, windows: Mapping[str, Window] | None = None
    ) -> None:
        """Match the windows to ``spectrum`` from the next frame (the maps restart).

        ``windows``: the windows ``spectrum`` gives, by peak label, measured elsewhere
        (the live match thread: :mod:`holoview.engine.window_matching`). The
        demodulator is then built with them (each within its peak's bound as it is
        then) and measures nothing, also when later rebuilt for moved carriers; without
        them it matches its windows to ``spectrum`` itself (seconds on a large frame).
        """
        self.spectrum = spectrum
        self._chosen = None if windows is None or spectrum is None else dict(windows)

    @property
    def demodulator(self) -> Demodulator | None:
        """The demodulator for the current peaks (None before a frame or with no peak)."""
        return self._demod

    @property
    def radius(self) -> float | None:
        """The window radius in use, cycles/pixel (the experiment's before the first frame)."""
        return self.experiment.fixed_radius if self._demod is None else self._demod.radius

    def radii(self) -> dict[str, float]:
        """Each labelled peak's window radius in use, cycles/pixel (empty before a frame)."""
        return {label: w.radius for label, w in self.windows().items()}

    def windows(self) -> dict[str, Window]:
        """Each labelled peak's window in use (empty before a frame)."""
        demod = self._demod
        if demod is None:
            return {}
        return {p.label: w for p, w in zip(demod.peaks, demod.windows, strict=True) if p.label}

    @property
    def notes(self) -> tuple[str, ...]:
        """What the user should know about the windows in use (a given radius reaching a peak)."""
        return () if self._demod is None else self._demod.notes

    def _settings(self) -> tuple[object, ...]:
        e = self.experiment
        return (e.window, e.radius, e.reference, e.unwrap, e.wavelength_m)

    def _same_peaks(self, demod: Demodulator) -> bool:
        """Whether the peaks are ``demod``'s: the same labels and alphas, no carrier moved
        by a whole bin."""
        if [(p.label, p.alpha) for p in self.peaks] != [(p.label, p.alpha) for p in demod.peaks]:
            return False
        rows, cols = self.frame_shape
        return not any(
            abs(p.carrier[0] - q.carrier[0]) * cols > 1.0
            or abs(p.carrier[1] - q.carrier[1]) * rows > 1.0
            for p, q in zip(self.peaks, demod.peaks, strict=True)
        )

    def _stale(self) -> bool:
        demod = self._demod
        if demod is None or self._settings_key != self._settings():
            return True
        if not self._same_peaks(demod):
            return True
        if self._fixed_windows() is not None:
            return False
        if demod.spectrum is not self.spectrum:
            return True
        return self._bounds_moved(demod)

    def _bounds_moved(self, demod: Demodulator) -> bool:
        """Whether the neighbours moved a window's bound by a whole bin (kept per
        demodulator and neighbours: 1-2 ms of every live frame's maps, twice)."""
        if self._bounds_checked is not None:
            checked, neighbours, moved = self._bounds_checked
            if checked is demod and neighbours == self.neighbours:
                return moved
        carriers = np.array([p.carrier for p in demod.peaks], dtype=np.float64)
        others = distinct_neighbours(self.frame_shape, carriers, self.neighbours)
        bounds = peak_radii(self.frame_shape, carriers, None, others)
        moved = any(
            abs(a - w.bound) * min(self.frame_shape) > 1.0
            for a, w in zip(bounds, demod.windows, strict=True)
        )
        self._bounds_checked = (demod, self.neighbours, moved)
        return moved

    def _fixed_windows(self) -> tuple[Window, ...] | None:
        """The windows given at construction, while the carriers are the ones they were for
        (the peaks may be named since: a run's identification gives labels and alphas)."""
        if self._fixed is None or self._fixed[0] != _carriers(self.peaks):
            return None
        return self._fixed[1]

    def _chosen_windows(self) -> tuple[Window, ...] | None:
        """The windows matched elsewhere (:meth:`match`), each within its bound as it is now.

        A peak the match did not see (a new label) gets its bound, as a window with no
        spectrum does; a window at the bound follows it.
        """
        if self._chosen is None or self.experiment.radius_rule != "matched":
            return None
        carriers = np.array([p.carrier for p in self.peaks], dtype=np.float64)
        others = distinct_neighbours(self.frame_shape, carriers, self.neighbours)
        bounds = peak_windows(
            self.frame_shape,
            carriers,
            "bound",
            others,
            kind=self.experiment.window,
            taper=DEFAULT_TAPER,
        )
        out = []
        for i, (peak, bound) in enumerate(zip(self.peaks, bounds, strict=True)):
            chosen = self._chosen.get(peak.label or f"#{i}")
            if chosen is None:
                out.append(replace(bound, reason=UNMEASURED_REASON))
            else:
                radius = min(chosen.radius, bound.radius)
                if chosen.rule == "bound":
                    radius = bound.radius
                out.append(replace(chosen, radius=radius, bound=bound.radius, kind=bound.kind))
        return tuple(out)

    def build(self) -> Demodulator | None:
        """Return the demodulator for the current settings, rebuilding it when stale.

        Raises
        ------
        InputError
            A radius or set of peaks that cannot work (a window holding another carrier).
        """
        if not self.peaks:
            self._demod = None
            return None
        if self._stale():
            if self._demod is not None and self._same_peaks(self._demod):
                # rebuilt for the windows only: the carriers stay the ones in use (a
                # detection's sub-bin refinement differs from the last), so the series
                # measured at them goes on (:class:`CarrierCore`'s key)
                self.peaks = self._demod.peaks
            self._demod = None
            e = self.experiment
            demod = Demodulator(
                self.frame_shape,
                self.peaks,
                window=e.window,
                radius=e.radius,
                reference=e.reference,
                unwrap=e.unwrap,
                wavelength=e.wavelength_m,
                saturation=self.saturation,
                threads=self.threads,
                neighbours=self.neighbours,
                spectrum=self.spectrum,
                windows=self._fixed_windows() or self._chosen_windows(),
                grid=self.grid,
            )
            self._probe.configure(demod.peaks)
            if self.background is not None and e.reference == "absolute":
                measured = self._probe.measure(self.background)
                assert measured is not None
                demod.set_background(self.background, measured.values)
            self._demod = demod
            self._settings_key = self._settings()
        return self._demod

    def reset_reference(self) -> None:
        """Make the next frame the reference (absolute maps start from zero again)."""
        if self._demod is not None:
            self._demod.reset_reference()

    def break_sequence(self) -> None:
        """The next frame does not follow the previous one (a replay jumped): no map pairs them.

        See :meth:`~holoview.processing.maps.demodulate.Demodulator.break_sequence`.
        """
        if self._demod is not None:
            self._demod.break_sequence()

    def process(
        self, frame: np.ndarray, values: Sequence[complex] | np.ndarray | None = None
    ) -> DemodResult | None:
        """Demodulate ``frame`` (not modified); None when there is no peak.

        ``values``: the carrier probe's values of the frame at the demodulator's peaks,
        when the caller has them already (the series measured them); else measured here.
        The maps' mean phases, steps and unwrapping in time follow them.

        Raises
        ------
        DamagedFrameError
            The frame was damaged in transfer (rows lost): no maps from it, the
            reference untouched.
        """
        demod = self.build()
        if demod is None:
            return None
        damage = frame_damage(np.asarray(frame))
        if damage is not None:
            raise DamagedFrameError(f"frame damaged in transfer: {damage}; no maps", damage)
        if values is None:
            measured = self._probe.measure(frame)
            assert measured is not None
            values = measured.values
        given = np.asarray(values, dtype=np.complex128)
        return demod.process(frame, given if np.all(np.isfinite(given)) else None)
