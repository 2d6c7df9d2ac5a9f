"""Spectral windows that cut one carrier out of the spectrum, and the automatic radius.

Three radial windows, all of radius ``r`` in cycles/pixel (circular in frequency,
so elliptical in FFT bins on a non-square frame), centred on the sub-bin carrier:

- ``"top-hat"``: 1 inside the disc ``rho <= r``, 0 outside (the paper's simplest choice);
- ``"raised-cosine"``: ``(1 + cos(pi rho / r)) / 2`` inside the disc, a Hann-shaped disc
  (the paper's improved filter; roll-off over the whole radius);
- ``"tukey"``: flat to ``(1 - taper) r``, then a cosine edge reaching 0 at ``r``.

The shot-noise phase floor of DESIGN.md depends on the window through its
*area fraction* ``eta = sum |W|^2 / (rows cols)`` over the spectrum's bins
(:func:`area_fraction`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from holoview.errors import InputError

#: The window kinds :func:`radial_window` knows.
WINDOW_KINDS: tuple[str, ...] = ("raised-cosine", "top-hat", "tukey")

#: Default width of the Tukey window's cosine edge, as a fraction of the radius.
DEFAULT_TAPER = 0.5

#: Fraction of the distance to the nearest other carrier used by :func:`auto_radius`.
SPACING_FRACTION = 0.5

#: Fraction of the carrier's distance to zero frequency used by :func:`auto_radius`:
#: the zero-order (autocorrelation) term is twice as wide as a carrier's sideband.
DC_FRACTION = 1.0 / 3.0

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


def spacing(carriers: Sequence[tuple[float, float]]) -> np.ndarray:
    """Return, per carrier, its distance to the nearest other carrier or twin (cycles/pixel).

    Distances are periodic (a carrier near Nyquist is close to its own aliased twin).
    A single carrier's nearest neighbour is its own twin at ``-f``.

    Parameters
    ----------
    carriers : sequence of (fx, fy)
        Carrier frequencies (cycles/pixel).

    Returns
    -------
    ndarray of float64, shape (len(carriers),)
    """
    points = np.asarray(carriers, dtype=np.float64).reshape(-1, 2)
    if points.size == 0:
        return np.zeros(0)
    others = np.concatenate([points, -points])
    delta = wrap_frequency(points[:, None, :] - others[None, :, :])
    dist = np.hypot(delta[..., 0], delta[..., 1])
    n = len(points)
    dist[np.arange(n), np.arange(n)] = np.inf
    return dist.min(axis=1)


def auto_radius(
    carriers: Sequence[tuple[float, float]],
    *,
    min_radius: float = 0.0,
    max_radius: float = MAX_AUTO_RADIUS,
) -> float:
    """Return one window radius for all carriers, from the distance to the nearest other peak.

    The radius is half the smallest distance between two carriers (twins and
    periodic aliases included), and at most a third of the smallest distance to
    zero frequency, whose autocorrelation term is twice as wide as a sideband;
    then clipped to ``[min_radius, max_radius]``.

    Parameters
    ----------
    carriers : sequence of (fx, fy)
        Carrier frequencies (cycles/pixel).
    min_radius, max_radius : float
        Bounds of the result (cycles/pixel).

    Returns
    -------
    float
        Radius in cycles/pixel.
    """
    points = np.asarray(carriers, dtype=np.float64).reshape(-1, 2)
    if points.size == 0:
        raise InputError("auto_radius needs at least one carrier")
    if not np.isfinite(points).all():
        raise InputError("carrier frequencies must be finite")
    to_dc = np.hypot(*wrap_frequency(points).T).min()
    if to_dc == 0:
        raise InputError("a carrier at zero frequency has no sideband to cut out")
    radius = min(SPACING_FRACTION * spacing(points).min(), DC_FRACTION * to_dc, max_radius)
    return float(max(radius, min_radius))


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
