"""Each demodulated peak's window: the checks of the peaks, and the window radii.

- :func:`check_peaks` refuses what cannot be demodulated (no peak, a carrier outside
  the spectrum, a bad alpha).
- :func:`peak_radii` gives every peak its window radius (cycles/pixel): the one given,
  or by default the widest that reaches no other peak, twin or zero frequency
  (:func:`~holoview.processing.fourier.windows.auto_radii`), per peak;
  :func:`check_radii` refuses a window holding another carrier and names the peaks
  whose windows overlap another's;
- :func:`distinct_neighbours`: the detected peaks that are not the demodulated ones.

Distances are periodic in frequency (:func:`~holoview.processing.fourier.windows.wrap_frequency`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from holoview.errors import InputError
from holoview.processing.fourier.windows import auto_radii, wrap_frequency
from holoview.processing.peaks.detection import MIN_RADIUS_BINS, Peak

__all__ = [
    "check_peaks",
    "check_radii",
    "distinct_neighbours",
    "peak_name",
    "peak_radii",
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


def peak_radii(
    shape: tuple[int, int],
    carriers: np.ndarray,
    radius: float | None,
    neighbours: np.ndarray,
) -> tuple[float, ...]:
    """Return each peak's window radius (cycles/pixel).

    Parameters
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)``.
    carriers : ndarray, shape (n, 2)
        The demodulated carriers ``(fx, fy)``, cycles/pixel.
    radius : float or None
        One radius for every peak; None: per peak, the widest that reaches no
        other carrier, neighbour, twin or zero frequency, at least
        :data:`~holoview.processing.peaks.detection.MIN_RADIUS_BINS` bins.
    neighbours : ndarray, shape (m, 2)
        Other peaks of the spectrum, not demodulated, that bound the radii.
    """
    if radius is not None:
        return (float(radius),) * len(carriers)
    radii = auto_radii(carriers, neighbours=neighbours, min_radius=MIN_RADIUS_BINS / min(shape))
    return tuple(float(r) for r in radii)


def check_radii(peaks: Sequence[Peak], radii: Sequence[float], neighbours: np.ndarray) -> set[int]:
    """Raise when a window holds another peak or zero frequency; return the overlapping ones.

    Peak ``i``'s window overlaps when it reaches into another carrier's window
    (``r_i + r_j`` beyond their distance; a twin's window is the carrier's own
    radius) or past half the distance to a neighbour.

    Raises
    ------
    InputError
        A radius that is not positive and finite, or a window holding zero
        frequency, another carrier, its twin or a neighbour.
    """
    carriers = np.array([p.carrier for p in peaks], dtype=np.float64)
    overlapping = set()
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
        for point, other_radius, name in others:
            d = float(np.hypot(*wrap_frequency(carriers[i] - point)))
            if r >= d:
                raise InputError(
                    f"window radius {r:.4g} cycles/pixel is larger than the spacing "
                    f"{d:.4g} between {peak_name(peaks, i)} and {name}; use a smaller radius"
                )
            if r + other_radius > d * (1 + 1e-9):
                overlapping.add(i)
    return overlapping
