"""Each peak's mean phase frame after frame: its steps, its reference, its unwrapping in time.

The demodulator (:class:`~holoview.processing.maps.demodulate.Demodulator`) places each
map's 2 pi offset where the peak's mean phase, unwrapped in time, says it should sit.
:class:`MeanPhases` keeps that running state of scalars per peak (the previous value,
the reference's value, the phase unwrapped since the reference) and nothing else, so
that a process which holds only the frames' carrier values (counts, complex; the
carrier probe's, :mod:`holoview.processing.series.carrier_probe`) can replay what the
demodulator did over them, with the same arithmetic, and hand the state on
(:class:`MeanPhaseState`): a worker demodulating a chunk of a run from the middle then
places every map's offset as a demodulator that saw every frame before would.

Phases in rad; values in counts.
"""

from __future__ import annotations

import cmath
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["PHASE_STEP_LIMIT", "MeanPhaseState", "MeanPhases", "PhaseStep"]

#: A mean-phase step per frame (rad) beyond which a peak is flagged ``"phase_step"``.
PHASE_STEP_LIMIT = 0.8 * np.pi


@dataclass(frozen=True)
class PhaseStep:
    """What one frame's value of one peak gives.

    Attributes
    ----------
    step : float
        Mean-phase change since the previous value, rad (0 for the first, or after a
        break in the sequence).
    stepped : bool
        ``|step|`` is beyond :data:`PHASE_STEP_LIMIT`.
    reference : bool
        This frame becomes the peak's reference (absolute and relative modes).
    mean_phase : float
        Mean phase against the reference, rad, wrapped: the step in relative mode, the
        value's own phase in synthetic mode, 0 on a reference frame.
    target : float
        Where the map's mean should sit, rad: ``mean_phase`` in relative mode, else the
        mean phase unwrapped in time since the reference.
    """

    step: float
    stepped: bool
    reference: bool
    mean_phase: float
    target: float


@dataclass(frozen=True)
class MeanPhaseState:
    """The running state of :class:`MeanPhases`, per peak (picklable, to hand on).

    Attributes
    ----------
    previous : tuple of (complex or None)
        The last value taken (None: none yet, or the sequence was broken).
    reference : tuple of (complex or None)
        The reference's value (None: the next frame becomes the reference).
    unwrapped : tuple of float
        Mean phase unwrapped in time since the reference, rad.
    """

    previous: tuple[complex | None, ...]
    reference: tuple[complex | None, ...]
    unwrapped: tuple[float, ...]


class MeanPhases:
    """Follow the mean phase of ``count`` peaks from frame to frame in one reference mode.

    Parameters
    ----------
    count : int
        Peaks.
    mode : {"synthetic", "absolute", "relative"}
        The reference mode (:mod:`~holoview.processing.maps.demodulate`).
    background : sequence of complex, optional
        Each peak's value in a background hologram, the reference of absolute phases.

    Examples
    --------
    >>> phases = MeanPhases(1, "absolute")
    >>> [round(phases.advance(0, v).target, 3) for v in (1, 1j, -1, -1j, 1)]
    [0.0, 1.571, 3.142, 4.712, 6.283]
    """

    def __init__(self, count: int, mode: str, background: Sequence[complex] | None = None) -> None:
        self.mode = mode
        self._background = None if background is None else tuple(background)
        self._count = int(count)
        self.reset()

    def reset(self) -> None:
        """Forget every value; the next frame starts over (against the background, if any)."""
        n = self._count
        self._previous: list[complex | None] = [None] * n
        self._reference: list[complex | None] = (
            [None] * n if self._background is None else list(self._background)
        )
        self._unwrapped = [0.0] * n

    def break_sequence(self) -> None:
        """The next frame does not follow the previous one: no step over the break.

        In relative mode the next frame is a reference frame again.
        """
        n = self._count
        self._previous = [None] * n
        if self.mode == "relative":
            self._reference = [None] * n

    def state(self) -> MeanPhaseState:
        """The running state, to resume from elsewhere (:meth:`restore`)."""
        return MeanPhaseState(tuple(self._previous), tuple(self._reference), tuple(self._unwrapped))

    def restore(self, state: MeanPhaseState) -> None:
        """Resume from ``state`` (taken by :meth:`state` after the same frames)."""
        self._previous = list(state.previous)
        self._reference = list(state.reference)
        self._unwrapped = list(state.unwrapped)

    def advance(self, i: int, value: complex) -> PhaseStep:
        """Take peak ``i``'s value of the next frame (counts); return what it gives."""
        previous = self._previous[i]
        step = 0.0 if previous is None else cmath.phase(value * previous.conjugate())
        self._previous[i] = value
        reference = False
        if self.mode == "synthetic":
            mean_phase = cmath.phase(value)
            if previous is None:
                self._unwrapped[i] = mean_phase
            else:
                self._unwrapped[i] += step
        elif self._reference[i] is None:
            reference = True
            self._reference[i] = value
            self._unwrapped[i] = 0.0
            mean_phase = 0.0
        else:
            self._unwrapped[i] += step
            if self.mode == "relative":
                mean_phase = step
            else:
                ref = self._reference[i]
                assert ref is not None
                mean_phase = cmath.phase(value * ref.conjugate())
                if previous is None:  # the first against a background, or after a break
                    self._unwrapped[i] = mean_phase
        target = mean_phase if self.mode == "relative" else self._unwrapped[i]
        return PhaseStep(step, abs(step) > PHASE_STEP_LIMIT, reference, mean_phase, target)

    def unwrapped(self, i: int) -> float:
        """Peak ``i``'s mean phase unwrapped in time since its reference, rad."""
        return self._unwrapped[i]
