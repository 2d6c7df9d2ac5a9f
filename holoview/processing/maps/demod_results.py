"""What the demodulator returns for a frame, and its modes.

:class:`~holoview.processing.maps.demodulate.Demodulator` returns a :class:`DemodResult`.

:class:`DemodResult` holds a frame's results, one :class:`PeakResult` per peak (maps
at box resolution, phases in rad, heights in m), and the flags either can carry.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from holoview.processing.peaks.detection import Peak

__all__ = [
    "FRAME_FLAGS",
    "MAP_GRIDS",
    "PEAK_RESULT_FLAGS",
    "REFERENCE_MODES",
    "UNWRAP_MODES",
    "DemodResult",
    "PeakResult",
]

#: Reference modes (docs/design.md, paper section 3).
REFERENCE_MODES: tuple[str, ...] = ("synthetic", "absolute", "relative")

#: Spatial unwrapping policies: ``"auto"`` unwraps only maps that have wraps.
UNWRAP_MODES: tuple[str, ...] = ("auto", "always", "never")

#: The grids the maps come on: ``"box"``, the demodulation box's (pixel ``(p, q)`` at frame
#: position ``(p rows / by, q cols / bx)``), or ``"frame"``, the camera frame's pixels.
MAP_GRIDS: tuple[str, ...] = ("box", "frame")

#: Flags a :class:`PeakResult` can carry (see its documentation).
PEAK_RESULT_FLAGS: tuple[str, ...] = ("reference", "phase_step", "low_amplitude", "overlap")

#: Flags a :class:`DemodResult` can carry (see its documentation).
FRAME_FLAGS: tuple[str, ...] = ("nonfinite", "no_signal", "saturated", "reference")


@dataclass(frozen=True)
class PeakResult:
    """What one frame gives for one peak (maps at box resolution).

    Attributes
    ----------
    peak : Peak
        The peak demodulated.
    radius : float
        Its window radius (cycles/pixel).
    field : ndarray of complex64, shape (by, bx)
        Complex field (counts), carrier removed to the nearest FFT bin.
    phase : ndarray of float32, shape (by, bx)
        Phase against the reference (rad); unwrapped when ``unwrapped``.
    delta_h : ndarray of float32 or None
        Height change (m), when the peak has alpha and a wavelength was given.
    carrier_value : complex
        The field's mean against the sub-bin plane wave (counts): the spectrum at
        the carrier alone, whose phase is the spatially averaged phase.
    mean_phase : float
        Phase of ``carrier_value`` against the reference (rad, wrapped).
    mean_phase_unwrapped : float
        Mean phase unwrapped in time since the reference was set (rad); in
        relative mode the running sum of the steps, in synthetic mode it starts
        at the first frame's wrapped value.
    mask : ndarray of bool, shape (by, bx)
        Trusted pixels: inside the aperture, amplitude high enough.
    noise : float
        Phase noise per trusted pixel (rad, rms), from the noise floor of the frame's
        spectrum and the reference's (:func:`~holoview.processing.maps.phase_maps.phase_noise`);
        0 on a reference frame, NaN without a trusted pixel.
    noise_height : float or None
        ``noise`` converted to height (m) like ``delta_h``.
    error_height : float or None
        The map's expected error per trusted pixel (m): ``noise`` and what its window
        cuts of the surface's change, as measured when the window was matched
        (:attr:`~holoview.processing.peaks.matched.Window.cut`), in quadrature; what
        fusion weighs the maps by. 0 on a reference frame.
    unwrapped : bool
        Whether spatial unwrapping ran on this map.
    flags : frozenset of str
        ``"reference"`` (this frame became the reference; phase zero),
        ``"phase_step"`` (mean phase moved more than
        :data:`~holoview.processing.maps.mean_phases.PHASE_STEP_LIMIT`
        since the previous frame), ``"low_amplitude"`` (few trusted pixels),
        ``"overlap"`` (window wider than half the distance to another peak).
    """

    peak: Peak
    radius: float
    field: np.ndarray
    phase: np.ndarray
    delta_h: np.ndarray | None
    carrier_value: complex
    mean_phase: float
    mean_phase_unwrapped: float
    mask: np.ndarray
    noise: float
    noise_height: float | None
    unwrapped: bool
    flags: frozenset[str]
    error_height: float | None = None


@dataclass(frozen=True)
class DemodResult:
    """Everything one frame gives.

    Attributes
    ----------
    index : int
        Frames processed since construction or the last reference reset (from 0).
    reference : str
        The reference mode.
    mean_counts : float
        Mean pixel value of the frame (counts).
    frame_shape, box_shape : tuple of int
        ``(rows, cols)`` of the frame and of every per-peak map.
    radius : float
        The largest window radius used (cycles/pixel); each peak's own is
        :attr:`PeakResult.radius`.
    peaks : tuple of PeakResult
        One per peak, in the demodulator's order; empty for a flagged frame.
    flags : frozenset of str
        Frame-level problems: ``"nonfinite"`` (NaN or infinite pixels: nothing
        demodulated, reference untouched), ``"no_signal"`` (no trusted pixel in
        any peak: constant, black or saturated frame), ``"saturated"`` (pixels at
        the saturation level, when one was given), ``"reference"``.
    """

    index: int
    reference: str
    mean_counts: float
    frame_shape: tuple[int, int]
    box_shape: tuple[int, int]
    radius: float
    peaks: tuple[PeakResult, ...]
    flags: frozenset[str]

    def by_label(self, label: str) -> PeakResult:
        """Return the result of the peak named ``label``."""
        for result in self.peaks:
            if result.peak.label == label:
                return result
        raise KeyError(label)
