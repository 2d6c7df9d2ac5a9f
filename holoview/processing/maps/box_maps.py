"""One peak's maps of one frame from its box: field, trusted pixels, 2 pi offset, result.

The steps of :class:`~holoview.processing.maps.demodulate.Demodulator` that hold no state
of their own: the box inverted into a new field (:func:`invert_box`), the pixels trusted
by amplitude (:func:`trusted_pixels`), the mean phase of the trusted pixels that sets a
map's 2 pi offset (:func:`trusted_level`), and the peak's result with its offset, noise
and heights (:func:`peak_result`). Scratch buffers are a phase workspace's
(:class:`~holoview.processing.fourier.fastmath.AngleWorkspace`), free between phases.

Fields in counts, phases in rad, heights in m; maps at box resolution.
"""

from __future__ import annotations

import numpy as np
import pyfftw

from holoview.processing.fourier.boxes import BoxGeometry, cut_box
from holoview.processing.fourier.fastmath import TWO_PI, AngleWorkspace
from holoview.processing.maps.demod_results import PeakResult
from holoview.processing.maps.phase_maps import PhaseMap, median_magnitude
from holoview.processing.peaks.detection import Peak

__all__ = ["invert_box", "peak_result", "trusted_level", "trusted_pixels"]


def invert_box(half: np.ndarray, geometry: BoxGeometry, plan: pyfftw.FFTW) -> np.ndarray:
    """Cut, window and invert a peak's box: its field (counts, complex64), a new array.

    ``half`` is the frame's half spectrum, ``plan`` the box shape's inverse FFT
    (:func:`~holoview.processing.fourier.fftplans.ifft2_plan`), left as it was given.
    """
    source, scratch = plan.input_array, plan.output_array
    cut_box(half, geometry, source)
    # the inverse FFT writes the new array itself (no copy); the shared plan then gets
    # its own buffer back
    field = pyfftw.empty_aligned(source.shape, dtype="complex64")
    plan.update_arrays(source, field)
    plan.execute()
    plan.update_arrays(source, scratch)
    return field


def trusted_pixels(
    field: np.ndarray,
    expected: float | None,
    min_amplitude: float,
    trusted: np.ndarray,
    workspace: AngleWorkspace,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Return a field's ``|f|^2`` (counts^2), its trusted pixels (a new mask) and their count.

    A pixel is trusted where ``|f|^2`` reaches ``(min_amplitude expected)^2`` (no square
    roots; ``expected``, the field's expected amplitude in counts, or None for the
    median ``|f|``; none is trusted when it is not above 0) and ``trusted`` (aperture,
    border) holds. ``|f|^2`` lives in the
    workspace's scratch: use it up before the workspace's next phase.
    """
    power, squares = workspace.scratch, workspace.pairs
    pairs = field.view(np.float32)
    np.multiply(pairs, pairs, out=squares)
    np.add(squares[:, 0::2], squares[:, 1::2], out=power)
    if expected is None:
        expected = median_magnitude(power)
    threshold = np.float32(min_amplitude * expected)
    mask = np.greater_equal(power, threshold * threshold)
    if not expected > 0:
        mask[...] = False
    mask &= trusted
    return power, mask, int(np.count_nonzero(mask))


def trusted_level(
    phase: np.ndarray, mask: np.ndarray, valid: int, workspace: AngleWorkspace
) -> float:
    """The mean phase (rad) of a map's ``valid`` trusted pixels (``mask``), the level.

    Uses the workspace's scratch (free after a phase is taken).
    """
    if valid == phase.size:
        return float(phase.sum()) / phase.size
    weights = workspace.scratch.reshape(-1)
    np.copyto(weights, mask.reshape(-1))
    return float(np.dot(phase.reshape(-1), weights)) / valid


def peak_result(
    part: PhaseMap,
    peak: Peak,
    *,
    radius: float,
    cut: float,
    wavelength: float | None,
    mean_phase_unwrapped: float,
    workspace: AngleWorkspace,
) -> PeakResult:
    """A peak's result: its map's 2 pi offset set, its noise, its heights.

    The offset puts the trusted pixels' mean phase (:attr:`PhaseMap.level`, unless
    unwrapping replaced the map) nearest the time-unwrapped mean phase
    (:attr:`PhaseMap.target`); ``cut`` is the window's estimated error (rad) added to
    the noise in the error height; ``radius`` the window's (cycles/pixel).
    """
    phase = part.phase
    if part.live and part.valid:
        level = part.level
        if level is None or part.unwrapped:
            level = trusted_level(phase, part.mask, part.valid, workspace)
        offset = TWO_PI * round((part.target - level) / TWO_PI)
        if offset:
            phase += np.float32(offset)
    noise = part.noise
    error = float(np.hypot(noise, cut)) if noise > 0 else noise
    to_height = None
    if peak.alpha is not None and wavelength is not None:
        to_height = wavelength / (4 * np.pi * peak.alpha)
    return PeakResult(
        peak=peak,
        radius=radius,
        field=part.field,
        phase=phase,
        delta_h=None if to_height is None else phase * np.float32(to_height),
        carrier_value=part.value,
        mean_phase=part.mean_phase,
        mean_phase_unwrapped=mean_phase_unwrapped,
        mask=part.mask,
        noise=noise,
        noise_height=None if to_height is None else abs(noise * to_height),
        unwrapped=part.unwrapped,
        flags=frozenset(part.flags),
        error_height=None if to_height is None else abs(error * to_height),
    )
