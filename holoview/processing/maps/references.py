"""What each peak's phases are taken against, frame after frame (the demodulator's state).

:class:`PhaseReferences` holds, for the
:class:`~holoview.processing.maps.demodulate.Demodulator`, every peak's reference field
(the conjugate of the field that the next map is taken against: the reference frame's
in ``absolute`` mode, the previous frame's in ``relative`` mode, an object-free
background hologram's when one is set; none in ``synthetic`` mode, where the sub-bin
plane wave is the reference), the reference's spectrum at the noise-floor bins (the
noise of a map is that of the change since its reference), and the running mean phases
(:class:`~holoview.processing.maps.mean_phases.MeanPhases`).

Fields in counts at box resolution (complex64), phases in rad, noise power in counts^2
per spectrum bin.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from holoview.processing.maps.mean_phases import MeanPhases, MeanPhaseState, PhaseStep
from holoview.processing.maps.phase_maps import floor_power

__all__ = ["PhaseReferences"]


class PhaseReferences:
    """Every peak's reference field, the reference's noise-floor samples, the mean phases.

    Parameters
    ----------
    count : int
        Peaks.
    mode : {"synthetic", "absolute", "relative"}
        The reference mode (:mod:`~holoview.processing.maps.demodulate`).

    Notes
    -----
    Use it from one thread at a time (the demodulator's rule).
    """

    def __init__(self, count: int, mode: str) -> None:
        self.count = int(count)
        self.mode = mode
        #: per peak, the background's conjugate field and carrier value (counts), or None
        self._background: tuple[tuple[np.ndarray, complex], ...] | None = None
        self._background_floor: np.ndarray | None = None
        self.reset()

    def set_background(
        self, fields: Sequence[tuple[np.ndarray, complex]] | None, floor: np.ndarray | None
    ) -> None:
        """Take phases against a background from now on (None: against the first frame).

        ``fields``: per peak, the background's conjugate field (kept, not copied) and its
        carrier value; ``floor``: its spectrum at the noise-floor bins. Resets the state.
        """
        self._background = None if fields is None else tuple(fields)
        self._background_floor = None if fields is None else floor
        self.reset()

    def reset(self) -> None:
        """Forget the reference frame and the mean phases (the background stays the reference)."""
        #: per peak, the conjugate of the reference field, or None before one
        self._conj: list[np.ndarray | None] = [None] * self.count
        values = None
        if self._background is not None:
            values = [value for _, value in self._background]
            self._conj = [conj.copy() for conj, _ in self._background]
        self._phases = MeanPhases(self.count, self.mode, values)
        #: the reference's spectrum at the noise-floor bins (absolute and relative modes)
        self._floor = self._background_floor

    def break_sequence(self) -> None:
        """Forget the previous frame (relative mode starts over; an absolute reference stays)."""
        self._phases.break_sequence()
        if self.mode == "relative":
            self._conj = [None] * self.count
            self._floor = None

    def floor(self, samples: np.ndarray) -> float:
        """Noise power per bin (counts^2) of this frame's phase maps; 0 for a reference frame.

        Synthetic mode: the frame's own floor (``samples``, the frame's spectrum at the
        noise-floor bins); absolute and relative modes: the floor of the change since
        the reference frame (the previous frame in relative mode), whose noise both
        enter the map. Advances the reference's samples.
        """
        if self.mode == "synthetic":
            return floor_power(samples)
        reference = self._floor
        if self.mode == "relative" or reference is None:
            self._floor = samples
        return 0.0 if reference is None else floor_power(samples, reference)

    def field(self, i: int) -> np.ndarray | None:
        """Peak ``i``'s reference field (counts, a new array), or None (before one; synthetic)."""
        conj = self._conj[i]
        return None if conj is None or self.mode == "synthetic" else np.conj(conj)

    def advance(self, i: int, value: complex) -> PhaseStep:
        """Peak ``i``'s mean phase advanced by this frame's carrier value (counts)."""
        return self._phases.advance(i, value)

    def against(
        self, i: int, field: np.ndarray, ramp_conj: np.ndarray, reference: bool, out: np.ndarray
    ) -> np.ndarray | None:
        """Peak ``i``'s field times its reference's conjugate, in ``out``; None on a reference.

        Synthetic mode: against the sub-bin plane wave (``ramp_conj``, its conjugate);
        else against the reference field, which ``field`` becomes when ``reference``
        (this frame is the peak's reference: None is returned) and, in relative mode,
        after this frame.
        """
        if self.mode == "synthetic":
            return np.multiply(field, ramp_conj, out=out)
        if reference:
            self._conj[i] = np.conj(field)
            return None
        conj = self._conj[i]
        assert conj is not None
        np.multiply(field, conj, out=out)
        if self.mode == "relative":
            np.conjugate(field, out=conj)
        return out

    def unwrapped(self, i: int) -> float:
        """Peak ``i``'s mean phase unwrapped in time since the reference (rad)."""
        return float(self._phases.unwrapped(i))

    def state(self) -> MeanPhaseState:
        """The mean phases' running state."""
        return self._phases.state()

    def restore(self, state: MeanPhaseState) -> None:
        """Resume the mean phases from ``state``."""
        self._phases.restore(state)
