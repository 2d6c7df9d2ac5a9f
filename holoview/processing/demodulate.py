"""Fourier demodulation of every labelled carrier, frame after frame (paper section 3).

:class:`Demodulator` takes one real FFT of each frame (pyFFTW, planned once per
shape), and per peak cuts a small box out of the half spectrum with the carrier
moved to the origin and the window applied in the same step, then takes an
inverse FFT of the box only. The complex field per peak therefore comes at the
box resolution (pixel ``(p, q)`` at frame position ``(p rows / by, q cols / bx)``);
:meth:`Demodulator.upsample` brings any map to the frame grid.

Conventions (DESIGN.md):

- the field is in counts: ``|field| = Y0 A`` for a fringe term ``Y0 A exp(i phi)``,
  demodulated at the FFT bin nearest the carrier (a residual sub-bin tilt remains
  in it; the synthetic reference removes it);
- phases are ``current - reference`` in rad: ``synthetic`` against the plane wave
  at the sub-bin carrier, ``absolute`` against the first frame after construction
  or :meth:`~Demodulator.reset_reference`, ``relative`` against the previous frame;
- ``delta_h = phase wavelength / (4 pi alpha)`` in metres for peaks with alpha.

Per peak and frame also: the trusted pixels (aperture, amplitude), the phase noise
(rad, and m), and the complex value at the carrier alone, whose phase is the
spatially averaged phase (paper section 4.2), unwrapped in time. Maps that wrap are
unwrapped in space (Herraez et al. 2002) or against another peak's map scaled by
the ratio of alphas (:meth:`Demodulator._unwrap`). Every returned array is new;
frames and peaks are never modified.

The demodulator keeps state (references, plans, buffers): use it from one thread
at a time. It creates no thread; FFTW may use ``threads`` internally.
"""

from __future__ import annotations

import cmath
import dataclasses
import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pyfftw

from holoview.errors import InputError
from holoview.processing.boxes import BoxGeometry, box_geometry, box_shape_for
from holoview.processing.fastmath import AngleWorkspace, angle
from holoview.processing.fftplans import default_threads, ifft2_plan, rfft2_plan
from holoview.processing.frames import MIN_SIDE
from holoview.processing.peaks import MIN_RADIUS_BINS, Peak
from holoview.processing.resample import resample_mask, upsample
from holoview.processing.unwrap import (
    EDGE,
    TWO_PI,
    has_wraps,
    phase_ratio,
    unwrap_guided,
    unwrap_spatial,
)
from holoview.processing.windows import (
    DEFAULT_TAPER,
    auto_radius,
    check_kind,
    wrap_frequency,
)

logger = logging.getLogger(__name__)

REFERENCE_MODES: tuple[str, ...] = ("synthetic", "absolute", "relative")
UNWRAP_MODES: tuple[str, ...] = ("auto", "always", "never")

#: Flags a :class:`PeakResult` can carry (see its documentation).
PEAK_RESULT_FLAGS: tuple[str, ...] = ("reference", "phase_step", "low_amplitude", "overlap")

#: Flags a :class:`DemodResult` can carry (see its documentation).
FRAME_FLAGS: tuple[str, ...] = ("nonfinite", "no_signal", "saturated", "reference")

#: Box size (bins) from which a box's inverse FFT uses the frame FFT's threads.
LARGE_BOX = 256 * 256

#: A mean-phase step per frame (rad) beyond which a peak is flagged ``"phase_step"``.
PHASE_STEP_LIMIT = 0.8 * np.pi

#: A peak with fewer trusted pixels than this fraction is flagged ``"low_amplitude"``.
MIN_VALID_FRACTION = 0.5


@dataclass(frozen=True)
class PeakResult:
    """What one frame gives for one peak (maps at box resolution).

    Attributes
    ----------
    peak : Peak
        The peak demodulated.
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
        Phase noise per pixel (rad), estimated from neighbour differences (see
        :meth:`Demodulator._noise`); 0 on a reference frame, NaN with fewer than
        two usable differences.
    noise_height : float or None
        ``noise`` converted to height (m) like ``delta_h``.
    unwrapped : bool
        Whether spatial unwrapping ran on this map.
    flags : frozenset of str
        ``"reference"`` (this frame became the reference; phase zero),
        ``"phase_step"`` (mean phase moved more than :data:`PHASE_STEP_LIMIT`
        since the previous frame), ``"low_amplitude"`` (few trusted pixels),
        ``"overlap"`` (window wider than half the distance to another peak).
    """

    peak: Peak
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
        Window radius used (cycles/pixel).
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


