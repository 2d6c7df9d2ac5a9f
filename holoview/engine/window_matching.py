"""When the live windows are matched to the surface again, and what the operator is told.

A run's windows are matched once, to the change its maps show
(:mod:`holoview.processing.peaks.matched`). Live, the surface can change its bandwidth
(waves start or die out), so :class:`WindowMatcher` measures the change between the
frames of two detections, about a second apart, at every detection, and matches the
windows again (:meth:`~holoview.engine.frame_core.FrameCore.match`, which restarts the
maps) only:

- the first time a change is measured;
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
"""

from __future__ import annotations

import numpy as np

from holoview.engine.frame_core import FrameCore
from holoview.errors import InputError
from holoview.processing.peaks.matched import Window
from holoview.processing.peaks.radii import distinct_neighbours
from holoview.processing.peaks.surface_spectrum import (
    MEAN_FRAMES,
    ChangeAverage,
    MeanChange,
    SurfaceSpectrum,
    measure_spectrum,
)

__all__ = ["CHANGE_BINS", "CHANGE_FRACTION", "CONFIRMATIONS", "WindowMatcher"]

#: A radius differs when it moves by more than this fraction of the one in use ...
CHANGE_FRACTION = 0.25

#: ... and by more than this many FFT bins.
CHANGE_BINS = 2.0

#: Detections in a row that must show the change before the windows follow it.
CONFIRMATIONS = 3


def _moved(new: Window, old: Window, bins: float) -> bool:
    step = abs(new.radius - old.radius)
    return step > CHANGE_FRACTION * old.radius and step * bins > CHANGE_BINS


class WindowMatcher:
    """Decide, detection after detection, when the live windows are matched again.

    Used from one thread (the live maps worker). Frames are kept (a copy of one frame).
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
        experiment = core.experiment
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
            mean = self._accumulate(core, frame, None if synthetic else previous)
            spectrum = measure_spectrum(
                frame, None if synthetic else previous, band=band, mean=mean
            )
        except InputError:
            return None  # a frame equal to the last (a stuck camera): no change to measure
        self.latest = spectrum
        in_use = core.windows()
        wanted = core.windows_for(spectrum)
        if core.spectrum is None or self._requested or not in_use or wanted is None:
            return self._match(core, spectrum, "on request" if self._requested else None)
        bins = float(min(core.frame_shape))
        moved = [
            label
            for (label, old), new in zip(in_use.items(), wanted, strict=False)
            if _moved(new, old, bins)
        ]
        self._streak = self._streak + 1 if moved else 0
        if self._streak < CONFIRMATIONS:
            return None
        before = {label: w.radius for label, w in in_use.items()}
        note = self._match(core, spectrum, "the surface's bandwidth changed")
        after = core.windows_for(spectrum) or ()
        changes = ", ".join(
            f"{label} {before[label]:.4f} -> {w.radius:.4f}"
            for label, w in zip(in_use, after, strict=False)
            if label in moved
        )
        return f"{note}: {changes} cycles/px" if changes else note

    def _accumulate(
        self, core: FrameCore, frame: np.ndarray, reference: np.ndarray | None
    ) -> MeanChange | None:
        """Add this detection's change around ``core``'s carriers; the mean so far."""
        carriers = tuple(p.carrier for p in core.peaks)
        average = self._average
        if not carriers:
            self._average = None
            return None
        if average is None or average.carriers != carriers or average.shape != frame.shape:
            others = distinct_neighbours(frame.shape, np.array(carriers), core.neighbours)
            average = self._average = ChangeAverage(
                frame.shape,
                carriers,
                neighbours=[(float(o[0]), float(o[1])) for o in others],
                horizon=MEAN_FRAMES,
            )
        average.add(frame, reference)
        return average.result()

    def _match(self, core: FrameCore, spectrum: SurfaceSpectrum, why: str | None) -> str:
        first = core.spectrum is None
        core.match(spectrum)
        self._requested = False
        self._streak = 0
        if first and why is None:
            return "windows matched to the surface's change (maps restart)"
        return f"windows matched again ({why}; maps restart)"
