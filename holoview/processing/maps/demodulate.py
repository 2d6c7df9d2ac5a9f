"""Fourier demodulation of every labelled carrier, frame after frame (paper section 3).

:class:`Demodulator` takes a real FFT of each frame (pyFFTW, planned once per
shape), along the columns only where its boxes and the noise floor read the spectrum
(:class:`~holoview.processing.fourier.half_spectrum.HalfSpectrum`), and per peak cuts a
small box out of the half spectrum with the carrier moved to the origin and the window
applied (:func:`~holoview.processing.fourier.boxes.cut_box`), then takes an inverse FFT
of the box only. The complex field per peak therefore comes at the box resolution
(pixel ``(p, q)`` at frame position ``(p rows / by, q cols / bx)``);
:meth:`Demodulator.upsample` brings any map to the frame grid. With ``grid="frame"``
the box is the frame's size: the windowed sideband, zero beyond the window, is
inverted in a frame-sized array, which gives the field on the camera's pixels (the
band-limited interpolation of the box's field, what a plain Fourier filter gives), and
every later step (trusted pixels, phases, unwrapping) runs on that grid.

Where the time goes: ``benchmarks/bench_demodulation.py --floor``.

Conventions (docs/design.md):

- the field is in counts: ``|field| = Y0 A`` for a fringe term ``Y0 A exp(i phi)``,
  demodulated at the FFT bin nearest the carrier (a residual sub-bin tilt remains
  in it; the synthetic reference removes it);
- phases are ``current - reference`` in rad: ``synthetic`` against the plane wave
  at the sub-bin carrier, ``absolute`` against the first frame after construction
  or :meth:`~Demodulator.reset_reference` (or against an object-free background
  hologram, :meth:`~Demodulator.set_background`), ``relative`` against the previous
  frame;
- ``delta_h = phase wavelength / (4 pi alpha)`` in metres for peaks with alpha.

Per peak and frame also: the trusted pixels (aperture, amplitude, off the border that
the periodic FFT spoils: :func:`~holoview.processing.fourier.boxes.border_mask`), the phase
noise (rad, and m, from the spectrum's noise floor), and the complex value at the
carrier alone, whose phase is the spatially averaged phase (paper section 4.2),
unwrapped in time. Maps that wrap are unwrapped in space (Herraez et al. 2002) or
against another peak's map scaled by the ratio of alphas
(:func:`~holoview.processing.maps.phase_maps.unwrap_maps`). Every returned array is new;
frames and peaks are never modified. Carriers below one FFT bin:
:func:`holoview.processing.peaks.detection.refine_carriers`.

Where the steps are: the per-peak step of every frame (box, trusted pixels, phase,
noise, result) in :mod:`~holoview.processing.maps.box_maps`; what each peak's phases are
taken against (reference fields, background, mean phases) in
:mod:`~holoview.processing.maps.references`; unwrapping and noise in
:mod:`~holoview.processing.maps.phase_maps`.

The demodulator keeps state (references, plans, buffers): use it from one thread
at a time. It creates no thread; FFTW may use ``threads`` internally.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

import numpy as np

from holoview.errors import InputError
from holoview.processing.fourier.boxes import (
    BoxGeometry,
    border_mask,
    box_geometry,
    box_shape_for,
)
from holoview.processing.fourier.fastmath import AngleWorkspace
from holoview.processing.fourier.fftplans import DEFAULT_THREADS, ifft2_plan
from holoview.processing.fourier.frames import MIN_SIDE
from holoview.processing.fourier.half_spectrum import HalfSpectrum
from holoview.processing.fourier.resample import resample_mask, upsample
from holoview.processing.fourier.windows import DEFAULT_TAPER, DEFAULT_WINDOW, check_kind
from holoview.processing.maps.box_maps import PeakBox, invert_box, peak_result, phase_map
from holoview.processing.maps.demod_results import (
    MAP_GRIDS,
    REFERENCE_MODES,
    UNWRAP_MODES,
    DemodResult,
    PeakResult,
)
from holoview.processing.maps.mean_phases import MeanPhaseState
from holoview.processing.maps.phase_maps import (
    PhaseMap,
    floor_grid,
    unwrap_maps,
)
from holoview.processing.maps.references import PhaseReferences
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.matched import Window
from holoview.processing.peaks.radii import (
    check_peaks,
    check_radii,
    distinct_neighbours,
    fallback_notes,
    peak_windows,
    radius_rule,
)
from holoview.processing.peaks.surface_spectrum import SurfaceSpectrum

logger = logging.getLogger(__name__)

__all__ = ["Demodulator"]

#: Box size (bins) from which a box's inverse FFT uses the frame FFT's threads.
LARGE_BOX = 256 * 256


class Demodulator:
    """Demodulate a fixed list of peaks from frame after frame of one shape.

    Parameters
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)`` in pixels.
    peaks : sequence of Peak
        The carriers to demodulate (not empty, inside the spectrum).
    window : {"tukey", "raised-cosine", "top-hat"}
        Spectral window (:mod:`holoview.processing.fourier.windows`); by default
        :data:`~holoview.processing.fourier.windows.DEFAULT_WINDOW`, chosen by measurement.
    radius : float, "matched", "bound" or None
        Window radius: a number (cycles/pixel) for every peak; ``"bound"``: each
        peak's own, the widest that reaches no other peak, twin or zero frequency
        (:func:`~holoview.processing.fourier.windows.auto_radii`); ``"matched"`` or None
        (the default): each peak's radius of least expected map error measured on
        ``spectrum``, never past the bound (the bound without a spectrum); see
        :func:`~holoview.processing.peaks.radii.peak_windows`. A given radius that
        reaches another peak is used, with a warning in :attr:`notes`.
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
        FFTW threads for the frame's FFT; by default
        :data:`~holoview.processing.fourier.fftplans.DEFAULT_THREADS` (one: see there why).
    neighbours : sequence of (fx, fy)
        Other peaks of the spectrum (cycles/pixel), not demodulated, which the
        automatic radii must not reach either: for example every detected peak (those
        within a few bins of a carrier or its twin are that peak and are dropped,
        :func:`~holoview.processing.peaks.radii.distinct_neighbours`).
    background : ndarray, optional
        An object-free hologram of shape ``shape`` (counts): with ``reference=
        "absolute"`` every frame's phase is taken against it instead of against
        the first frame (:meth:`set_background`).
    spectrum : SurfaceSpectrum, optional
        A frame's spectrum (:func:`~holoview.processing.peaks.surface_spectrum.measure_spectrum`)
        the matched radii are measured on.
    windows : sequence of Window, optional
        Each peak's window, decided elsewhere (the same as another demodulator's);
        ``radius``, ``window``, ``taper`` and ``spectrum`` are then not used.
    grid : {"box", "frame"}
        Where the maps are: ``"box"`` (the default), the demodulation box's grid, the
        smallest that holds the widest window; ``"frame"``, the frame's pixels (module
        documentation: more time and memory a frame, the same information).

    Raises
    ------
    InputError
        For a bad shape, an empty peak list, a carrier outside the spectrum, an
        unknown mode, a radius so large that a window holds zero frequency, or a
        background of another shape or mode.

    Examples
    --------
    >>> import numpy as np
    >>> from holoview.processing.peaks.detection import Peak
    >>> y, x = np.mgrid[:256, :256]
    >>> frame = 1000 + 300 * np.cos(2 * np.pi * (0.25 * x + 0.125 * y))
    >>> demod = Demodulator(frame.shape, [Peak((0.25, 0.125), 0.15, 100.0, label="RB1")])
    >>> result = demod.process(frame)
    >>> round(abs(result.peaks[0].carrier_value))
    150
    """

    def __init__(
        self,
        shape: tuple[int, int],
        peaks: Sequence[Peak],
        *,
        window: str = DEFAULT_WINDOW,
        radius: float | str | None = None,
        reference: str = "relative",
        unwrap: str = "auto",
        wavelength: float | None = None,
        aperture: np.ndarray | None = None,
        min_amplitude: float = 0.25,
        saturation: float | None = None,
        taper: float = DEFAULT_TAPER,
        threads: int | None = None,
        neighbours: Sequence[tuple[float, float]] = (),
        background: np.ndarray | None = None,
        spectrum: SurfaceSpectrum | None = None,
        windows: Sequence[Window] | None = None,
        grid: str = "box",
    ) -> None:
        if len(shape) != 2 or min(int(shape[0]), int(shape[1])) < MIN_SIDE:
            raise InputError(f"frame shape must be (rows, cols), each >= {MIN_SIDE}; got {shape}")
        self.shape: tuple[int, int] = (int(shape[0]), int(shape[1]))
        self.peaks: tuple[Peak, ...] = check_peaks(peaks)
        self.window = check_kind(window)
        if reference not in REFERENCE_MODES:
            raise InputError(
                f"unknown reference {reference!r}; choose one of {', '.join(REFERENCE_MODES)}"
            )
        if unwrap not in UNWRAP_MODES:
            raise InputError(
                f"unknown unwrap mode {unwrap!r}; choose one of {', '.join(UNWRAP_MODES)}"
            )
        if grid not in MAP_GRIDS:
            raise InputError(f"unknown map grid {grid!r}; choose one of {', '.join(MAP_GRIDS)}")
        #: where the maps are (``"box"`` or ``"frame"``)
        self.grid = grid
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
        self.threads = int(threads) if threads else DEFAULT_THREADS
        carriers = np.array([p.carrier for p in self.peaks], dtype=np.float64)
        others = distinct_neighbours(self.shape, carriers, neighbours)
        #: the neighbouring peaks given (cycles/pixel), kept for :meth:`with_peaks`
        self.neighbours: tuple[tuple[float, float], ...] = tuple(
            (float(fx), float(fy)) for fx, fy in neighbours
        )
        self.spectrum = spectrum
        if windows is None:
            windows = peak_windows(
                self.shape,
                carriers,
                radius,
                others,
                kind=self.window,
                taper=self.taper,
                spectrum=spectrum,
            )
        elif len(windows) != len(self.peaks):
            raise InputError(f"{len(windows)} windows for {len(self.peaks)} peaks")
        #: each peak's window: radius, shape and why
        self.windows: tuple[Window, ...] = tuple(windows)
        #: each peak's window radius, cycles/pixel
        self.radii = tuple(w.radius for w in self.windows)
        self._overlapping, warnings = check_radii(self.peaks, self.radii, others)
        fallbacks = (
            fallback_notes(self.peaks, self.windows) if radius_rule(radius) == "matched" else ()
        )
        #: what the user should know about the windows: a given radius reaching a peak,
        #: a matched window at the bound for want of measurable surface power
        self.notes: tuple[str, ...] = warnings + fallbacks
        for line in warnings:
            logger.warning("%s", line)
        #: the largest window radius (cycles/pixel): it sets the box shape
        self.radius = max(self.radii)
        #: the maps' shape: the box's, or the frame's with ``grid="frame"``
        self.box_shape = self.shape if grid == "frame" else box_shape_for(self.shape, self.radius)
        self._boxes = [
            box_geometry(
                self.shape,
                self.box_shape,
                carrier=(float(p.carrier[0]), float(p.carrier[1])),
                kind=w.kind,
                radius=w.radius,
                taper=w.taper,
            )
            for p, w in zip(self.peaks, self.windows, strict=True)
        ]
        logger.debug(
            "demodulating %d peak(s) of %s frames: %s window, radii %s cycles/pixel (%s), box %s",
            len(self.peaks),
            self.shape,
            window,
            ", ".join(f"{r:.4g}" for r in self.radii),
            ", ".join(w.rule for w in self.windows),
            self.box_shape,
        )
        self.aperture: np.ndarray | None = None
        aperture_box = np.ones(self.box_shape, dtype=bool)
        if aperture is not None:
            ap = np.array(aperture, dtype=bool)  # a copy: the caller's mask may change
            if ap.shape != self.shape:
                raise InputError(f"aperture mask has shape {ap.shape}, frames have {self.shape}")
            ap.setflags(write=False)
            self.aperture = ap
            aperture_box = resample_mask(ap, self.box_shape)
        #: per peak, the box pixels that may be trusted: inside the aperture, off the border
        self._trusted_box = [
            aperture_box & border_mask(self.box_shape, self.shape, r) for r in self.radii
        ]
        #: per peak, what its step of every frame takes (:func:`phase_map`)
        self._peak_boxes = [
            PeakBox(
                index=i,
                geometry=self._boxes[i],
                trusted=trusted,
                trustable=int(np.count_nonzero(trusted)),
                amplitude=self.peaks[i].amplitude,
                overlapping=i in self._overlapping,
                frame_size=self.shape[0] * self.shape[1],
            )
            for i, trusted in enumerate(self._trusted_box)
        ]
        #: the frame's FFT, along columns only where the boxes and the noise floor read it
        self._half_spectrum = HalfSpectrum(
            self.shape,
            [geo.columns for geo in self._boxes],
            *floor_grid(self.shape),
            threads=self.threads,
        )
        n_box = self.box_shape[0] * self.box_shape[1]
        #: boxes of 256 x 256 bins or more are worth FFTW's threads; smaller ones are not
        self._box_threads = self.threads if n_box >= LARGE_BOX else 1
        self._angle_workspace = AngleWorkspace(self.box_shape)
        self.background: np.ndarray | None = None
        #: every peak's reference field, the reference's floor samples, the mean phases
        self._references = PhaseReferences(len(self.peaks), reference)
        self.set_background(background)

    # -- state -----------------------------------------------------------------------------

    def reset_reference(self) -> None:
        """Forget the reference frame and the running mean phases; the next frame starts over.

        With a background hologram (:meth:`set_background`) the reference stays the
        background: the next frame is taken against it.
        """
        self._index = 0
        self._references.reset()

    def break_sequence(self) -> None:
        """Forget the previous frame: the next one does not follow it (a replay jumped).

        Relative maps start over (the next frame is a reference frame: no map pairs
        frames from before and after the jump); an absolute reference, or a background
        hologram, is kept; the mean phase is not unwrapped in time across the break
        (the next frame's is taken as it is, against the reference), and no phase step
        is measured over it.
        """
        self._references.break_sequence()

    def set_background(
        self, background: np.ndarray | None, values: Sequence[complex] | np.ndarray | None = None
    ) -> None:
        """Take absolute phases against an object-free hologram from the next frame on.

        Parameters
        ----------
        background : ndarray or None
            A hologram of the demodulator's shape (counts; not modified), recorded
            without the object (or before the change to measure); None returns to
            taking the first frame after :meth:`reset_reference` as the reference.
        values : sequence of complex, optional
            Each peak's carrier value in the background measured elsewhere (counts), as
            :meth:`process` takes them: give them when the frames' values are given.

        Raises
        ------
        InputError
            For a background with another reference mode than ``"absolute"``, of
            another shape, not 2-D, not real, or holding NaN or infinity.
        """
        if background is None:
            self.background = None
            self._references.set_background(None, None)
            self._index = 0
            return
        if self.reference != "absolute":
            raise InputError(
                "a background hologram is the reference of absolute phases: use "
                f"reference='absolute', not {self.reference!r}"
            )
        array = np.array(self._check(background, "background hologram"))  # a copy
        half, mean, floor = self._half_spectrum.transform(array)
        if half is None:
            raise InputError("the background hologram holds NaN or infinite pixels")
        box_plan = ifft2_plan(self.box_shape, threads=self._box_threads)
        given = self._given(values)
        kept = []
        for i, geo in enumerate(self._boxes):
            field = invert_box(half, self._boxes[i], box_plan)
            value = complex(np.vdot(geo.ramp, field)) / field.size if given is None else given[i]
            kept.append((np.conj(field), value))
        array.setflags(write=False)
        self.background = array
        self._references.set_background(kept, floor)
        self._index = 0
        logger.debug("background hologram set: mean %.4g counts", mean)

    def with_peaks(self, peaks: Sequence[Peak], **changes: object) -> Demodulator:
        """Return a demodulator for other peaks (and optionally other settings), same frames.

        Windows and FFT plans are cached by shape and parameters, so this is cheap
        when the GUI relabels or moves peaks. The radii are recomputed from the new
        carriers (and the same spectrum) unless given in ``changes``; references start
        over (against the background hologram, when there is one and the reference
        stays absolute).
        """
        settings: dict[str, Any] = {  # Demodulator's keywords, checked where it is made
            "spectrum": self.spectrum,
            "aperture": self.aperture,
            "window": self.window,
            "reference": self.reference,
            "unwrap": self.unwrap,
            "wavelength": self.wavelength,
            "min_amplitude": self.min_amplitude,
            "saturation": self.saturation,
            "taper": self.taper,
            "threads": self.threads,
            "neighbours": self.neighbours,
            "background": self.background,
            "grid": self.grid,
        }
        settings.update(changes)
        if settings["reference"] != "absolute" and "background" not in changes:
            settings["background"] = None
        return Demodulator(self.shape, peaks, **settings)

    def reference_field(self, i: int) -> np.ndarray | None:
        """Return peak ``i``'s reference field (counts, box resolution), or None before one.

        The background hologram's (:meth:`set_background`) or the reference frame's in
        absolute mode, the previous frame's in relative mode; None in synthetic mode.
        """
        return self._references.field(i)

    def geometry(self, i: int) -> BoxGeometry:
        """Return peak ``i``'s box geometry: spectrum indices, window, sub-bin plane wave."""
        return self._boxes[i]

    def area_fraction(self, i: int) -> float:
        """Return peak ``i``'s window area fraction ``sum |W|^2 / (rows cols)`` (docs/design.md)."""
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

    def _check(self, frame: np.ndarray, what: str = "frame") -> np.ndarray:
        array = np.asarray(frame)
        if array.ndim != 2:
            raise InputError(f"{what} must be 2-D (rows, cols), got shape {array.shape}")
        if array.shape != self.shape:
            raise InputError(
                f"{what} has shape {array.shape}; this demodulator expects {self.shape}"
            )
        if array.dtype.kind not in "uif":
            raise InputError(
                f"{what} has dtype {array.dtype}: expected integer or real pixel values"
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

    def _given(self, values: Sequence[complex] | np.ndarray | None) -> list[complex] | None:
        """``values`` as one complex per peak (InputError for another count), or None."""
        if values is None:
            return None
        given = [complex(v) for v in values]
        if len(given) != len(self.peaks):
            raise InputError(f"{len(given)} carrier values given for {len(self.peaks)} peaks")
        return given

    def phase_state(self) -> MeanPhaseState:
        """The mean phases' running state (:mod:`~holoview.processing.maps.mean_phases`)."""
        return self._references.state()

    def restore_phase_state(self, state: MeanPhaseState) -> None:
        """Resume the mean phases from ``state``: that of a demodulator given the same frames.

        The reference fields are not part of it: a demodulator resuming a run from its
        middle first demodulates the run's reference frame (absolute mode) or the frame
        before (relative mode), then restores the state the whole run would have.
        """
        self._references.restore(state)

    def process(
        self, frame: np.ndarray, values: Sequence[complex] | np.ndarray | None = None
    ) -> DemodResult:
        """Demodulate one frame (never modified) and advance the reference.

        Parameters
        ----------
        frame : ndarray, shape ``shape``
            The hologram, counts.
        values : sequence of complex, optional
            Each peak's carrier value of this frame measured elsewhere (counts; the
            carrier probe's, :mod:`holoview.processing.series.carrier_probe`): its mean
            phase, steps and unwrapping in time then follow them instead of the box's
            own mean (:attr:`~holoview.processing.maps.demod_results.PeakResult.carrier_value`
            is the value given).

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
        half, mean, samples = self._half_spectrum.transform(array)
        if half is None:
            return self._result({"nonfinite"}, mean)
        frame_flags: set[str] = set()
        if self.saturation is not None and (array[::4, ::4] >= self.saturation).any():
            frame_flags.add("saturated")
        floor = self._references.floor(samples)
        box_plan = ifft2_plan(self.box_shape, threads=self._box_threads)
        given = self._given(values)
        partial = [
            phase_map(
                half,
                box,
                box_plan,
                self._references,
                mean=mean,
                floor=floor,
                value=None if given is None else given[i],
                min_amplitude=self.min_amplitude,
                check_wraps=self.unwrap == "auto",
                workspace=self._angle_workspace,
            )
            for i, box in enumerate(self._peak_boxes)
        ]
        if self.unwrap != "never":
            unwrap_maps(partial, self.peaks, always=self.unwrap == "always")
        results = tuple(self._finish(i, part) for i, part in enumerate(partial))
        if all(not r.mask.any() for r in results):
            frame_flags.add("no_signal")
        if any("reference" in r.flags for r in results):
            frame_flags.add("reference")
        result = self._result(frame_flags, mean, results)
        self._index += 1
        return result

    def _finish(self, i: int, part: PhaseMap) -> PeakResult:
        """Set the map's 2 pi offset, estimate the noise, convert to height."""
        return peak_result(
            part,
            self.peaks[i],
            radius=self.radii[i],
            cut=self.windows[i].cut,
            wavelength=self.wavelength,
            mean_phase_unwrapped=self._references.unwrapped(i),
            workspace=self._angle_workspace,
        )
