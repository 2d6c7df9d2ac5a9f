"""The wave analyses of one label's maps, streamed from a ``results.h5`` in a few passes.

:func:`analyse_waves` reads the maps a block at a time (:mod:`~holoview.headless.waves.maps`)
and runs the Qt-free analyses of :mod:`holoview.processing.waves`, so memory stays
bounded whatever the number of frames (a segment's maps, and at most
:data:`KEPT_SAMPLES_BYTES` of the rings' samples):

1. every frame into the omega-k accumulator (and, with a drive frequency, the lock-in
   maps); then E(k), E(omega) and the fit of sigma, d and U to the ridge;
2. with a centre (given, or ``auto``: found on the lock-in map at the drive frequency,
   made in pass 1, or else at the strongest peak of E(omega), within the ringdown's
   band when one is asked for, one more pass): every
   frame into the azimuthal accumulator, which gives the (m, f) spectrum, lock-ins of
   every ``m`` at a comb of frequencies around each candidate tone (the strongest peaks
   of E(omega), the drive's harmonics, or the modes asked for) and the series of the
   ringdown's ``m``; then per chosen (m, f) the tone's frequency and radial profile
   (:func:`refine_tone`) and its Hankel fit, and the ringdown fit. A chosen (m, f) that
   no candidate's comb holds takes lock-ins on a comb of its own, from the rings'
   samples kept in this pass (or, past their budget, one more pass).

Times are from the first frame analysed (phases of complex amplitudes refer to it).
Every fit that fails raises :class:`~holoview.errors.InputError` with the reason, but
the dispersion fit: without it the spectra and the other analyses still stand, so its
reason is kept (:attr:`WaveResults.fit_problem`, a note) for the caller to say.
"""

from __future__ import annotations

import logging
import math
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from holoview.errors import InputError
from holoview.headless.waves.maps import WaveMaps
from holoview.headless.waves.modes import comb_around, mode_lock_ins
from holoview.headless.waves.tones import PROMINENCE, check_steady, find_tones, tone_energy
from holoview.optics.surfaces import dispersion_k
from holoview.processing.waves.azimuthal import (
    AzimuthalAccumulator,
    MFSpectrum,
    PolarGrid,
    polar_grid,
)
from holoview.processing.waves.centre import CENTRE_SEGMENTS, centre_stderr, find_centre
from holoview.processing.waves.dispersion import (
    DispersionFit,
    Fluid,
    check_fit_settings,
    fit_dispersion,
)
from holoview.processing.waves.filters import Band, block_for
from holoview.processing.waves.lockin import LockIn, LockInMaps, push_lockins
from holoview.processing.waves.omega_k import OmegaKAccumulator, OmegaKSpectrum
from holoview.processing.waves.partial_waves import PartialWaveFit, fit_partial_wave, refine_tone
from holoview.processing.waves.ringdown import Ringdown, fit_ringdown

logger = logging.getLogger(__name__)

__all__ = ["WaveOptions", "WaveResults", "analyse_waves"]

#: Candidate tones taken from E(omega) when no mode is asked for.
CANDIDATE_TONES = 6

#: The (m, f) spectrum's segment is an eighth of the longest run without a gap (a power of
#: two), at least ``--segment`` and at most this many frames: tones that a long record
#: parts are then parted in it too (segments of 128 frames at 100 frames/s blend tones
#: 1.2 Hz apart however long the record, and their one blended peak was fitted as neither).
MF_SEGMENT_MAX = 2048

#: Pass 2's ring samples are kept for the lock-ins of modes that no candidate's comb holds
#: where they take at most this many bytes (2000 frames of rings 5-38 mm at 0.32 mm, with
#: |m| <= 8: 28 MB); past it, those lock-ins take one more pass over the maps.
KEPT_SAMPLES_BYTES = 128 * 2**20


