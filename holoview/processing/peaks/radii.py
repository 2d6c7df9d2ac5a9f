"""Each demodulated peak's window: the checks of the peaks, and the window radii.

- :func:`check_peaks` refuses what cannot be demodulated (no peak, a carrier outside
  the spectrum, a bad alpha).
- :func:`peak_windows` gives every peak its :class:`~holoview.processing.peaks.matched.Window`
  by one of three rules: ``"matched"`` (the radius of least expected map error from a
  frame's spectrum, :mod:`~holoview.processing.peaks.matched`; the default),
  ``"bound"`` (the widest that reaches no other peak, twin or zero frequency:
  :func:`~holoview.processing.fourier.windows.auto_radii`) or a number given;
  :func:`peak_radii` the radii alone;
- :func:`check_radii` refuses a window holding zero frequency, says which given
  window reaches another peak (a warning: the user asked for it) and names the peaks
  whose windows overlap another's;
- :func:`window_neighbours`: the detected peaks that bound windows (not the surface's
  sidebands); :func:`distinct_neighbours`: those that are not the demodulated ones.

Distances are periodic in frequency (:func:`~holoview.processing.fourier.windows.wrap_frequency`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from holoview.errors import InputError
from holoview.processing.fourier.windows import auto_radii, check_kind, wrap_frequency
from holoview.processing.peaks.detection import MIN_RADIUS_BINS, Peak
from holoview.processing.peaks.matched import Window, matched_window
from holoview.processing.peaks.surface_spectrum import SurfaceSpectrum

__all__ = [
    "RADIUS_RULES",
    "check_peaks",
    "check_radii",
    "distinct_neighbours",
    "fell_back",
    "peak_name",
    "peak_radii",
    "peak_windows",
    "radius_rule",
    "surface_band",
    "window_neighbours",
]

#: How a radius may be asked for, besides a number (cycles/pixel): matched to the
#: surface's spectrum (the default), or the bound.
RADIUS_RULES = ("matched", "bound")

#: What a window's radius is asked for by: a number (cycles/pixel), a rule, or None
#: (``"matched"``).
Radius = float | str | None

#: Why a bound window has its radius.
BOUND_REASON = "the bound: half the distance to the nearest other peak, twin or zero frequency"

#: Why a window meant to be matched is at the bound before a spectrum was measured.
UNMEASURED_REASON = "the bound: the spectrum was not measured"


def radius_rule(radius: Radius) -> str:
    """``"matched"``, ``"bound"`` or ``"given"`` (a number): the rule ``radius`` asks for.

    Raises
    ------
    InputError
        For a string that is not a rule, or a radius that is not a positive number.
    """
    if radius is None:
        return "matched"
    if isinstance(radius, str):
        if radius not in RADIUS_RULES:
            raise InputError(
                f"window radius {radius!r}: give a number (cycles/pixel), "
                f"{' or '.join(repr(r) for r in RADIUS_RULES)}"
            )
        return radius
    if isinstance(radius, bool) or not isinstance(radius, int | float):
        raise InputError(f"window radius {str(radius)[:20]!r} is not a number")
    try:
        value = float(radius)
    except OverflowError:
        raise InputError("window radius is not a finite number") from None
    if not (np.isfinite(value) and value > 0):
        raise InputError(f"window radius must be > 0 cycles/pixel, got {value:g}")
    return "given"


def surface_band(detected: Sequence[Peak]) -> float:
    """The surface's waves as detection saw them: the largest first-order sideband offset.

    Returns ``max |q|`` (cycles/pixel) over the detected sidebands at a wave's ``+-q``
    (:attr:`~holoview.processing.peaks.detection.Peak.sideband_order` 1); 0 without.
    """
    offsets = [p.surface_offset for p in detected if p.sideband_order == 1]
    return max((float(np.hypot(*q)) for q in offsets if q is not None), default=0.0)


def window_neighbours(
    detected: Sequence[Peak], on_lattice: Sequence[bool] | None = None
) -> list[tuple[float, float]]:
    """The carriers (cycles/pixel) of the detected peaks that bound windows.

    Every detected peak but the surface's sidebands (flag ``"surface"``): a sideband is
    the surface's content around its carrier, which the carrier's window is to pass.
    ``on_lattice`` (per detected peak, from naming) overrules the flag: a lattice point
    is never a sideband.
    """
    lattice = list(on_lattice) if on_lattice is not None else [False] * len(detected)
    return [
        p.carrier
        for p, placed in zip(detected, lattice, strict=True)
        if placed or "surface" not in p.flags
    ]


def peak_name(peaks: Sequence[Peak], i: int) -> str:
    """Return peak ``i``'s label, or ``"peak i"`` when it has none."""
    return peaks[i].label or f"peak {i}"


