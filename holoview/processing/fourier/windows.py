"""Spectral windows that cut one carrier out of the spectrum, and the automatic radius.

Three radial windows, all of radius ``r`` in cycles/pixel (circular in frequency,
so elliptical in FFT bins on a non-square frame), centred on the sub-bin carrier:

- ``"top-hat"``: 1 inside the disc ``rho <= r``, 0 outside (the paper's simplest choice);
- ``"raised-cosine"``: ``(1 + cos(pi rho / r)) / 2`` inside the disc, a Hann-shaped disc
  (the paper's improved filter; roll-off over the whole radius);
- ``"tukey"``: flat to ``(1 - taper) r``, then a cosine edge reaching 0 at ``r``.

The shot-noise phase floor of docs/design.md depends on the window through its
*area fraction* ``eta = sum |W|^2 / (rows cols)`` over the spectrum's bins
(:func:`area_fraction`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from holoview.errors import InputError

#: The window kinds :func:`radial_window` knows.
WINDOW_KINDS: tuple[str, ...] = ("raised-cosine", "top-hat", "tukey")

#: The window used when none is given (see :func:`radial_window`), chosen by measurement
#: with :data:`DEFAULT_TAPER` (``benchmarks/bench_windows.py``: optics simulator, 1024^2,
#: moving waves of 25 nm rms change, windows at the bound of 0.034 cycles/pixel). RB1's
#: map error with waves up to 0.01 / 0.02 / 0.03 cycles/pixel: Tukey 0.25 0.48 / 0.50 /
#: 0.52 nm, Tukey 0.5 0.40 / 0.41 / 1.00, Tukey 0.75 0.32 / 0.57 / 1.47, top-hat
#: 0.61 / 0.65 / 0.67, raised cosine 0.40 / 1.17 / 2.17. A wider taper passes less noise
#: but attenuates the band; the quarter taper has the smallest worst case.
DEFAULT_WINDOW = "tukey"

#: Default width of the Tukey window's cosine edge, as a fraction of the radius (at the
#: bound, or a radius given). A window matched to the surface chooses its edge too
#: (:data:`~holoview.processing.peaks.matched.MATCHED_TAPERS`): at the radii a smooth
#: surface wants, a wider edge rings less (``bench_windows.py``, issue 23: kmax 0.005,
#: Tukey 0.75 at 0.0229 cycles/pixel 0.23 nm, Tukey 0.25 at best 0.31 nm).
DEFAULT_TAPER = 0.25

#: Fraction of the distance to the nearest other carrier used by :func:`auto_radii`:
#: two neighbouring windows touch.
SPACING_FRACTION = 0.5

#: Fraction of the carrier's distance to zero frequency used by :func:`auto_radii`. The
#: zero order is treated as one more neighbour: in this instrument every beam is close to
#: a plane wave, so the zero order (the beams' intensities, uniform up to the illumination
#: profile that every peak shares) is no wider than a sideband. The usual third holds for
#: an object wave whose autocorrelation is twice as wide as its sideband (microscopy);
#: measured on the simulator (``benchmarks/bench_windows.py``), a third left FB1 beside
#: the zero order at 0.023 cycles/pixel where its neighbours allow 0.034.
DC_FRACTION = 0.5

#: Largest radius :func:`auto_radius` returns (cycles/pixel).
MAX_AUTO_RADIUS = 0.2


def check_kind(kind: str) -> str:
    """Return ``kind`` if it names a window, else raise :class:`InputError` listing the kinds."""
    if kind not in WINDOW_KINDS:
        raise InputError(f"unknown window {kind!r}; choose one of {', '.join(WINDOW_KINDS)}")
    return kind


def radial_window(
    kind: str, rho: np.ndarray, radius: float, *, taper: float = DEFAULT_TAPER
) -> np.ndarray:
    """Evaluate a window on distances from its centre.

    Parameters
    ----------
    kind : {"raised-cosine", "top-hat", "tukey"}
        Window shape.
    rho : ndarray
        Distances from the carrier (cycles/pixel); not modified.
    radius : float
        Window radius (cycles/pixel); the window is 0 beyond it.
    taper : float
        Tukey edge width as a fraction of ``radius``, in (0, 1].

    Returns
    -------
    ndarray of float64, shape of ``rho``
        Window values in [0, 1].
    """
    check_kind(kind)
    if not radius > 0:
        raise InputError(f"window radius must be > 0 cycles/pixel, got {radius}")
    rho = np.asarray(rho, dtype=np.float64)
    inside = rho <= radius
    if kind == "top-hat":
        return inside.astype(np.float64)
    if kind == "raised-cosine":
        return np.where(inside, 0.5 * (1.0 + np.cos(np.pi * np.minimum(rho / radius, 1.0))), 0.0)
    if not 0 < taper <= 1:
        raise InputError(f"Tukey taper must be in (0, 1], got {taper}")
    flat = (1.0 - taper) * radius
    edge = np.clip((rho - flat) / (taper * radius), 0.0, 1.0)
    return np.where(inside, 0.5 * (1.0 + np.cos(np.pi * edge)), 0.0)


def wrap_frequency(f: np.ndarray | float) -> np.ndarray:
    """Wrap frequencies (cycles/pixel) into [-0.5, 0.5): a sampled spectrum is periodic."""
    return (np.asarray(f, dtype=np.float64) + 0.5) % 1.0 - 0.5


def _distances(points: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Periodic distances (cycles/pixel) from each point to each other point, shape (n, m)."""
    delta = wrap_frequency(points[:, None, :] - others[None, :, :])
    return np.hypot(delta[..., 0], delta[..., 1])