@dataclass(frozen=True)
class WaveOptions:
    """What to analyse and how (SI units).

    Attributes
    ----------
    fluid : Fluid
        Density, gravity, and the starting surface tension.
    depth : float
        Starting (or held) depth, m.
    flow : (float, float)
        Starting (or held) flow, m/s.
    hold : tuple of str
        Parameters of the dispersion fit held (``sigma``, ``depth``, ``flow``).
    fit : bool
        Fit the dispersion relation.
    segment : int
        Frames per segment of the spectra.
    k_range : (float or None, float or None)
        Wavenumbers of the dispersion fit, rad/m.
    centre : (float, float), "auto" or None
        Centre of the azimuthal analyses (map coordinates, m), or found, or none.
    m_max : int
        Largest ``|m|``.
    r_range : (float or None, float or None)
        Ring radii, m.
    modes : tuple of (int, float)
        (m, f in Hz) partial waves to fit (default: the strongest of the (m, f) spectrum).
    n_modes : int
        How many of the strongest (m, f) peaks to fit when ``modes`` is empty.
    drive : float or None
        Drive frequency, Hz (lock-in maps at its harmonics).
    harmonics : int
        Harmonics of the drive.
    ringdown : (int, float, float) or None
        ``(m, f1, f2)``: the band of a damped mode.
    ringdown_start : float or None
        Start of the ringdown fit, s (from the first frame analysed).
    band : Band or None
        A band filter whose output is written.
    block : int
        Frames read at a time.
    workers : int
        FFT threads.
    """

    fluid: Fluid = field(default_factory=Fluid)
    depth: float = 5e-3
    flow: tuple[float, float] = (0.0, 0.0)
    hold: tuple[str, ...] = ()
    fit: bool = True
    segment: int = 128
    k_range: tuple[float | None, float | None] = (None, None)
    centre: tuple[float, float] | str | None = None
    m_max: int = 8
    r_range: tuple[float | None, float | None] = (None, None)
    modes: tuple[tuple[int, float], ...] = ()
    n_modes: int = 4
    drive: float | None = None
    harmonics: int = 3
    ringdown: tuple[int, float, float] | None = None
    ringdown_start: float | None = None
    band: Band | None = None
    block: int = 64
    workers: int = 1

    @property
    def azimuthal(self) -> bool:
        """True when a centre is given or asked for."""
        return self.centre is not None

    @property
    def fit_alone(self) -> bool:
        """True when the dispersion fit is the one analysis asked for (no centre, drive
        or band filter): its failure is then the command's."""
        return self.fit and self.centre is None and self.drive is None and self.band is None

    @property
    def drive_harmonics(self) -> list[float]:
        """The drive's harmonics, Hz (none without a drive): candidate tones whose frequency
        is exact."""
        if self.drive is None:
            return []
        return [self.drive * n for n in range(1, self.harmonics + 1)]


@dataclass
class WaveResults:
    """What :func:`analyse_waves` found (the writers turn it into files and figures)."""

    maps: WaveMaps
    options: WaveOptions
    spectrum: OmegaKSpectrum
    dispersion: DispersionFit | None = None
    lockin: LockInMaps | None = None
    centre_lockins: list[LockInMaps] = field(default_factory=list)
    centre: tuple[float, float] | None = None
    centre_stderr: tuple[float, float] = (0.0, 0.0)
    centre_method: str = ""
    grid: PolarGrid | None = None
    mf: MFSpectrum | None = None
    tones: list[tuple[int, float, np.ndarray]] = field(default_factory=list)
    partial_waves: list[PartialWaveFit] = field(default_factory=list)
    ringdown: Ringdown | None = None
    #: Why the dispersion fit asked for was not made (None: made, or not asked for).
    fit_problem: str | None = None
    notes: list[str] = field(default_factory=list)
    timing: dict[str, float] = field(default_factory=dict)

    def wavenumber(self, frequency: float) -> float:
        """Wavenumber (rad/m) at ``frequency`` (Hz) by the fitted (else the given) fluid."""
        fluid = self.options.fluid
        sigma, depth = fluid.surface_tension, self.options.depth
        if self.dispersion is not None:
            sigma, depth = self.dispersion.surface_tension, self.dispersion.depth
        return dispersion_k(2 * math.pi * frequency, depth, fluid.gravity, sigma, fluid.density)


def _span(maps: WaveMaps) -> tuple[float, float]:
    return 0.0, float(maps.clock.times[-1])


def _hann_weights(times: np.ndarray, span: tuple[float, float]) -> np.ndarray:
    phase = (times - span[0]) / (span[1] - span[0])
    return np.sin(np.pi * np.clip(phase, 0.0, 1.0)) ** 2


