"""One peak's maps of one frame from its box: field, trusted pixels, 2 pi offset, result.

The per-peak steps of :class:`~holoview.processing.maps.demodulate.Demodulator`: the
box inverted into a new field (:func:`invert_box`), the pixels trusted by amplitude
(:func:`trusted_pixels`), the wrapped phase map against the peak's reference with its
noise (:func:`phase_map`, the only step that touches the references' state), the mean
phase of the trusted pixels that sets a map's 2 pi offset (:func:`trusted_level`), and
the peak's result with its offset, noise and heights (:func:`peak_result`). Scratch
buffers are a phase workspace's
(:class:`~holoview.processing.fourier.fastmath.AngleWorkspace`), free between phases.

Fields in counts, phases in rad, heights in m; maps at box resolution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyfftw

from holoview.processing.fourier.boxes import BoxGeometry, cut_box
from holoview.processing.fourier.fastmath import TWO_PI, AngleWorkspace, angle
from holoview.processing.maps.demod_results import PeakResult
from holoview.processing.maps.phase_maps import PhaseMap, median_magnitude, phase_noise
from holoview.processing.maps.references import PhaseReferences
from holoview.processing.maps.unwrap import has_wraps
from holoview.processing.peaks.detection import Peak

__all__ = [
    "MIN_VALID_FRACTION",
    "PeakBox",
    "invert_box",
    "peak_result",
    "phase_map",
    "trusted_level",
    "trusted_pixels",
]

#: A peak with fewer trusted pixels than this fraction of those it could have (inside the
#: aperture, off the border) is flagged ``"low_amplitude"``.
MIN_VALID_FRACTION = 0.5


@dataclass(frozen=True)
class PeakBox:
    """What one peak's step of every frame takes (:func:`phase_map`), fixed by the demodulator.

    Attributes
    ----------
    index : int
        The peak's position in the demodulator's list (and in its references).
    geometry : BoxGeometry
        Its box: where in the half spectrum, its window, its sub-bin plane wave.
    trusted : ndarray of bool
        The box pixels that may be trusted (inside the aperture, off the border).
    trustable : int
        Their count.
    amplitude : float
        The peak's amplitude relative to the frame's mean (0 when not known).
    overlapping : bool
        Its window reaches another peak (flag ``"overlap"``).
    frame_size : int
        Pixels in the frame (``rows cols``).
    """

    index: int
    geometry: BoxGeometry
    trusted: np.ndarray
    trustable: int
    amplitude: float
    overlapping: bool
    frame_size: int


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


def phase_map(
    half: np.ndarray,
    box: PeakBox,
    plan: pyfftw.FFTW,
    references: PhaseReferences,
    *,
    mean: float,
    floor: float,
    value: complex | None,
    min_amplitude: float,
    check_wraps: bool,
    workspace: AngleWorkspace,
) -> PhaseMap:
    """Cut, window and invert a peak's box; its phase against its reference (wrapped).

    Parameters
    ----------
    half : ndarray of complex64
        The frame's half spectrum
        (:class:`~holoview.processing.fourier.half_spectrum.HalfSpectrum`).
    box : PeakBox
        The peak's constants.
    plan : pyfftw.FFTW
        The box shape's inverse FFT; its input buffer is the product's scratch.
    references : PhaseReferences
        The demodulator's references: the peak's mean phase is advanced, its reference
        field taken or replaced.
    mean : float
        The frame's mean (counts).
    floor : float
        The noise power per spectrum bin of this frame's maps (counts^2).
    value : complex or None
        The peak's carrier value given for this frame (counts), else the box's own mean.
    min_amplitude : float
        The fraction of the expected amplitude a trusted pixel reaches.
    check_wraps : bool
        Whether to tell, while the map is in cache, if it wraps (``unwrap="auto"``).
    workspace : AngleWorkspace
        Scratch of the box's shape.
    """
    geo = box.geometry
    field = invert_box(half, geo, plan)
    flags: set[str] = {"overlap"} if box.overlapping else set()
    power, mask, valid = trusted_pixels(
        field,
        box.amplitude * mean if box.amplitude > 0 else None,
        min_amplitude,
        box.trusted,
        workspace,
    )
    if valid < MIN_VALID_FRACTION * box.trustable:
        flags.add("low_amplitude")

    # mean phase: the field against the sub-bin plane wave, averaged (or given)
    if value is None:
        value = complex(np.vdot(geo.ramp, field)) / field.size
    step = references.advance(box.index, value)
    if step.stepped:
        flags.add("phase_step")

    # the box's spectrum is spent: the product goes where it was (a buffer still in cache)
    product = references.against(box.index, field, geo.ramp_conj, step.reference, plan.input_array)
    level, wraps = None, None
    if product is None:
        flags.add("reference")
        phase = np.zeros(field.shape, dtype=np.float32)
        noise = 0.0
    else:
        noise = phase_noise(power, mask, floor, geo.area_fraction, box.frame_size)
        phase = angle(product, workspace=workspace)
        if valid:
            # while the map is in cache: the 2 pi offset's level, whether it wraps
            level = trusted_level(phase, mask, valid, workspace)
            if check_wraps:
                wraps = has_wraps(phase, mask)
    return PhaseMap(
        field=field,
        phase=phase,
        mask=mask,
        valid=valid,
        value=value,
        mean_phase=step.mean_phase,
        target=step.target,
        flags=flags,
        live=product is not None,
        noise=noise,
        wraps=wraps,
        level=level,
    )


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