#: Carriers ``(fx, fy)`` in cycles/pixel: a sequence of pairs or an array of shape (N, 2).
Carriers = Sequence[tuple[float, float]] | np.ndarray


def _points(carriers: Carriers) -> np.ndarray:
    return np.asarray(carriers, dtype=np.float64).reshape(-1, 2)


def spacing(
    carriers: Carriers,
    neighbours: Carriers = (),
) -> np.ndarray:
    """Return, per carrier, its distance to the nearest other carrier or twin (cycles/pixel).

    Distances are periodic (a carrier near Nyquist is close to its own aliased twin).
    A single carrier's nearest neighbour is its own twin at ``-f``.

    Parameters
    ----------
    carriers : sequence of (fx, fy)
        Carrier frequencies (cycles/pixel).
    neighbours : sequence of (fx, fy)
        Other peaks of the spectrum (cycles/pixel) that count as neighbours, with
        their twins, though they are not carriers themselves.

    Returns
    -------
    ndarray of float64, shape (len(carriers),)
    """
    points = _points(carriers)
    if points.size == 0:
        return np.zeros(0)
    extra = _points(neighbours)
    others = np.concatenate([points, -points, extra, -extra])
    dist = _distances(points, others)
    n = len(points)
    dist[np.arange(n), np.arange(n)] = np.inf
    return dist.min(axis=1)


def auto_radii(
    carriers: Carriers,
    *,
    neighbours: Carriers = (),
    min_radius: float = 0.0,
    max_radius: float = MAX_AUTO_RADIUS,
) -> np.ndarray:
    """Return each carrier's widest window radius that reaches no other peak (cycles/pixel).

    Peak ``i`` gets :data:`SPACING_FRACTION` of the distance to the nearest other
    carrier, twin or neighbour (periodic), and at most :data:`DC_FRACTION` of its
    distance to zero frequency: two neighbouring windows of these radii touch and do
    not overlap. Each radius is then clipped to ``[min_radius, max_radius]``.

    Parameters
    ----------
    carriers : sequence of (fx, fy)
        Carrier frequencies (cycles/pixel).
    neighbours : sequence of (fx, fy)
        Other peaks of the spectrum (not demodulated) that bound the radii too.
    min_radius, max_radius : float
        Bounds of the result (cycles/pixel).

    Returns
    -------
    ndarray of float64, shape (len(carriers),)
        Radii in cycles/pixel.

    Raises
    ------
    InputError
        For no carrier, a non-finite one, or a carrier at zero frequency.
    """
    points = _points(carriers)
    if points.size == 0:
        raise InputError("auto_radius needs at least one carrier")
    if not (np.isfinite(points).all() and np.isfinite(_points(neighbours)).all()):
        raise InputError("carrier frequencies must be finite")
    to_dc = np.hypot(*wrap_frequency(points).T)
    if (to_dc == 0).any():
        raise InputError("a carrier at zero frequency has no sideband to cut out")
    radii = np.minimum(SPACING_FRACTION * spacing(points, neighbours), DC_FRACTION * to_dc)
    return np.clip(np.minimum(radii, max_radius), min_radius, None)


def auto_radius(
    carriers: Carriers,
    *,
    neighbours: Carriers = (),
    min_radius: float = 0.0,
    max_radius: float = MAX_AUTO_RADIUS,
) -> float:
    """Return one window radius for all carriers: the smallest of :func:`auto_radii`.

    Parameters and errors as :func:`auto_radii`; the result is in cycles/pixel.
    """
    radii = auto_radii(
        carriers, neighbours=neighbours, min_radius=min_radius, max_radius=max_radius
    )
    return float(radii.min())


def area_fraction(window_bins: np.ndarray, frame_shape: tuple[int, int]) -> float:
    """Return ``sum |W|^2 / (rows cols)``: the fraction of the spectrum's noise a window passes.

    Parameters
    ----------
    window_bins : ndarray
        The window sampled on FFT bins (any layout; every nonzero bin included).
    frame_shape : tuple of int
        Frame shape ``(rows, cols)``.
    """
    w = np.asarray(window_bins, dtype=np.float64)
    return float(np.sum(w * w) / (frame_shape[0] * frame_shape[1]))