def _check_frames(maps: WaveMaps, segment: int) -> None:
    longest = max(b - a for a, b in maps.clock.runs)
    if longest < segment:
        gaps = f" (its longest run without a gap has {longest})" if maps.clock.gaps else ""
        raise InputError(
            f"{maps.path}: maps/{maps.label} have {maps.frames} frames{gaps}, fewer than a "
            f"segment of {segment}; give a shorter --segment"
        )


def _pass_spectrum(maps: WaveMaps, options: WaveOptions, results: WaveResults) -> None:
    """Pass 1: the omega-k spectrum and the drive's lock-in maps; E and the fit."""
    started = time.perf_counter()
    omega_k = OmegaKAccumulator(
        maps.shape,
        maps.pixel_size,
        maps.clock.interval,
        segment=options.segment,
        k_cut=maps.k_cut,
        workers=options.workers,
    )
    lockins: list[LockIn] = []
    if options.drive is not None:
        lockins.append(
            LockIn(
                maps.shape,
                options.drive,
                tuple(range(1, options.harmonics + 1)),
                span=_span(maps),
            )
        )
        if options.centre == "auto":  # the centre is found at the drive
            lockins.extend(_centre_lockins(maps, options.drive))
    finite = 0
    # With two threads or more the omega-k segments of a block are worked on beside the
    # lock-ins and the reading of the next block (each accumulator in order, as alone).
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="omega-k") as pool:
        pending: Future[None] | None = None
        for times, block in maps.blocks(options.block):
            if pending is not None:
                pending.result()
            if options.workers > 1:
                pending = pool.submit(omega_k.extend, block, times)
            else:
                omega_k.extend(block, times)
            finite += int(np.count_nonzero(np.isfinite(block)))
            push_lockins(lockins, block, times)
        if pending is not None:
            pending.result()
    if finite == 0:
        raise InputError(f"{maps.path}: maps/{maps.label} are all NaN (no trusted pixel)")
    results.spectrum = omega_k.spectrum()
    if lockins:
        results.lockin = lockins[0].result()
        results.centre_lockins = [lockin.result() for lockin in lockins[1:]]
    results.timing["spectrum_s"] = time.perf_counter() - started
    if options.fit:
        started = time.perf_counter()
        try:
            results.dispersion = fit_dispersion(
                results.spectrum,
                options.fluid,
                depth=options.depth,
                flow=options.flow,
                hold=options.hold,
                k_min=options.k_range[0],
                k_max=options.k_range[1],
            )
        except InputError as exc:
            # the spectra and the other analyses stand without it (the caller says it)
            results.fit_problem = str(exc)
            if maps.wider is not None:
                other, k_cut = maps.wider
                results.fit_problem += (
                    f"; maps/{maps.label} pass waves up to {maps.k_cut:.0f} rad/m, "
                    f"maps/{other} up to {k_cut:.0f} rad/m: try holoview waves --label {other}"
                )
            results.notes.append(f"no dispersion fit: {results.fit_problem}")
        results.timing["fit_s"] = time.perf_counter() - started


def _centre_lockins(maps: WaveMaps, frequency: float) -> list[LockIn]:
    """Lock-ins for the centre: the whole record, then its consecutive segments (the
    centre's error, :func:`~holoview.processing.waves.centre.centre_stderr`), equal
    weights.

    Equal weights, not Hann's: a ringdown fades, and Hann's weight on the middle of the
    record would favour the noise. The segments hold as many frames each (to one).
    """
    parts = np.array_split(maps.clock.times, CENTRE_SEGMENTS)
    spans = [(float(part[0]), float(part[-1])) for part in parts if part.size > 1]
    return [
        LockIn(maps.shape, frequency, (1,), span=span, window="flat")
        for span in (_span(maps), *spans)
    ]