def check_peaks(peaks: Sequence[Peak]) -> tuple[Peak, ...]:
    """Return the peaks as a tuple, or raise :class:`InputError` naming the first bad one."""
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


def distinct_neighbours(
    shape: tuple[int, int], carriers: np.ndarray, neighbours: Sequence[tuple[float, float]]
) -> np.ndarray:
    """Return the neighbours that are not one of the carriers (or a twin), shape (m, 2).

    A neighbour within :data:`~holoview.processing.peaks.detection.MIN_RADIUS_BINS` FFT bins of a
    carrier or of its twin is that peak, detected again: callers may pass every
    detected peak.

    Raises
    ------
    InputError
        For a neighbour that is not a finite ``(fx, fy)``.
    """
    others = np.asarray(neighbours, dtype=np.float64).reshape(-1, 2)
    if not np.isfinite(others).all():
        raise InputError("neighbouring peaks must have finite carriers")
    if not len(others):
        return others
    points = np.concatenate([carriers, -carriers])
    delta = wrap_frequency(others[:, None, :] - points[None, :, :])
    bins = np.hypot(delta[..., 0] * shape[1], delta[..., 1] * shape[0])
    return others[bins.min(axis=1) > MIN_RADIUS_BINS]


def peak_windows(
    shape: tuple[int, int],
    carriers: np.ndarray,
    radius: Radius,
    neighbours: np.ndarray,
    *,
    kind: str,
    taper: float,
    spectrum: SurfaceSpectrum | None = None,
) -> tuple[Window, ...]:
    """Return each peak's window.

    Parameters
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)``.
    carriers : ndarray, shape (n, 2)
        The demodulated carriers ``(fx, fy)``, cycles/pixel.
    radius : float, "matched", "bound" or None
        A number: that radius (cycles/pixel) for every peak. ``"bound"``: per peak, the
        widest that reaches no other carrier, neighbour, twin or zero frequency, at
        least :data:`~holoview.processing.peaks.detection.MIN_RADIUS_BINS` bins.
        ``"matched"`` or None: per peak, the radius of least expected map error from
        ``spectrum``, never past the bound
        (:func:`~holoview.processing.peaks.matched.matched_window`); the bound without
        a spectrum.
    neighbours : ndarray, shape (m, 2)
        Other peaks of the spectrum, not demodulated, that bound the radii.
    kind, taper
        The windows' shape (:func:`~holoview.processing.fourier.windows.radial_window`).
    spectrum : SurfaceSpectrum, optional
        The spectrum the matched radii are measured on
        (:func:`~holoview.processing.peaks.surface_spectrum.measure_spectrum`).
    """
    rule = radius_rule(radius)
    check_kind(kind)
    bounds = auto_radii(carriers, neighbours=neighbours, min_radius=MIN_RADIUS_BINS / min(shape))
    if rule == "given":
        r = float(radius)  # type: ignore[arg-type]
        return tuple(Window(r, kind, taper, "given", float(b), "given by the user") for b in bounds)
    if rule == "bound" or spectrum is None:
        reason = BOUND_REASON if rule == "bound" else UNMEASURED_REASON
        return tuple(Window(float(b), kind, taper, "bound", float(b), reason) for b in bounds)
    if spectrum.shape != tuple(shape):
        raise InputError(f"spectrum of a {spectrum.shape} frame for frames of {shape}")
    return tuple(
        matched_window(spectrum, (float(c[0]), float(c[1])), float(b), kind=kind, taper=taper)
        for c, b in zip(carriers, bounds, strict=True)
    )


