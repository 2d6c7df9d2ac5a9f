"""A window matched to the surface: per peak, the radius that minimises the expected map error.

A peak's map is the phase of the spectrum around its carrier times the window ``W``,
against a reference. A window too narrow cuts what the map must show (the change of the
surface between the frame and the reference, and the surface's discontinuity across
the frame's periodic seam, which rings into the map when cut); a window too wide passes
noise (per pixel ``sum W^2`` times the spectrum's noise floor). :func:`matched_window`
makes the maps of one frame against its reference at a dozen radii from
:data:`MIN_RADIUS_BINS` FFT bins to the bound (half the distance to the nearest other
term: :func:`~holoview.processing.fourier.windows.auto_radii`), as the demodulator makes
them, and estimates each one's error from how it differs from the widest
(:func:`map_errors`): the cut content is what remains of the difference once the noise
the widest passes in addition is taken off. It keeps the radius of least error, then
looks again around it, there comparing every radius on the same pixels (those the
narrowest of them trusts: otherwise each wider radius, trusted closer to the frame's
edge, took in a band of the widest map's own edge error, and the estimate rose in steps
with the radius). The noise is the quiet part of the spectrum's
(:mod:`holoview.processing.peaks.surface_spectrum`). Each edge width searches from the
smallest radius that passes the waves detection saw with its own edge
(:func:`_waves_floor`), and the waves that only many frames show
(:func:`_varying_annuli`: a change one frame shows below its noise, whose variance over
many frames stands above the noise of their mean), kept at :data:`WAVE_LEVEL` of their
amplitude (:func:`_level_floor`); the window chosen is then widened where it passes
less than :data:`CONTENT_PASS` of what the annuli of the change that stand above the
noise save when passed (:func:`_content_floor`): the estimate sees a cut as the small
difference of two variances dominated by the widest map's noise, and on a weak family
it cut half of a ringing mode that detection saw no sidebands of. What a window cuts
weighs :data:`CUT_WEIGHT` times its error: it is the same surface content missing from
every peak's map, which the fused map does not average down as it does their noise.

What the map must show is measured on the frames the demodulator itself sees
(:func:`~holoview.processing.peaks.surface_spectrum.measure_spectrum`). Without
measurable change around a carrier (a flat surface: the excess power of the change
outside the carrier's central bins within
:data:`~holoview.processing.peaks.surface_spectrum.MEASURABLE_SIGMAS` standard errors of
zero), the radius is the bound, with a note: nothing says how narrow the surface's
spectrum is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyfftw

from holoview.processing.fourier.boxes import border_mask, box_layout, box_shape_for, box_weights
from holoview.processing.fourier.fftplans import ifft2_plan
from holoview.processing.fourier.windows import radial_window
from holoview.processing.peaks.surface_spectrum import (
    CENTRE_BINS,
    MEASURABLE_SIGMAS,
    SurfaceSpectrum,
    chi2_median,
)

__all__ = ["Window", "map_errors", "matched_window"]

#: Step (FFT bins) of the radial profile of the change (the content the reason names).
STEP_BINS = 0.25

#: Radii tried per peak, twice: spaced in log up to the bound, then around the best.
CANDIDATES = 12

#: Radii whose expected squared error is within this fraction of the least are as good:
#: the widest of them is kept. The estimate is low for narrow windows (measured against
#: the true surface on ``benchmarks/bench_windows.py``'s scene at kmax 0.005: RF 0.64 nm
#: estimated at 0.0125 cycles/pixel against 0.88 nm true, 0.70 against 0.60 at 0.0229),
#: and the fused map averages down the noise a wider window passes, not what a narrower
#: one cuts: keeping the narrowest put the fused map at 1.11 and 1.16 times the sweep's
#: best at kmax 0.01 and 0.005, the widest at 1.04 and 1.05. Since the noise floor is
#: the quiet part of the spectrum's (lower, so wide windows look cheaper) 0.1 kept too
#: wide a window (fused 1.18 times the best at kmax 0.005, 4 seeds); 0.05: 1.10.
NEAR_BEST = 0.05

#: What a window cuts counts this many times its squared error when the radius is chosen:
#: the cut is the same surface content missing from every peak's map, which fusing them
#: does not average down, as it does their noise.
CUT_WEIGHT = 2.0

#: The Tukey edges a matched window chooses among (with the one asked for), by the same
#: estimate of the map error: a wider edge rings less at small radii
#: (``benchmarks/bench_windows.py``).
MATCHED_TAPERS = (0.25, 0.5, 0.75)

#: A Tukey window passes at least 90 % of the power (``W >= 0.95``) out to ``1 - WAVE_EDGE
#: taper`` of its radius: the matched radius of a surface with waves seen at ``|q|`` is at
#: least ``|q| / (1 - WAVE_EDGE taper)``.
WAVE_EDGE = 0.856

#: Fraction of what the content standing above the noise around a carrier saves when
#: passed (annuli whose excess power over the noise floor is more than the noise they
#: let in, outside the central bins; :func:`_content_floor`) that every matched window
#: passes.
CONTENT_PASS = 0.9

#: An annulus whose variance over many frames stands :data:`WAVE_SIGMAS` standard
#: errors above the frames' noise, and at least this fraction of that noise per bin
#: above it, holds waves (:func:`_varying_annuli`): the outermost is passed at
#: :data:`WAVE_LEVEL`. Coherent in time, a wave the noise hides in one frame stands
#: out of the noise of the run's maps. The fraction keeps the weak tails of strong
#: waves out (partial waves of ``benchmarks/accuracy_waves.py``: 1.05 to 1.3 times the
#: noise out to the bound around RB1, 5 to 30 standard errors above it).
WAVE_FRACTION = 0.25

#: Standard errors of the many frames' mean above the noise at which an annulus's
#: variance over the frames counts as waves.
WAVE_SIGMAS = 5.0

#: Fewest frames (effective) whose variance is a test of waves: over fewer, the noise
#: is known to a third of itself or worse, and a weak family's window widened for what
#: it took for waves lost more to noise than it kept (FB2 of ``benchmarks/bench_wavy.py``,
#: 5 frames: correlation with the true surface 0.960 to 0.970 on three seeds of six,
#: 0.972 to 0.979 without the test).
MEAN_FRAMES_LEAST = 16

#: Amplitude transfer ``W`` of the window at the outermost annulus of waves: the wave
#: analyses want each wave's amplitude whole (within 3 %, issue 24).
WAVE_LEVEL = 0.98

#: Likewise for the other shapes: the fraction of the radius where ``W`` falls to 0.95.
PASS_FRACTION = {"raised-cosine": 0.144, "top-hat": 1.0}

#: A map pixel is trusted from this fraction of the median amplitude (as the demodulator's).
MIN_AMPLITUDE = 0.25

#: Smallest matched radius, FFT bins (as the automatic radii's floor).
MIN_RADIUS_BINS = 4.0


#: The rules a window radius is chosen by.
RULES = ("matched", "bound", "given")


@dataclass(frozen=True)
class Window:
    """One peak's window: its radius, shape and why.

    Attributes
    ----------
    radius : float
        Radius, cycles/pixel.
    kind : str
        Shape (:data:`~holoview.processing.fourier.windows.WINDOW_KINDS`).
    taper : float
        Edge width of a Tukey window, fraction of the radius.
    rule : {"matched", "bound", "given"}
        Matched to the surface's spectrum, the bound (widest reaching no other term),
        or given by the user.
    bound : float
        Half the distance to the nearest other term, cycles/pixel.
    reason : str
        One line saying why this radius.
    content : float or None
        Matched: how far from the carrier the surface's change stands above the noise
        floor (cycles/pixel, in whole annuli); else None.
    cut : float
        Matched: the map error (rad rms per trusted pixel) expected of what the window
        cuts of the change it was matched to; else 0 (not measured).
    """

    radius: float
    kind: str
    taper: float
    rule: str
    bound: float
    reason: str
    content: float | None = None
    cut: float = 0.0

    def to_dict(self) -> dict[str, object]:
        """The window as JSON-ready values (``radius_cpp``, ``kind``, ``taper``, ...)."""
        return {
            "radius_cpp": self.radius,
            "kind": self.kind,
            "taper": self.taper,
            "rule": self.rule,
            "bound_cpp": self.bound,
            "content_cpp": self.content,
            "cut_rad": self.cut,
            "reason": self.reason,
        }


def _field(box: np.ndarray, weights: np.ndarray, plan: pyfftw.FFTW) -> np.ndarray:
    """A peak's field (counts, box resolution) from its box's bins: window, invert."""
    pairs = plan.input_array.reshape(-1).view(np.float32)
    np.multiply(box.view(np.float32), weights, out=pairs)
    plan.execute()
    return plan.output_array.astype(np.complex128)


def map_errors(
    spectrum: SurfaceSpectrum,
    carrier: tuple[float, float],
    radii: np.ndarray,
    *,
    kind: str,
    taper: float,
    widest: tuple[str, float] | None = None,
    same_pixels: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Expected squared map error and its noise (rad^2 per trusted pixel) at each radius.

    The last radius is the largest, ``B``. The maps of every frame at every radius are
    made as the demodulator makes them (on the box of ``B``), each on its own trusted
    pixels (amplitude, border), and compared with the widest map: ``B`` with ``widest``
    = ``(kind, taper)``, by default the windows' own. The map of radius ``r`` differs
    from it by what ``r`` cuts and by the noise of the bins the widest passes and ``r``
    does not: ``D_r = c_r^2 + n^2 sum (W_B - W_r)^2``; its error is ``c_r^2 + n^2 sum
    W_r^2``, ``n^2`` the phase noise per unit of window from the spectrum's noise floor;
    averaged over the frames. What the widest map cuts is not seen: windows of other
    shapes are compared against one widest map, the one that cuts least. With
    ``same_pixels``, every radius on the pixels the smallest trusts.
    """
    rows, cols = spectrum.shape
    size = float(rows * cols)
    box_shape = box_shape_for(spectrum.shape, float(radii[-1]))
    plan = ifft2_plan(box_shape)
    shapes = [(kind, taper)] * len(radii) + [widest or (kind, taper)]
    radii = np.append(radii, radii[-1])
    # one layout for every radius (the same box and carrier): only the windows differ;
    # not box_geometry, whose cache would keep every candidate's arrays for the run
    layout = box_layout(spectrum.shape, box_shape, carrier)
    pairs = [
        box_weights(layout, spectrum.shape, kind=k, radius=float(r), taper=t)[1]
        for r, (k, t) in zip(radii, shapes, strict=True)
    ]
    weights = [np.abs(pair[0::2]).astype(np.float64) * size for pair in pairs]
    passed = np.array([float(np.sum(w * w)) for w in weights])
    extra = np.array([float(np.sum((weights[-1] - w) ** 2)) for w in weights])
    borders = [
        border_mask(box_shape, spectrum.shape, float(radii.min() if same_pixels else r))
        for r in radii
    ]
    reference = None if spectrum.reference is None else spectrum.reference.reshape(-1)
    references = None
    if reference is not None:
        box = np.take(reference, layout.index).astype(np.complex64, copy=False)
        references = [np.conj(_field(box, pair, plan)) for pair in pairs]
    total = np.zeros(len(radii))
    noise = np.zeros(len(radii))
    for half in spectrum.frames:
        box = np.take(half.reshape(-1), layout.index).astype(np.complex64, copy=False)
        products = [_field(box, pair, plan) for pair in pairs]
        magnitude = np.abs(products[-1])
        valid = magnitude >= MIN_AMPLITUDE * float(np.median(magnitude))
        if not valid.any():
            continue
        if references is not None:
            products = [p * ref for p, ref in zip(products, references, strict=True)]
        # phase noise per unit of sum W^2: floor / (2 size^2 |f|^2), averaged over pixels
        unit = spectrum.floor * float(np.mean(1.0 / magnitude[valid] ** 2)) / (2.0 * size * size)
        noise += unit * passed
        for j, product in enumerate(products):
            trusted = valid & borders[j]
            if not trusted.any():
                total[j] = np.inf
                continue
            step = np.angle(product[trusted] * np.conj(products[-1][trusted]))
            total[j] += max(float(np.var(step)) - unit * extra[j], 0.0) + unit * passed[j]
    count = len(spectrum.frames)
    return total[:-1] / count, noise[:-1] / count