def _auto_centre(maps: WaveMaps, options: WaveOptions, results: WaveResults) -> None:
    """The centre on the lock-in map at the drive (from pass 1) or at E(omega)'s peak."""
    frequency = options.drive
    if frequency is not None and results.centre_lockins:
        amplitudes = [lockin.amplitude[0] for lockin in results.centre_lockins]
    else:  # a ringdown asked for is the mode to centre on, not E(omega)'s strongest peak
        omega, energy = tone_energy(results.spectrum)
        band = None if options.ringdown is None else options.ringdown[1:]
        peaks = find_tones(omega, energy, 1, 2, band)
        if not peaks:
            where = "" if band is None else f" in the ringdown's band {band[0]:g}-{band[1]:g} Hz"
            raise InputError(
                f"no centre can be found: E(omega) has no tone{where} standing "
                f"{PROMINENCE:g} times over its surroundings (the maps show no waves to "
                "centre on); give the centre with --centre X,Y"
            )
        frequency = peaks[0]
        lockins = _centre_lockins(maps, frequency)
        for times, block in maps.blocks(options.block):
            push_lockins(lockins, block, times)
        amplitudes = [lockin.result().amplitude[0] for lockin in lockins]
    dy, dx = maps.pixel_size
    rows, cols = maps.shape
    radius = options.r_range[1] or 0.35 * min((rows - 1) * dy, (cols - 1) * dx)
    r_min, m_max = options.r_range[0], options.m_max
    results.centre = find_centre(
        amplitudes[0], maps.pixel_size, radius=radius, r_min=r_min, m_max=m_max
    )
    results.centre_stderr = centre_stderr(
        amplitudes[1:],
        maps.pixel_size,
        results.centre,
        radius=radius,
        r_min=r_min,
        m_max=m_max,
        workers=options.workers,
    )
    results.centre_method = (
        f"auto: least entropy over m of the lock-in map (equal weights) at "
        f"{frequency:.4g} Hz, rings to {radius * 1e3:.3g} mm; error: jackknife over "
        f"{len(amplitudes) - 1} segments of the record, widened by Student's t"
    )


def _candidates(results: WaveResults, options: WaveOptions) -> list[float]:
    if options.modes:
        return sorted({f for _, f in options.modes})
    found = options.drive_harmonics
    omega, energy = tone_energy(results.spectrum)
    for f in find_tones(omega, energy, CANDIDATE_TONES, 2):
        if all(abs(f - g) > 2 * results.spectrum.df for g in found):
            found.append(f)
    return found


