"""When the live windows are matched to the surface again, and what the operator is told.

A run's windows are matched once, to the change its maps show
(:mod:`holoview.processing.peaks.matched`). Live, the surface can change its bandwidth
(waves start or die out), so :class:`WindowMatcher` measures the change between the
frames of two detections, about a second apart, at every detection, and matches the
windows again (:meth:`~holoview.engine.frame_core.FrameCore.match`, which restarts the
maps) only:

- the first time a change is measured (with a peak demodulated);
- when a peak was added since (its window at the bound, not measured);
- when the operator asks (:meth:`WindowMatcher.request`);
- when the radii the new measurement gives differ from those in use by more than
  :data:`CHANGE_FRACTION` (and :data:`CHANGE_BINS` FFT bins) on
  :data:`CONFIRMATIONS` detections in a row: the surface's bandwidth changed.

Each match returns one line for the operator (the windows changed, the maps restart),
so that the maps' continuity is never broken silently.

The changes measured at the detections are also accumulated around the carriers in use
(:class:`~holoview.processing.peaks.surface_spectrum.ChangeAverage`, the last
:data:`~holoview.processing.peaks.surface_spectrum.MEAN_FRAMES` or so weighing most):
waves that stand above the noise only over many frames are passed whole, as headless.

A measurement takes seconds on a large frame (the maps at a dozen radii per peak), far
longer than a frame: the live maps worker must not wait for it. So the work is split
by thread. :func:`windows_in_use` takes, between two frames, what the measurement needs
of the maps' core (a :class:`WindowsInUse`: cheap, nothing shared); :meth:`WindowMatcher.propose`
measures on any thread and returns a :class:`Rematch` (the spectrum, the new windows
by label, the line) when the windows are due to change; :meth:`Rematch.apply` hands it
to the core between two frames, where the demodulator is rebuilt with those windows
without measuring anything. :meth:`WindowMatcher.measure` does all three in one call.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FrameCore
from holoview.errors import InputError
from holoview.processing.peaks.matched import Window
from holoview.processing.peaks.radii import UNMEASURED_REASON, distinct_neighbours, peak_windows
from holoview.processing.peaks.surface_spectrum import (
    MEAN_FRAMES,
    ChangeAverage,
    MeanChange,
    SurfaceSpectrum,
    measure_spectrum,
)

__all__ = [
    "CHANGE_BINS",
    "CHANGE_FRACTION",
    "CONFIRMATIONS",
    "MatchJob",
    "Rematch",
    "WindowMatcher",
    "WindowsInUse",
    "windows_in_use",
]

#: A radius differs when it moves by more than this fraction of the one in use ...
CHANGE_FRACTION = 0.25

#: ... and by more than this many FFT bins.
CHANGE_BINS = 2.0

#: Detections in a row that must show the change before the windows follow it.
CONFIRMATIONS = 3


def _moved(new: Window, old: Window, bins: float) -> bool:
    step = abs(new.radius - old.radius)
    return step > CHANGE_FRACTION * old.radius and step * bins > CHANGE_BINS


@dataclass(frozen=True)
class WindowsInUse:
    """What a measurement needs of the maps' core, taken between two frames.

    Attributes
    ----------
    frame_shape : tuple of int
        ``(rows, cols)`` of the frames, pixels.
    experiment : Experiment
        The experiment in use (its radius rule and reference mode).
    labels : tuple of str
        The demodulated peaks' labels, in the demodulator's order (empty before the
        first demodulator).
    carriers : ndarray, shape (n, 2)
        Their carriers ``(fx, fy)``, cycles/pixel (before the first demodulator, the
        peaks the core was given; None without any).
    others : ndarray, shape (m, 2)
        The detected peaks that bound the windows and are not demodulated, cycles/pixel.
    kind, taper
        The windows' shape.
    windows : mapping of str to Window
        Each labelled peak's window in use.
    matched : bool
        Whether the windows in use were matched to a measured spectrum.
    """

    frame_shape: tuple[int, int]
    experiment: Experiment
    labels: tuple[str, ...] = ()
    carriers: np.ndarray | None = None
    others: np.ndarray | None = None
    kind: str = ""
    taper: float = 0.0
    windows: Mapping[str, Window] | None = None
    matched: bool = False

    def windows_for(self, spectrum: SurfaceSpectrum) -> dict[str, Window] | None:
        """The windows ``spectrum`` gives these peaks, by label (None before a demodulator).

        The slow part of a match (seconds on a 1024 x 1024 frame with six peaks).
        """
        if not self.labels or self.carriers is None or self.others is None:
            return None
        windows = peak_windows(
            self.frame_shape,
            self.carriers,
            self.experiment.radius,
            self.others,
            kind=self.kind,
            taper=self.taper,
            spectrum=spectrum,
        )
        return dict(zip(self.labels, windows, strict=True))


def windows_in_use(core: FrameCore) -> WindowsInUse:
    """What :meth:`WindowMatcher.propose` needs of ``core`` (copied: ``core`` may change)."""
    demod = core.demodulator
    if demod is None:
        if not core.peaks:
            return WindowsInUse(core.frame_shape, core.experiment, matched=False)
        given = np.array([p.carrier for p in core.peaks], dtype=np.float64)
        return WindowsInUse(
            core.frame_shape,
            core.experiment,
            carriers=given,
            others=distinct_neighbours(core.frame_shape, given, core.neighbours),
            matched=core.spectrum is not None,
        )
    carriers = np.array([p.carrier for p in demod.peaks], dtype=np.float64)
    return WindowsInUse(
        frame_shape=core.frame_shape,
        experiment=core.experiment,
        labels=tuple(p.label or f"#{i}" for i, p in enumerate(demod.peaks)),
        carriers=carriers,
        others=distinct_neighbours(core.frame_shape, carriers, core.neighbours),
        kind=demod.window,
        taper=demod.taper,
        windows=core.windows(),
        matched=core.spectrum is not None,
    )


@dataclass(frozen=True)
class Rematch:
    """Windows matched again: what the maps' core takes between two frames.

    Attributes
    ----------
    spectrum : SurfaceSpectrum
        The spectrum the windows were matched to.
    windows : mapping of str to Window
        The new window of each peak, by label.
    note : str
        The line for the operator (the windows changed, the maps restart).
    """

    spectrum: SurfaceSpectrum
    windows: Mapping[str, Window]
    note: str

    def apply(self, core: FrameCore) -> None:
        """Use these windows in ``core`` from its next frame on (the maps restart)."""
        core.match(self.spectrum, self.windows)


@dataclass(frozen=True)
class MatchJob:
    """One measurement for :class:`WindowMatcher`, handed from the maps to the match thread.

    Attributes
    ----------
    in_use : WindowsInUse
        The maps' core when ``frame`` came.
    frame : ndarray
        The frame of the detection (counts; the job's own copy).
    band : float
        The waves the detection saw, cycles/pixel.
    requested : bool
        The operator asked for a match since the last job.
    """

    in_use: WindowsInUse
    frame: np.ndarray
    band: float
    requested: bool = False

    def run(self, matcher: WindowMatcher) -> Rematch | None:
        """Measure with ``matcher`` (:meth:`WindowMatcher.propose`); slow, any thread."""
        if self.requested:
            matcher.request()
        return matcher.propose(self.in_use, self.frame, self.band)


class WindowMatcher:
    """Decide, detection after detection, when the live windows are matched again.

    Used from one thread at a time (the live match thread). Frames are kept (a copy of
    one frame).
    """

    def __init__(self) -> None:
        self._previous: np.ndarray | None = None
        self._average: ChangeAverage | None = None
        self._requested = False
        self._streak = 0
        #: The newest measurement (None before one).
        self.latest: SurfaceSpectrum | None = None

    def request(self) -> None:
        """Match the windows at the next measurement, whatever it shows (the operator asked)."""
        self._requested = True

    def forget(self) -> None:
        """Start over (new frame shape, a replay that jumped): the next pair is measured afresh."""
        self._previous = None
        self._average = None
        self._streak = 0

    def measure(self, core: FrameCore, frame: np.ndarray, band: float = 0.0) -> str | None:
        """Measure ``frame`` against the last one measured; match ``core``'s windows when due.

        :meth:`propose` and :meth:`Rematch.apply` in one call, on one thread.

        Parameters
        ----------
        core : FrameCore
            The maps' core (its experiment says the rule and the reference mode).
        frame : ndarray
            The frame of this detection (counts; not modified, copied).
        band : float
            The waves this detection saw, cycles/pixel
            (:func:`~holoview.processing.peaks.radii.surface_band`).

        Returns
        -------
        str or None
            The line for the operator when the windows were matched again.
        """
        rematch = self.propose(windows_in_use(core), frame, band)
        if rematch is None:
            return None
        rematch.apply(core)
        return rematch.note

    def propose(self, in_use: WindowsInUse, frame: np.ndarray, band: float = 0.0) -> Rematch | None:
        """Measure ``frame`` against the last one measured; the new windows when due.

        Parameters
        ----------
        in_use : WindowsInUse
            The maps' core as it was when ``frame`` came (:func:`windows_in_use`).
        frame : ndarray
            The frame of this detection (counts; not modified, copied).
        band : float
            The waves this detection saw, cycles/pixel.

        Returns
        -------
        Rematch or None
            The windows to use from the next frame, and the line for the operator;
            None while the windows in use stay.
        """
        experiment = in_use.experiment
        if experiment.radius_rule != "matched":
            self._previous = None
            return None
        synthetic = experiment.reference == "synthetic"
        previous = self._previous
        self._previous = np.array(frame, copy=True)
        if previous is None and not synthetic:
            return None
        if previous is not None and previous.shape != self._previous.shape:
            return None
        try:
            mean = self._accumulate(in_use, frame, None if synthetic else previous)
            spectrum = measure_spectrum(
                frame, None if synthetic else previous, band=band, mean=mean
            )
        except InputError:
            return None  # a frame equal to the last (a stuck camera): no change to measure
        self.latest = spectrum
        current = in_use.windows or {}
        wanted = in_use.windows_for(spectrum)
        if wanted is None:
            return None  # no peak demodulated yet: nothing to match (a request waits)
        if not in_use.matched or self._requested or not current:
            why = "on request" if self._requested else None
            return self._rematch(spectrum, wanted, why, not in_use.matched)
        if any(w.reason == UNMEASURED_REASON for w in current.values()):
            return self._rematch(spectrum, wanted, "new peaks", False)
        bins = float(min(in_use.frame_shape))
        moved = [
            label
            for label, old in current.items()
            if label in wanted and _moved(wanted[label], old, bins)
        ]
        self._streak = self._streak + 1 if moved else 0
        if self._streak < CONFIRMATIONS:
            return None
        rematch = self._rematch(spectrum, wanted, "the surface's bandwidth changed", False)
        changes = ", ".join(
            f"{label} {current[label].radius:.4f} -> {wanted[label].radius:.4f}"
            for label in current
            if label in moved
        )
        note = f"{rematch.note}: {changes} cycles/px" if changes else rematch.note
        return Rematch(spectrum, wanted, note)

    def _accumulate(
        self, in_use: WindowsInUse, frame: np.ndarray, reference: np.ndarray | None
    ) -> MeanChange | None:
        """Add this detection's change around the carriers in use; the mean so far."""
        if in_use.carriers is None or in_use.others is None or not len(in_use.carriers):
            self._average = None
            return None
        carriers = tuple((float(c[0]), float(c[1])) for c in in_use.carriers)
        average = self._average
        if average is None or average.carriers != carriers or average.shape != frame.shape:
            average = self._average = ChangeAverage(
                frame.shape,
                carriers,
                neighbours=[(float(o[0]), float(o[1])) for o in in_use.others],
                horizon=MEAN_FRAMES,
            )
        average.add(frame, reference)
        return average.result()

    def _rematch(
        self,
        spectrum: SurfaceSpectrum,
        windows: Mapping[str, Window],
        why: str | None,
        first: bool,
    ) -> Rematch:
        self._requested = False
        self._streak = 0
        if first and why is None:
            note = "windows matched to the surface's change (maps restart)"
        else:
            note = f"windows matched again ({why}; maps restart)"
        return Rematch(spectrum, windows, note)