def fell_back(window: Window) -> bool:
    """Whether a window meant to be matched is at the bound for want of surface power."""
    return window.rule == "bound" and window.reason not in (BOUND_REASON, UNMEASURED_REASON)


def fallback_notes(peaks: Sequence[Peak], windows: Sequence[Window]) -> tuple[str, ...]:
    """One note per reason for the matched windows that fell back to the bound.

    Peaks with the same reason share a line (``"RB1, RF and FB1: no measurable change
    ... (0.0793, 0.0801, 0.0793 cycles/pixel)"``): a flat surface gives one line, not
    one per peak.
    """
    by_reason: dict[str, list[int]] = {}
    for i, window in enumerate(windows):
        if fell_back(window):
            by_reason.setdefault(window.reason, []).append(i)
    notes = []
    for reason, which in by_reason.items():
        names = [peak_name(peaks, i) for i in which]
        named = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
        radii = ", ".join(f"{windows[i].radius:.4g}" for i in which)
        notes.append(f"{named}: {reason} ({radii} cycles/pixel)")
    return tuple(notes)


def peak_radii(
    shape: tuple[int, int],
    carriers: np.ndarray,
    radius: float | None,
    neighbours: np.ndarray,
) -> tuple[float, ...]:
    """Return each peak's window radius (cycles/pixel): ``radius``, or the bound if None.

    See :func:`peak_windows` (rule ``"bound"`` for None here: no spectrum).
    """
    windows = peak_windows(
        shape, carriers, "bound" if radius is None else radius, neighbours, kind="tukey", taper=0.25
    )
    return tuple(w.radius for w in windows)


def check_radii(
    peaks: Sequence[Peak], radii: Sequence[float], neighbours: np.ndarray
) -> tuple[set[int], tuple[str, ...]]:
    """Raise when a window holds zero frequency; return the overlapping ones and warnings.

    Peak ``i``'s window overlaps when it reaches into another carrier's window
    (``r_i + r_j`` beyond their distance; a twin's window is the carrier's own
    radius) or past half the distance to a neighbour. A window that reaches another
    carrier, its twin or a neighbour (only a given radius can) is demodulated as asked,
    with one warning line naming the peak it reaches: that peak's content leaks into
    the map.

    Raises
    ------
    InputError
        A radius that is not positive and finite, or a window holding zero frequency.
    """
    carriers = np.array([p.carrier for p in peaks], dtype=np.float64)
    overlapping = set()
    warnings = []
    for i, r in enumerate(radii):
        if not (np.isfinite(r) and r > 0):
            raise InputError(f"window radius must be > 0 cycles/pixel, got {r}")
        to_dc = float(np.hypot(*wrap_frequency(carriers[i])))
        if r >= to_dc:
            raise InputError(
                f"window radius {r:.4g} cycles/pixel reaches zero frequency from "
                f"{peak_name(peaks, i)} (|f| = {to_dc:.4g}); use a smaller radius"
            )
        others = [
            (carriers[j] * sign, radii[j], f"{what}{peak_name(peaks, j)}")
            for j in range(len(peaks))
            for sign, what in ((1, ""), (-1, "the twin of "))
            if not (j == i and sign == 1)
        ]
        others += [
            (point * sign, r, f"{what}the unselected peak at ({point[0]:.4g}, {point[1]:.4g})")
            for point in neighbours
            for sign, what in ((1, ""), (-1, "the twin of "))
        ]
        reached = []
        for point, other_radius, name in others:
            d = float(np.hypot(*wrap_frequency(carriers[i] - point)))
            if r >= d:
                reached.append((d, name))
            if r + other_radius > d * (1 + 1e-9):
                overlapping.add(i)
        if reached:
            d, name = min(reached)
            more = f" and {len(reached) - 1} more" if len(reached) > 1 else ""
            warnings.append(
                f"window radius {r:.4g} cycles/pixel around {peak_name(peaks, i)} reaches "
                f"{name}{more} (spacing {d:.4g}): its content leaks into the map"
            )
    return overlapping, tuple(warnings)