def _weighed(errors: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """What a radius is chosen by: the noise, and :data:`CUT_WEIGHT` times what it cuts."""
    return noise + CUT_WEIGHT * (errors - noise)


def _best_radius(
    spectrum: SurfaceSpectrum,
    carrier: tuple[float, float],
    span: tuple[float, float],
    *,
    kind: str,
    taper: float,
) -> tuple[float, float, float, float]:
    """``(least weighed error, radius, cut, taper)`` of the radius :func:`matched_window` takes.

    ``span``: the smallest radius (the waves' floor for this shape, where it is larger)
    and the bound, cycles/pixel. The first value is the
    least weighed error of any radius tried, by which the tapers are compared (not the
    one of the radius kept, up to :data:`NEAR_BEST` above it: compared so, a taper with
    a wider radius as good lost to one without).
    """
    smallest, bound = span
    widest = (kind, min(MATCHED_TAPERS)) if kind == "tukey" else None
    if smallest >= bound:
        errors, errors_noise = map_errors(
            spectrum, carrier, np.array([bound]), kind=kind, taper=taper, widest=widest
        )
        weighed = _weighed(errors, errors_noise)
        cut = float(np.sqrt(max(errors[0] - errors_noise[0], 0.0)))
        return float(weighed[0]), bound, cut, taper
    coarse = np.geomspace(smallest, bound, CANDIDATES)
    errors, errors_noise = map_errors(
        spectrum, carrier, coarse, kind=kind, taper=taper, widest=widest
    )
    best = int(np.argmin(_weighed(errors, errors_noise)))
    low, high = coarse[max(best - 1, 0)], coarse[min(best + 1, len(coarse) - 1)]
    fine = np.append(np.linspace(low, high, CANDIDATES), bound)
    fine_errors, fine_noise = map_errors(
        spectrum, carrier, fine, kind=kind, taper=taper, widest=widest, same_pixels=True
    )
    weighed = _weighed(fine_errors, fine_noise)
    # the widest of the radii as good as the best (NEAR_BEST)
    least = float(np.min(weighed))
    chosen = int(np.flatnonzero(weighed <= least + NEAR_BEST * abs(least)).max())
    cut = float(np.sqrt(max(fine_errors[chosen] - fine_noise[chosen], 0.0)))
    return least, float(fine[chosen]), cut, taper


def _waves_floor(band: float, kind: str, taper: float, bound: float) -> float:
    """The smallest radius (cycles/pixel, at most ``bound``) that passes waves seen at ``band``.

    0 without waves seen.
    """
    if band <= 0:
        return 0.0
    passing = 1.0 - WAVE_EDGE * taper if kind == "tukey" else PASS_FRACTION[kind]
    return min(bound, band / passing)


def _content_floor(
    annuli: tuple[np.ndarray, np.ndarray],
    kind: str,
    taper: float,
    span: tuple[float, float],
    step: float,
    *,
    fraction: float = CONTENT_PASS,
) -> float:
    """The smallest radius (cycles/pixel, in ``span``) passing the content above the noise.

    ``annuli``: the middles (cycles/pixel) and what passing them saves (counts^2) of
    the annuli around a carrier whose change stands above the noise floor, outside its
    central bins: their excess power over the floor less the noise they let in (an
    annulus of a change just above the noise saves little). The radius is the smallest,
    in steps of ``step`` (cycles/pixel), whose window passes ``fraction`` of it
    (``sum W^2 saved``), else the bound; 0 without any such annulus. The map error
    estimate (:func:`map_errors`) sees a cut only as the small difference between two
    maps' variances, both dominated by the widest map's noise, and cut half of the
    power of a weak family's ringing mode (RB2 of ``holoview simulate --scenario
    ringdown``, ``tests/headless/test_process_ringdown_window.py``). Weighed by the
    excess alone, the broad low content of a smooth surface (``benchmarks/bench_windows.py``
    at kmax 0.005) widened the windows past the best: the fused map at 1.11 times the
    sweep's best; weighed by what passing saves, 1.09.
    """
    middles, power = annuli
    smallest, bound = span
    if middles.size == 0 or smallest >= bound:
        return 0.0
    radii = np.append(np.arange(smallest, bound, step), bound)
    passed = np.array(
        [float(np.sum(power * radial_window(kind, middles, r, taper=taper) ** 2)) for r in radii]
    )
    enough = np.flatnonzero(passed >= fraction * float(np.sum(power)))
    return float(radii[enough[0]]) if enough.size else bound


def _varying_annuli(
    spectrum: SurfaceSpectrum,
    varying: np.ndarray | None,
    which: np.ndarray,
    middles: np.ndarray,
    inner: float,
    *,
    seen: np.ndarray,
) -> np.ndarray:
    """Middles (cycles/pixel) of the annuli that hold waves, beyond ``inner``.

    The annuli (``which``: each bin's; ``middles``, cycles/pixel), beyond ``inner``
    (the carrier's central bins), whose median variance over many frames
    (:attr:`SurfaceSpectrum.mean`) stands :data:`WAVE_SIGMAS` standard errors and
    :data:`WAVE_FRACTION` of the frames' noise above the noise's, where the change does
    not stand above one frame's noise (not ``seen``: that is content, passed as the
    map error and :func:`_content_floor` decide): a change
    coherent over the run that one frame may show below its noise. Empty without the
    many frames.
    """
    mean = spectrum.mean
    if varying is None or mean is None or mean.frames < MEAN_FRAMES_LEAST:
        return np.zeros(0)
    # the median of each annulus: a ring of waves fills its annulus, where the frame's
    # periodic seam rings along two lines through the carrier (benchmarks/bench_windows.py
    # at kmax 0.005: their mean 3 times the noise out to the bound, their median 1.1)
    order = np.argsort(which, kind="stable")
    starts = np.searchsorted(which[order], np.arange(len(middles) + 1))
    dof = max(mean.frames - 1.0, 1.0)
    median = chi2_median(2.0 * dof) / (2.0 * dof)  # of noise alone, per floor
    standing = np.zeros(len(middles), dtype=bool)
    for j in np.flatnonzero((middles > inner) & (np.diff(starts) > 0) & ~seen):
        values = varying[order[starts[j] : starts[j + 1]]] / mean.floor
        # the median's standard error: sqrt(pi / 2) of a mean's
        error = 1.2533 / np.sqrt(values.size * dof)
        excess = float(np.median(values)) - median
        standing[j] = excess > WAVE_SIGMAS * error and excess > WAVE_FRACTION
    return middles[standing]


def _level_floor(reach: float, kind: str, taper: float, span: tuple[float, float]) -> float:
    """The smallest radius (cycles/pixel, in ``span``) whose window is :data:`WAVE_LEVEL`
    at ``reach`` (cycles/pixel); the bound where none is; 0 for no reach."""
    smallest, bound = span
    if reach <= 0:
        return 0.0
    radii = np.linspace(max(smallest, reach), bound, 256)
    level = np.array([radial_window(kind, np.array([reach]), r, taper=taper)[0] for r in radii])
    enough = np.flatnonzero(level >= WAVE_LEVEL)
    return float(radii[enough[0]]) if enough.size else bound


def matched_window(
    spectrum: SurfaceSpectrum,
    carrier: tuple[float, float],
    bound: float,
    *,
    kind: str,
    taper: float,
) -> Window:
    """Return the window of least expected map error around ``carrier``, at most ``bound``.

    Parameters
    ----------
    spectrum : SurfaceSpectrum
        The spectra the map is made of (:func:`measure_spectrum`).
    carrier : tuple of float
        ``(fx, fy)``, cycles/pixel.
    bound : float
        The widest radius reaching no other term, cycles/pixel.
    kind, taper
        The window's shape (:func:`~holoview.processing.fourier.windows.radial_window`).

    Returns
    -------
    Window
        Rule ``"matched"``: the radius of least :func:`map_errors` (what it cuts weighed
        :data:`CUT_WEIGHT` times) among :data:`CANDIDATES` radii spaced evenly in log
        between :data:`MIN_RADIUS_BINS` bins (or the radius that passes the waves
        detected, :func:`_waves_floor`) and the bound, then as many around the best,
        the widest within :data:`NEAR_BEST` of the least; for a Tukey window, with
        the edge of :data:`MATCHED_TAPERS` (or ``taper``) that gives the least;
        widened to pass the content above the noise (:func:`_content_floor`); the
        bound (rule ``"bound"``, with the reason) where the spectra show no measurable
        change around the carrier.
    """
    rows, cols = spectrum.shape
    per_bin = 1.0 / max(rows, cols)  # cycles/pixel of one bin along the finer axis
    smallest = MIN_RADIUS_BINS / min(rows, cols)
    if bound <= smallest:
        return Window(bound, kind, taper, "bound", bound, "the bound is the smallest window")
    rho, power, varying = spectrum.around(carrier, bound)
    noise = spectrum.floor
    excess = power - noise
    beyond = rho > CENTRE_BINS * per_bin
    outside = int(np.count_nonzero(beyond))
    measured = float(excess[beyond].sum())
    step = STEP_BINS * per_bin
    edges = np.arange(0.0, bound + step, step)
    which = np.minimum(np.searchsorted(edges, rho, side="right") - 1, len(edges) - 2)
    middles = edges[:-1] + 0.5 * step
    if outside == 0 or measured <= MEASURABLE_SIGMAS * noise * np.sqrt(outside):
        return Window(
            bound,
            kind,
            taper,
            "bound",
            bound,
            "no measurable change of the surface around the carrier: the bound",
        )
    tapers = (taper, *(t for t in MATCHED_TAPERS if t != taper)) if kind == "tukey" else (taper,)
    # each shape searched from the radius that passes the waves detected (its own floor):
    # widening the best of a shape after the shapes were compared chose a sharp edge
    # (which passes the waves from a smaller radius) widened to where a smoother one
    # was better
    signal = np.bincount(which, weights=excess, minlength=len(edges) - 1)
    count = np.bincount(which, minlength=len(edges) - 1).astype(np.float64)
    above = np.flatnonzero(signal > count * noise)
    # the annuli of waves that only many frames show (those one frame shows are content)
    seen = np.zeros(len(middles), dtype=bool)
    seen[above] = True
    waving = _varying_annuli(spectrum, varying, which, middles, CENTRE_BINS * per_bin, seen=seen)
    content = float(edges[above[-1] + 1]) if above.size else 0.0
    # the annuli beyond the carrier's central bins whose change stands above the noise
    standing = above[middles[above] > CENTRE_BINS * per_bin]
    annuli = (middles[standing], signal[standing] - count[standing] * noise)
    # the waves detected, and those that stand above the noise of many frames
    reach = float(waving[-1] + 0.5 * step) if waving.size else 0.0
    content = max(content, reach)
    waves = {
        t: max(
            _waves_floor(spectrum.band, kind, t, bound),
            _level_floor(reach, kind, t, (smallest, bound)),
        )
        for t in tapers
    }
    choices = [
        _best_radius(spectrum, carrier, (max(smallest, waves[t]), bound), kind=kind, taper=t)
        for t in tapers
    ]
    _, radius, cut, taper = min(choices)
    # then widened to pass the content that stands above the noise (searched from there,
    # the estimate's noise chose narrower windows as often as wider: FB2 of the wavy
    # surface, seed 6 of tests/processing/test_processing_matched.py, 0.0269 to 0.0219)
    floor = _content_floor(annuli, kind, taper, (smallest, bound), step)
    widened = floor > radius
    if widened:
        errors, errors_noise = map_errors(
            spectrum, carrier, np.array([floor, bound]), kind=kind, taper=taper
        )
        radius, cut = floor, float(np.sqrt(max(errors[0] - errors_noise[0], 0.0)))
    reason = (
        f"matched: least expected map error; the surface's change stands above the noise "
        f"out to {content:.4f} cycles/pixel, the bound is {bound:.4f}"
    )
    if waves[taper] > smallest and radius <= waves[taper]:
        if reach > 0 and waves[taper] > _waves_floor(spectrum.band, kind, taper, bound):
            reason += (
                f"; widened to pass the waves above the noise of "
                f"{spectrum.mean.frames if spectrum.mean else 0:.0f} frames whole "
                f"(out to {reach:.4f})"
            )
        else:
            reason += f"; widened to pass the waves detected (|q| up to {spectrum.band:.4f})"
    if widened:
        reason += f"; widened to pass {CONTENT_PASS:.0%} of the content above the noise"
    return Window(radius, kind, taper, "matched", bound, reason, content, cut)