@dataclass
class _Partial:
    """A peak's results between demodulation and unwrapping (mutable, internal)."""

    field: np.ndarray
    phase: np.ndarray
    mask: np.ndarray
    valid: int  # number of trusted pixels
    value: complex
    mean_phase: float
    target: float  # where the map's mean should sit, rad (sets its 2 pi offset)
    flags: set[str]
    live: bool  # False for a reference frame: the phase is zero by definition
    unwrapped: bool = False


def _wrapped_inside(phase: np.ndarray, mask: np.ndarray) -> bool:
    """Whether a map has wraps away from its edge (:data:`~holoview.processing.unwrap.EDGE`)."""
    e = EDGE if min(phase.shape) > 4 * EDGE else 0
    inner = (slice(e, phase.shape[0] - e), slice(e, phase.shape[1] - e))
    return has_wraps(phase[inner], mask[inner])


def _check_peaks(peaks: Sequence[Peak]) -> tuple[Peak, ...]:
    out = tuple(peaks)
    if not out:
        raise InputError("no peaks to demodulate: give at least one")
    for i, peak in enumerate(out):
        if not isinstance(peak, Peak):
            raise InputError(f"peak {i} is a {type(peak).__name__}, not a Peak")
        fx, fy = peak.carrier
        name = f"peak {i}" + (f" ({peak.label})" if peak.label else "")
        if not (np.isfinite(fx) and np.isfinite(fy)):
            raise InputError(f"{name} has a non-finite carrier {peak.carrier}")
        if abs(fx) > 0.5 or abs(fy) > 0.5:
            raise InputError(
                f"{name} carrier ({fx:.4g}, {fy:.4g}) is outside the spectrum "
                "(|fx|, |fy| <= 0.5 cycles/pixel)"
            )
        if peak.alpha is not None and not (np.isfinite(peak.alpha) and peak.alpha != 0):
            raise InputError(f"{name} has alpha {peak.alpha}: it must be finite and nonzero")
    return out


def _names(peaks: Sequence[Peak], i: int) -> str:
    return peaks[i].label or f"peak {i}"