def _mf_segment(maps: WaveMaps, segment: int) -> int:
    """Frames per segment of the (m, f) spectrum (:data:`MF_SEGMENT_MAX`)."""
    longest = max(b - a for a, b in maps.clock.runs)
    eighth = 1 << max((longest // 8).bit_length() - 1, 0)
    return max(segment, min(eighth, MF_SEGMENT_MAX))


def _pass_azimuthal(maps: WaveMaps, options: WaveOptions, results: WaveResults) -> None:
    """Pass 2: the (m, f) spectrum, lock-ins around the candidate tones, the ringdown series."""
    started = time.perf_counter()
    if options.centre == "auto":
        _auto_centre(maps, options, results)
    else:
        assert isinstance(options.centre, tuple)
        results.centre = options.centre
        results.centre_method = "given"
    assert results.centre is not None
    grid = polar_grid(
        maps.shape,
        maps.pixel_size,
        results.centre,
        r_min=options.r_range[0],
        r_max=options.r_range[1],
        m_max=options.m_max,
    )
    results.grid = grid
    candidates = _candidates(results, options)
    combs = [comb_around(maps, f) for f in candidates]
    series = () if options.ringdown is None else (options.ringdown[0],)
    span = _span(maps)
    accumulator = AzimuthalAccumulator(
        grid,
        maps.clock.interval,
        segment=_mf_segment(maps, options.segment),
        lock_in=[float(f) for comb in combs for f in comb],
        span=span,
        series=series,
        workers=options.workers,
    )
    # complex64 as PolarGrid.modes makes them (in float32): nothing is lost
    kept: list[tuple[np.ndarray, np.ndarray]] | None = None
    if maps.frames * grid.radii.size * grid.m.size * 8 <= KEPT_SAMPLES_BYTES:
        kept = []
    for times, block in maps.blocks(options.block):
        modes = grid.modes(block, workers=options.workers)
        accumulator.push_modes(modes, times)
        if kept is not None:
            kept.append((np.asarray(times), modes.astype(np.complex64)))
    results.mf = accumulator.spectrum()
    weights = _hann_weights(maps.clock.times, span)
    profiles = accumulator.profiles()
    for m, f, comb, block in mode_lock_ins(
        maps, options, results, candidates, combs=combs, profiles=profiles, kept=kept, span=span
    ):
        try:
            tone = refine_tone(comb, block, maps.clock.times, weights)
            check_steady(
                tone,
                comb,
                block,
                weights,
                times=maps.clock.times,
                noise=accumulator.profile_noise(m, tone.frequency),
                m=m,
            )
        except InputError as exc:
            problem = f"(m, f) = ({m}, {f:.4g} Hz): {exc}"
            if options.modes:
                raise InputError(problem) from None
            results.notes.append(f"{problem}; not fitted")
            continue
        results.tones.append((m, tone.frequency, tone.profile))
        try:
            results.partial_waves.append(
                fit_partial_wave(
                    grid.radii,
                    tone.profile,
                    m,
                    tone.frequency,
                    results.wavenumber(tone.frequency),
                    k_cut=maps.k_cut,
                    frequency_stderr=tone.frequency_stderr,
                    phase_stderr=tone.phase_stderr,
                )
            )
        except InputError as exc:
            if options.modes:
                raise
            results.notes.append(str(exc))
    if options.ringdown is not None:
        m, f1, f2 = options.ringdown
        times, values = accumulator.series()
        results.ringdown = fit_ringdown(
            times, values[:, :, 0], (f1, f2), m=m, radii=grid.radii, start=options.ringdown_start
        )
    results.timing["azimuthal_s"] = time.perf_counter() - started


def _check_asked(maps: WaveMaps, options: WaveOptions) -> None:
    """Refuse, before any pass, what the maps cannot give or a fit cannot start from: a
    frequency above the maps' Nyquist frequency, a band of wavenumbers past their cut-off,
    fit settings that are not a fit's (an option's typo need not wait for the spectra)."""
    if options.fit:
        check_fit_settings(options.hold, options.depth, options.fluid)
    band = options.band
    if band is not None and band.k_min is not None and band.k_min >= maps.k_cut:
        raise InputError(
            f"the band filter's wavenumbers from {band.k_min:.0f} rad/m lie past the maps' "
            f"cut-off {maps.k_cut:.0f} rad/m ({maps.k_cut_source}): it would keep nothing"
        )
    clock = maps.clock
    if options.drive is not None:
        for h in range(1, options.harmonics + 1):
            what = "the drive" if h == 1 else f"harmonic {h} of the {options.drive:.4g} Hz drive"
            fewer = f" (give --harmonics {h - 1})" if h > 1 else ""
            try:
                clock.check_resolved(h * options.drive, what)
            except InputError as exc:
                raise InputError(f"{exc}{fewer}") from None
    for m, f in options.modes:
        clock.check_resolved(f, f"the mode m={m}")
    if options.ringdown is not None:
        _, f1, f2 = options.ringdown
        clock.check_resolved(f2, f"the top of the ringdown's band {f1:g}:{f2:g} Hz")
    if band is not None and band.f_min is not None:
        clock.check_resolved(band.f_min, "the band filter's lowest frequency")
    if band is not None and band.temporal:  # a band its filter cannot make
        longest = max(stop - start for start, stop in clock.runs)
        band.frequency_intervals(clock.rate, block_for(band, clock.rate, maps.shape, longest))


def analyse_waves(maps: WaveMaps, options: WaveOptions) -> WaveResults:
    """Run the wave analyses on one label's maps (module docstring).

    Raises
    ------
    InputError
        Fewer frames than a segment, all-NaN maps, a centre outside the maps, or a fit
        that does not converge (the message says which; a dispersion fit's reason is in
        :attr:`WaveResults.fit_problem` instead).
    """
    _check_frames(maps, options.segment)
    if options.ringdown is not None and options.centre is None:
        raise InputError("a ringdown fit needs a centre: give --centre X,Y or --centre auto")
    _check_asked(maps, options)
    if isinstance(options.centre, tuple):  # a centre off the maps is refused before any pass
        polar_grid(
            maps.shape,
            maps.pixel_size,
            options.centre,
            r_min=options.r_range[0],
            r_max=options.r_range[1],
            m_max=options.m_max,
        )
    started = time.perf_counter()
    results = WaveResults(maps=maps, options=options, spectrum=None)  # type: ignore[arg-type]
    _pass_spectrum(maps, options, results)
    if options.azimuthal:
        _pass_azimuthal(maps, options, results)
    results.timing["analysis_s"] = time.perf_counter() - started
    return results