class Demodulator:
    """Demodulate a fixed list of peaks from frame after frame of one shape.

    Parameters
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)`` in pixels.
    peaks : sequence of Peak
        The carriers to demodulate (not empty, inside the spectrum).
    window : {"raised-cosine", "top-hat", "tukey"}
        Spectral window (:mod:`holoview.processing.windows`).
    radius : float, optional
        Window radius (cycles/pixel), the same for every peak; by default
        :func:`~holoview.processing.windows.auto_radius` of the carriers.
    reference : {"synthetic", "absolute", "relative"}
        Reference mode (module documentation).
    unwrap : {"auto", "always", "never"}
        Spatial unwrapping: ``"auto"`` runs it only when a map has wraps.
    wavelength : float, optional
        Laser wavelength (m), needed for ``delta_h``.
    aperture : ndarray of bool, optional
        Trusted region at frame resolution, shape ``shape``.
    min_amplitude : float
        A pixel is trusted when ``|field|`` reaches this fraction of the peak's
        expected amplitude ``peak.amplitude * mean`` (or of the median ``|field|``
        when the peak's amplitude is not known).
    saturation : float, optional
        Pixel value (counts) at which the camera saturates; frames reaching it
        (checked on every 4th row and column) are flagged ``"saturated"``.
    taper : float
        Tukey window edge fraction.
    threads : int, optional
        FFTW threads for the frame's FFT; by default the usable CPUs (at most 4).

    Raises
    ------
    InputError
        For a bad shape, an empty peak list, a carrier outside the spectrum, an
        unknown mode, or a radius so large that a window holds another carrier
        or zero frequency.
    """

    def __init__(
        self,
        shape: tuple[int, int],
        peaks: Sequence[Peak],
        *,
        window: str = "raised-cosine",
        radius: float | None = None,
        reference: str = "relative",
        unwrap: str = "auto",
        wavelength: float | None = None,
        aperture: np.ndarray | None = None,
        min_amplitude: float = 0.25,
        saturation: float | None = None,
        taper: float = DEFAULT_TAPER,
        threads: int | None = None,
    ) -> None:
        if len(shape) != 2 or min(int(shape[0]), int(shape[1])) < MIN_SIDE:
            raise InputError(f"frame shape must be (rows, cols), each >= {MIN_SIDE}; got {shape}")
        self.shape: tuple[int, int] = (int(shape[0]), int(shape[1]))
        self.peaks: tuple[Peak, ...] = _check_peaks(peaks)
        self.window = check_kind(window)
        if reference not in REFERENCE_MODES:
            raise InputError(
                f"unknown reference {reference!r}; choose one of {', '.join(REFERENCE_MODES)}"
            )
        if unwrap not in UNWRAP_MODES:
            raise InputError(
                f"unknown unwrap mode {unwrap!r}; choose one of {', '.join(UNWRAP_MODES)}"
            )
        if wavelength is not None and not (np.isfinite(wavelength) and wavelength > 0):
            raise InputError(f"wavelength must be > 0 metres, got {wavelength}")
        if not 0 <= min_amplitude < 1:
            raise InputError(f"min_amplitude must be in [0, 1), got {min_amplitude}")
        self.reference = reference
        self.unwrap = unwrap
        self.wavelength = wavelength
        self.min_amplitude = float(min_amplitude)
        self.saturation = saturation
        self.taper = float(taper)
        self.threads = int(threads) if threads else default_threads()
        carriers = np.array([p.carrier for p in self.peaks], dtype=np.float64)
        self.radius = float(
            auto_radius(carriers, min_radius=MIN_RADIUS_BINS / min(self.shape))
            if radius is None
            else radius
        )
        self._overlapping = self._check_radius(carriers)
        self.box_shape = box_shape_for(self.shape, self.radius)
        self._boxes = [
            box_geometry(
                self.shape,
                self.box_shape,
                carrier=(float(p.carrier[0]), float(p.carrier[1])),
                kind=window,
                radius=self.radius,
                taper=self.taper,
            )
            for p in self.peaks
        ]
        logger.debug(
            "demodulating %d peak(s) of %s frames: %s window, radius %.4g cycles/pixel, box %s",
            len(self.peaks),
            self.shape,
            window,
            self.radius,
            self.box_shape,
        )
        self.aperture: np.ndarray | None = None
        self._aperture_box: np.ndarray | None = None
        if aperture is not None:
            ap = np.array(aperture, dtype=bool)  # a copy: the caller's mask may change
            if ap.shape != self.shape:
                raise InputError(f"aperture mask has shape {ap.shape}, frames have {self.shape}")
            ap.setflags(write=False)
            self.aperture = ap
            self._aperture_box = resample_mask(ap, self.box_shape)
        n_box = self.box_shape[0] * self.box_shape[1]
        #: boxes of 256 x 256 bins or more are worth FFTW's threads; smaller ones are not
        self._box_threads = self.threads if n_box >= LARGE_BOX else 1
        self._angle_workspace = AngleWorkspace(self.box_shape)
        self._product = np.empty(self.box_shape, dtype=np.complex64)
        self._magnitude = np.empty(self.box_shape, dtype=np.float32)
        self._weights = np.empty(n_box, dtype=np.float32)
        self.reset_reference()

    def _check_radius(self, carriers: np.ndarray) -> set[int]:
        """Raise when a window holds another carrier or zero frequency; return overlapping peaks."""
        r = self.radius
        if not (np.isfinite(r) and r > 0):
            raise InputError(f"window radius must be > 0 cycles/pixel, got {r}")
        overlapping = set()
        n = len(carriers)
        for i in range(n):
            to_dc = float(np.hypot(*wrap_frequency(carriers[i])))
            if r >= to_dc:
                raise InputError(
                    f"window radius {r:.4g} cycles/pixel reaches zero frequency from "
                    f"{_names(self.peaks, i)} (|f| = {to_dc:.4g}); use a smaller radius"
                )
            for j in range(n):
                for sign, what in ((1, ""), (-1, "the twin of ")):
                    if j == i and sign == 1:
                        continue
                    d = float(np.hypot(*wrap_frequency(carriers[i] - sign * carriers[j])))
                    if r >= d:
                        raise InputError(
                            f"window radius {r:.4g} cycles/pixel is larger than the spacing "
                            f"{d:.4g} between {_names(self.peaks, i)} and "
                            f"{what}{_names(self.peaks, j)}; use a smaller radius"
                        )
                    if 2 * r > d:
                        overlapping.add(i)
        return overlapping

    # -- state -----------------------------------------------------------------------------

    def reset_reference(self) -> None:
        """Forget the reference frame and the running mean phases; the next frame starts over."""
        n = len(self.peaks)
        self._index = 0
        self._ref_conj: list[np.ndarray | None] = [None] * n
        self._prev_value: list[complex | None] = [None] * n
        self._ref_value: list[complex | None] = [None] * n
        self._unwrapped_mean = [0.0] * n

    def with_peaks(self, peaks: Sequence[Peak], **changes: object) -> Demodulator:
        """Return a demodulator for other peaks (and optionally other settings), same frames.

        Windows and FFT plans are cached by shape and parameters, so this is cheap
        when the GUI relabels or moves peaks. The radius is recomputed from the new
        carriers unless given in ``changes``; references start over.
        """
        settings: dict[str, object] = {
            "aperture": self.aperture,
            "window": self.window,
            "reference": self.reference,
            "unwrap": self.unwrap,
            "wavelength": self.wavelength,
            "min_amplitude": self.min_amplitude,
            "saturation": self.saturation,
            "taper": self.taper,
            "threads": self.threads,
        }
        settings.update(changes)
        return Demodulator(self.shape, peaks, **settings)  # type: ignore[arg-type]

    def area_fraction(self, i: int) -> float:
        """Return peak ``i``'s window area fraction ``sum |W|^2 / (rows cols)`` (DESIGN.md)."""
        return self._boxes[i].area_fraction

    def upsample(self, box_map: np.ndarray) -> np.ndarray:
        """Return a box-resolution map (field, unwrapped phase, delta-h) on the frame grid."""
        array = np.asarray(box_map)
        if array.shape != self.box_shape:
            raise InputError(
                f"map of shape {array.shape} is not at box resolution {self.box_shape}"
            )
        return upsample(array, self.shape)

    # -- processing ------------------------------------------------------------------------

    def _check(self, frame: np.ndarray) -> np.ndarray:
        array = np.asarray(frame)
        if array.ndim != 2:
            raise InputError(f"frame must be 2-D (rows, cols), got shape {array.shape}")
        if array.shape != self.shape:
            raise InputError(
                f"frame has shape {array.shape}; this demodulator expects {self.shape}"
            )
        if array.dtype.kind not in "uif":
            raise InputError(
                f"frame has dtype {array.dtype}: expected integer or real pixel values"
            )
        return array

    def _result(
        self, flags: set[str], mean: float, peaks: tuple[PeakResult, ...] = ()
    ) -> DemodResult:
        """This frame's result: ``peaks`` (none for a frame flagged unusable) and flags."""
        return DemodResult(
            index=self._index,
            reference=self.reference,
            mean_counts=mean,
            frame_shape=self.shape,
            box_shape=self.box_shape,
            radius=self.radius,
            peaks=peaks,
            flags=frozenset(flags),
        )

    def process(self, frame: np.ndarray) -> DemodResult:
        """Demodulate one frame (never modified) and advance the reference.

        Returns
        -------
        DemodResult
            A result with no peak results and the ``"nonfinite"`` flag for a frame
            holding NaN or infinity (the reference is then left as it was).

        Raises
        ------
        InputError
            For a frame of another shape, not 2-D, or not of real numbers.
        """
        array = self._check(frame)
        rows, cols = self.shape
        plan = rfft2_plan(self.shape, threads=self.threads)
        np.copyto(plan.input_array, array, casting="unsafe")
        plan.execute()
        half = plan.output_array
        dc = float(half[0, 0].real)
        if not np.isfinite(dc):
            return self._result({"nonfinite"}, float("nan"))
        mean = dc / (rows * cols)
        frame_flags: set[str] = set()
        if self.saturation is not None and (array[::4, ::4] >= self.saturation).any():
            frame_flags.add("saturated")
        flat = half.reshape(-1)
        box_plan = ifft2_plan(self.box_shape, threads=self._box_threads)
        partial = [self._demodulate(i, flat, box_plan, mean) for i in range(len(self.peaks))]
        if self.unwrap != "never":
            self._unwrap(partial)
        results = tuple(self._finish(i, part) for i, part in enumerate(partial))
        if all(not r.mask.any() for r in results):
            frame_flags.add("no_signal")
        if any("reference" in r.flags for r in results):
            frame_flags.add("reference")
        result = self._result(frame_flags, mean, results)
        self._index += 1
        return result

    def _demodulate(self, i: int, flat: np.ndarray, box_plan: pyfftw.FFTW, mean: float) -> _Partial:
        """Cut, window and invert peak ``i``'s box; phase against the reference (wrapped)."""
        peak = self.peaks[i]
        geo = self._boxes[i]
        box = box_plan.input_array.reshape(-1)
        np.take(flat, geo.index, out=box)
        pairs = box.view(np.float32)  # window and conjugation in one pass (BoxGeometry)
        np.multiply(pairs, geo.weights, out=pairs)
        box_plan.execute()
        field = box_plan.output_array.copy()
        flags: set[str] = set()
        if i in self._overlapping:
            flags.add("overlap")

        # trusted pixels
        magnitude = np.abs(field, out=self._magnitude)
        expected = peak.amplitude * mean if peak.amplitude > 0 else float(np.median(magnitude))
        mask = np.greater_equal(magnitude, np.float32(self.min_amplitude * expected))
        if not expected > 0:
            mask[...] = False
        if self._aperture_box is not None:
            mask &= self._aperture_box
        valid = int(np.count_nonzero(mask))
        if valid < MIN_VALID_FRACTION * mask.size:
            flags.add("low_amplitude")

        # mean phase: the field against the sub-bin plane wave, averaged
        value = complex(np.vdot(geo.ramp, field)) / field.size
        prev = self._prev_value[i]
        step = 0.0 if prev is None else cmath.phase(value * prev.conjugate())
        if abs(step) > PHASE_STEP_LIMIT:
            flags.add("phase_step")
        self._prev_value[i] = value

        product: np.ndarray | None = self._product
        if self.reference == "synthetic":
            np.multiply(field, geo.ramp_conj, out=product)
            if prev is None:
                self._unwrapped_mean[i] = cmath.phase(value)
            else:
                self._unwrapped_mean[i] += step
            mean_phase = cmath.phase(value)
        elif self._ref_conj[i] is None:
            flags.add("reference")
            self._ref_conj[i] = np.conj(field)
            self._ref_value[i] = value
            self._unwrapped_mean[i] = 0.0
            product = None
            mean_phase = 0.0
        else:
            ref_conj = self._ref_conj[i]
            np.multiply(field, ref_conj, out=product)
            self._unwrapped_mean[i] += step
            if self.reference == "relative":
                np.conjugate(field, out=ref_conj)
                mean_phase = step
            else:
                mean_phase = cmath.phase(value * self._ref_value[i].conjugate())
        if product is None:
            phase = np.zeros(field.shape, dtype=np.float32)
        else:
            phase = angle(product, workspace=self._angle_workspace)
        return _Partial(
            field=field,
            phase=phase,
            mask=mask,
            valid=valid,
            value=value,
            mean_phase=mean_phase,
            target=mean_phase if self.reference == "relative" else self._unwrapped_mean[i],
            flags=flags,
            live=product is not None,
        )

    def _guide_index(self, partial: list[_Partial]) -> int | None:
        """The peak whose map guides the others.

        Among peaks with trusted pixels: the one with a known alpha and the smallest
        ``|alpha| / amplitude`` (fewest wraps per unit of noise); with no alpha
        known, the brightest.
        """
        candidates = [i for i, part in enumerate(partial) if part.live and part.valid]
        with_alpha = [i for i in candidates if self.peaks[i].alpha is not None]
        if with_alpha:
            return min(
                with_alpha,
                key=lambda i: abs(self.peaks[i].alpha) / max(self.peaks[i].amplitude, 1e-30),  # type: ignore[arg-type]
            )
        if candidates:
            return max(candidates, key=lambda i: self.peaks[i].amplitude)
        return None

    def _unwrap(self, partial: list[_Partial]) -> None:
        """Unwrap the maps that need it: one in space, the others guided by it.

        The guide (:meth:`_guide_index`), when its map has wraps, is unwrapped in space
        (:func:`~holoview.processing.unwrap.unwrap_spatial`, Herraez et al. 2002, on a
        decimated map, see :meth:`_unwrap_in_space`). Every other wrapped map is then
        unwrapped against the guide scaled by the ratio of the two alphas
        (:func:`~holoview.processing.unwrap.unwrap_guided`), a few array passes
        instead of a spatial unwrap. When an alpha is unknown the ratio is measured
        from the two maps' gradients (:func:`~holoview.processing.unwrap.phase_ratio`),
        and a map still wrapped after that (another surface, or none) is unwrapped
        in space.
        """
        need = [p.live and (self.unwrap == "always" or has_wraps(p.phase, p.mask)) for p in partial]
        if not any(need):
            return
        guide = self._guide_index(partial)
        if guide is None:
            return  # no trusted pixel anywhere: nothing worth unwrapping
        g = partial[guide]
        if need[guide]:
            g.phase, g.unwrapped = self._unwrap_in_space(g.phase, g.mask)
        guide_alpha = self.peaks[guide].alpha
        for i, part in enumerate(partial):
            if not need[i] or i == guide or not part.valid:
                continue
            alpha = self.peaks[i].alpha
            if alpha is not None and guide_alpha is not None:
                part.phase = unwrap_guided(part.phase, g.phase * (alpha / guide_alpha), part.mask)
                part.unwrapped = True
                continue
            ratio = phase_ratio(part.phase, g.phase, part.mask & g.mask)
            guided = unwrap_guided(part.phase, g.phase * np.float32(ratio), part.mask)
            if _wrapped_inside(guided, part.mask):
                part.phase, part.unwrapped = self._unwrap_in_space(part.phase, part.mask)
            else:
                part.phase, part.unwrapped = guided, True

    def _unwrap_in_space(self, phase: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, bool]:
        """Herraez on a decimated map (coarse grid of 64 pixels or more), finer if that fails.

        A map still wrapped after the coarse pass (away from the box's edge, where a
        non-periodic frame leaves the field unreliable) moved more than pi between
        coarse samples somewhere: it is done again on a twice finer grid, down to
        every pixel.
        """
        decimate = max(1, min(self.box_shape) // 64)
        while True:
            unwrapped, changed = unwrap_spatial(phase, mask, decimate=decimate)
            if decimate == 1 or not _wrapped_inside(unwrapped, mask):
                return unwrapped, changed
            decimate //= 2

    def _finish(self, i: int, part: _Partial) -> PeakResult:
        """Set the map's 2 pi offset, estimate the noise, convert to height."""
        peak = self.peaks[i]
        phase = part.phase
        if part.live and part.valid:
            # put the map's 2 pi offset where the time-unwrapped mean phase says
            if part.valid == phase.size:
                level = float(np.mean(phase))
            else:
                weights = self._weights
                np.copyto(weights, part.mask.reshape(-1))
                level = float(np.dot(phase.reshape(-1), weights)) / part.valid
            offset = TWO_PI * round((part.target - level) / TWO_PI)
            if offset:
                phase += np.float32(offset)
        noise = self._noise(phase, part.mask, self._boxes[i]) if part.live else 0.0
        to_height = None
        if peak.alpha is not None and self.wavelength is not None:
            to_height = self.wavelength / (4 * np.pi * peak.alpha)
        return PeakResult(
            peak=peak,
            field=part.field,
            phase=phase,
            delta_h=None if to_height is None else phase * np.float32(to_height),
            carrier_value=part.value,
            mean_phase=part.mean_phase,
            mean_phase_unwrapped=float(self._unwrapped_mean[i]),
            mask=part.mask,
            noise=noise,
            noise_height=None if to_height is None else abs(noise * to_height),
            unwrapped=part.unwrapped,
            flags=frozenset(part.flags),
        )

    @staticmethod
    def _noise(phase: np.ndarray, mask: np.ndarray, geo: BoxGeometry) -> float:
        """Phase noise (rad) from the spread of second differences along every 4th or 8th row.

        Second differences cancel the surface's slope; for noise shaped by the
        window they have variance ``sigma^2 (6 - 8 rho1 + 2 rho2)``, with ``rho1``
        and ``rho2`` the window's noise correlation at lags 1 and 2. Surface
        curvature adds to it, so the estimate errs on the high side. Differences
        beyond pi (wraps, untrusted pixels) are left out, and so are two pixels at
        the box's edge: where the frame is not periodic the field dips there and
        its phase is noisier than the rest.
        """
        edge = 2 if min(phase.shape) > 16 else 0  # a non-periodic frame's field dips at the edge
        every = 8 if phase.shape[0] >= 128 else 4  # thousands of differences are plenty
        rows = phase[edge : phase.shape[0] - edge : every, edge : phase.shape[1] - edge]
        trusted = mask[edge : phase.shape[0] - edge : every, edge : phase.shape[1] - edge]
        second = rows[:, 2:] - 2 * rows[:, 1:-1] + rows[:, :-2]
        keep = trusted[:, 2:] & trusted[:, 1:-1] & trusted[:, :-2]
        keep &= np.abs(second) < np.pi
        count = int(np.count_nonzero(keep))
        if count < 2:
            return float("nan")
        second *= keep
        variance = float(np.vdot(second, second)) / count
        return float(np.sqrt(variance / geo.noise_gain))


def refine_carriers(
    frame: np.ndarray,
    peaks: Sequence[Peak],
    *,
    radius: float | None = None,
    window: str = "raised-cosine",
    iterations: int = 2,
) -> list[Peak]:
    """Return the peaks with carriers moved to the mean phase gradient of their fields.

    :func:`~holoview.processing.peaks.find_peaks` places a carrier within about 0.02
    FFT bins, which leaves a synthetic-reference map a tilt of up to
    ``2 pi 0.02`` rad across the frame. Here each peak is demodulated against its
    sub-bin plane wave and the carrier moved by the residual phase gradient,
    measured as the amplitude-weighted mean phase of neighbour products (Kay's
    frequency estimator, in two dimensions), away from the box's edge.

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        A hologram (counts); not modified.
    peaks : sequence of Peak
        Peaks with approximate carriers; labels, alphas and flags are kept.
    radius : float, optional
        Window radius (cycles/pixel); by default from the carriers.
    window : str
        Window kind.
    iterations : int
        Demodulate-and-move rounds (>= 1).

    Returns
    -------
    list of Peak
        The same peaks with refined carriers (cycles/pixel).
    """
    if iterations < 1:
        raise InputError(f"iterations must be >= 1, got {iterations}")
    array = np.asarray(frame)
    current = list(peaks)
    for _ in range(iterations):
        demod = Demodulator(
            array.shape,
            current,
            window=window,
            radius=radius,
            reference="synthetic",
            unwrap="never",
        )
        result = demod.process(array)
        if "nonfinite" in result.flags:
            raise InputError("frame holds NaN or infinite pixels")
        (by, bx), (rows, cols) = demod.box_shape, demod.shape
        moved = []
        for peak, geo, r in zip(current, demod._boxes, result.peaks, strict=True):
            residual = (r.field * geo.ramp_conj)[2:-2, 2:-2]
            along_x = np.vdot(residual[:, :-1], residual[:, 1:])
            along_y = np.vdot(residual[:-1, :], residual[1:, :])
            fx = peak.carrier[0] + cmath.phase(along_x) / TWO_PI * bx / cols
            fy = peak.carrier[1] + cmath.phase(along_y) / TWO_PI * by / rows
            moved.append(dataclasses.replace(peak, carrier=(float(fx), float(fy))))
        current = moved
    return current
