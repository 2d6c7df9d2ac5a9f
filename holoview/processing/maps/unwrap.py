"""Spatial phase unwrapping, and masks of pixels worth unwrapping.

Spatial unwrapping is Herraez et al. 2002 (Appl. Opt. 41, 7437), as implemented
by :func:`skimage.restoration.unwrap_phase`; it costs 20-40 times a whole
demodulation, so :func:`unwrap_spatial` first checks cheaply whether the map has
any wrap at all and returns it unchanged when not. Mean phases are unwrapped in
time by :func:`holoview.processing.series.phase_series.unwrap_in_time`.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import ndimage
from skimage.restoration import unwrap_phase

from holoview.errors import InputError
from holoview.processing.fourier.fastmath import TWO_PI

#: Pixels at a map's edge left out of :func:`phase_ratio`.
EDGE = 3

#: Width (pixels) of the box filter :func:`phase_ratio` smooths the guide with.
GUIDE_SMOOTHING = 5


def wrap(phase: np.ndarray | float) -> np.ndarray:
    """Wrap phases (rad) into [-pi, pi] (float32 stays float32).

    ``p - 2 pi rint(p / 2 pi)``: four vectorised passes, several times faster than ``%``.
    """
    p = np.asarray(phase)
    if p.dtype.kind != "f":
        p = p.astype(np.float64)
    turns = np.rint(p * p.dtype.type(1 / TWO_PI))
    turns *= p.dtype.type(TWO_PI)
    return p - turns


def _steps_x(phase: np.ndarray) -> np.ndarray:
    """``phase[:, 1:] - phase[:, :-1]`` in the first ``cols - 1`` columns, 0 in the last (rad).

    A new contiguous array of the map's shape, made by one subtraction over the map seen
    as one row (the 2-D one between strided views took four times as long, and reductions
    over a strided view twice as long, measured on 240 x 240 float32 maps); the last
    column, the pairs that straddle two rows, is then set to 0.
    """
    p = np.ascontiguousarray(phase)
    rows, cols = p.shape
    flat = p.reshape(-1)
    steps = np.empty((rows, cols), dtype=p.dtype)
    if flat.size:
        np.subtract(flat[1:], flat[:-1], out=steps.reshape(-1)[:-1])
        steps[:, -1] = 0
    return steps


def _jumps(phase: np.ndarray, mask: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Neighbour pairs (along rows, along columns) of trusted pixels more than pi apart."""
    p = np.asarray(phase)
    jump_x = np.abs(_steps_x(p)[:, :-1]) > np.pi
    jump_y = np.abs(p[1:, :] - p[:-1, :]) > np.pi
    if mask is not None:
        m = np.asarray(mask, dtype=bool)
        jump_x &= m[:, 1:] & m[:, :-1]
        jump_y &= m[1:, :] & m[:-1, :]
    return jump_x, jump_y


def _trusted(phase: np.ndarray, mask: np.ndarray | None) -> tuple[np.ndarray, float]:
    """The phase with untrusted pixels at 0, and its largest magnitude (rad)."""
    p = np.asarray(phase)
    trusted = p if mask is None else np.multiply(p, np.asarray(mask, dtype=bool))
    if not trusted.size:
        return trusted, 0.0
    return trusted, max(-float(trusted.min()), float(trusted.max()))


def _beyond_pi(steps: np.ndarray) -> bool:
    """Whether any step (rad) is more than pi either way (two reductions, no new array)."""
    return bool(steps.max(initial=0.0) > np.pi or steps.min(initial=0.0) < -np.pi)


def has_wraps(phase: np.ndarray, mask: np.ndarray | None = None) -> bool:
    """Return whether two neighbouring trusted pixels differ by more than pi (rad).

    A map whose trusted phases all lie within pi/2 of zero (a small change against
    the reference, the usual case) is told apart in three array passes.

    Parameters
    ----------
    phase : ndarray, shape (rows, cols)
        Wrapped phase map (rad); not modified.
    mask : ndarray of bool, optional
        Trusted pixels; a pair counts only when both are trusted.
    """
    trusted, extent = _trusted(phase, mask)
    if extent < np.pi / 2:
        return False
    if extent <= np.pi:  # pairs with an untrusted pixel (0) are within pi: no mask needed
        # the steps along the rows end in a column of 0: no step beyond pi there
        return _beyond_pi(_steps_x(trusted)) or _beyond_pi(
            np.subtract(trusted[1:, :], trusted[:-1, :])
        )
    jump_x, jump_y = _jumps(phase, mask)
    return bool(jump_x.any() or jump_y.any())


def wrap_bounds(
    phase: np.ndarray, mask: np.ndarray | None = None
) -> tuple[int, int, int, int] | None:
    """Return the rectangle holding every wrap (:func:`has_wraps`'s pairs), or None.

    Returns
    -------
    tuple of int or None
        ``(top, bottom, left, right)``, the first and last rows and columns (pixels,
        inclusive) of the pixels of every pair of trusted neighbours more than pi apart;
        None when there is no such pair.
    """
    trusted, extent = _trusted(phase, mask)
    if extent < np.pi / 2:
        return None
    if extent <= np.pi:
        # the zeroed map's pairs are the trusted ones (has_wraps); most maps have none
        step_x = _steps_x(trusted)  # its last column is 0: no step beyond pi there
        step_y = np.subtract(trusted[1:, :], trusted[:-1, :])
        if not (_beyond_pi(step_x) or _beyond_pi(step_y)):
            return None
        jump_x = np.abs(step_x[:, :-1]) > np.pi
        jump_y = np.abs(step_y, out=step_y) > np.pi
    else:
        jump_x, jump_y = _jumps(phase, mask)
    along_x, along_y = jump_x.any(axis=1), jump_y.any(axis=1)
    if not (along_x.any() or along_y.any()):
        return None
    rows: np.ndarray = np.array(along_x)
    rows[:-1] |= along_y
    rows[1:] |= along_y
    cols: np.ndarray = np.array(jump_y.any(axis=0))
    cols[:-1] |= jump_x.any(axis=0)
    cols[1:] |= jump_x.any(axis=0)
    r = np.flatnonzero(rows)
    c = np.flatnonzero(cols)
    return int(r[0]), int(r[-1]), int(c[0]), int(c[-1])


def _herraez(phase: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    """Herraez et al. 2002 through scikit-image; untrusted pixels keep their wrapped value."""
    source = phase.astype(np.float64)
    if mask is None:
        return unwrap_phase(source)
    with warnings.catch_warnings():
        # separate trusted islands are unwrapped independently; skimage says so in a warning
        warnings.simplefilter("ignore", UserWarning)
        result = unwrap_phase(np.ma.masked_array(source, mask=~mask))
    return np.where(mask, result.filled(0.0), source)


def unwrap_spatial(
    phase: np.ndarray, mask: np.ndarray | None = None, *, decimate: int = 1
) -> tuple[np.ndarray, bool]:
    """Unwrap a phase map in space when it has wraps (Herraez et al. 2002).

    Parameters
    ----------
    phase : ndarray, shape (rows, cols)
        Wrapped phase (rad); not modified.
    mask : ndarray of bool, optional
        Trusted pixels; the others keep their wrapped value.
    decimate : int
        Unwrap every ``decimate``-th pixel along each axis, then bring each pixel
        within pi of its coarse neighbour (``decimate**2`` times cheaper; exact
        wherever the phase moves less than pi between coarse samples).

    Returns
    -------
    unwrapped : ndarray of float32
        The unwrapped map (a new array), or ``phase`` itself when nothing was wrapped.
        The global offset is a multiple of 2 pi chosen by the algorithm.
    changed : bool
        Whether unwrapping ran.
    """
    p = np.asarray(phase)
    if p.ndim != 2:
        raise InputError(f"phase map must be 2-D, got shape {p.shape}")
    if decimate < 1:
        raise InputError(f"decimate must be >= 1, got {decimate}")
    m = None if mask is None else np.asarray(mask, dtype=bool)
    if not has_wraps(p, m) or (m is not None and not m.any()):
        return p, False
    if decimate == 1:
        return _herraez(p, m).astype(np.float32), True
    f = decimate
    coarse = _herraez(p[::f, ::f], None if m is None else m[::f, ::f])
    guide = np.repeat(np.repeat(coarse, f, axis=0), f, axis=1)[: p.shape[0], : p.shape[1]]
    turns = np.round((guide - p) / TWO_PI)
    return (p + TWO_PI * turns).astype(np.float32), True


def unwrap_guided(
    phase: np.ndarray, guide: np.ndarray, mask: np.ndarray | None = None, *, scale: float = 1.0
) -> np.ndarray:
    """Unwrap a map against an unwrapped map of the same shape up to a constant and a scale.

    Used across peaks: ``guide`` is another peak's unwrapped phase and ``scale`` the
    ratio of the two alphas. The constant difference between the two (each map's own
    offset) is found as the circular mean of the wrapped difference, so only the
    *shape* of the guide matters; each pixel is then moved by whole turns to within
    pi of ``scale`` times the guide plus the constant.

    Parameters
    ----------
    phase : ndarray, shape (rows, cols)
        Wrapped phase (rad); not modified.
    guide : ndarray, shape (rows, cols)
        Continuous phase (rad); ``scale`` times it is expected to differ from the truth
        by a constant.
    mask : ndarray of bool, optional
        Pixels trusted for the constant.
    scale : float
        Factor applied to ``guide``.

    Returns
    -------
    ndarray of float32
        ``phase`` plus whole turns (rad).
    """
    p = np.asarray(phase, dtype=np.float32)
    g = np.asarray(guide, dtype=np.float32)
    if p.shape != g.shape or p.ndim != 2:
        raise InputError(f"phase {p.shape} and guide {g.shape} must be 2-D of one shape")
    k = np.float32(scale)
    # the constant from every 4th row and column (trusted ones): plenty for a mean
    sample = wrap(p[::4, ::4] - g[::4, ::4] * k)
    if mask is not None:
        sample = sample[np.asarray(mask, dtype=bool)[::4, ::4]]
    if sample.size == 0:
        sample = wrap(p - g * k)
    constant = float(np.angle(np.mean(np.exp(1j * sample))))
    # turns = rint((scale guide + constant - phase) / 2 pi), in place in one buffer
    turns = np.multiply(g, k)
    turns -= p
    turns += np.float32(constant)
    turns *= np.float32(1 / TWO_PI)
    np.rint(turns, out=turns)
    turns *= np.float32(TWO_PI)
    turns += p
    return turns


def phase_ratio(phase: np.ndarray, guide: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Estimate ``r`` in ``phase ~ r guide + constant`` from the maps' gradients.

    Neighbour differences of the wrapped ``phase`` (wrapped again, so valid while
    the phase moves less than pi per pixel) are regressed on those of the unwrapped
    ``guide`` smoothed over :data:`GUIDE_SMOOTHING` pixels (the noise of a regressor
    would bias the slope low), by least squares through zero on every 4th row,
    leaving out an edge of :data:`EDGE` pixels (where a non-periodic frame's field
    dips) and guide steps over pi/2. Between two peaks that see the same surface,
    ``r`` is the ratio of their alphas (paper eq. 3); about 1 % here for maps of a
    few hundred pixels.

    Parameters
    ----------
    phase : ndarray, shape (rows, cols)
        Wrapped phase (rad); not modified.
    guide : ndarray, shape (rows, cols)
        Unwrapped phase (rad) of another peak.
    mask : ndarray of bool, optional
        Pixels trusted in both.

    Returns
    -------
    float
        The ratio; 0 when the guide is flat (every ratio fits then).
    """
    if np.shape(phase) != np.shape(guide) or np.ndim(phase) != 2:
        raise InputError(
            f"phase {np.shape(phase)} and guide {np.shape(guide)} must be 2-D of one shape"
        )
    rows, cols = np.shape(phase)
    e = EDGE if min(rows, cols) > 4 * EDGE else 0
    inner = (slice(e, rows - e, 4), slice(e, cols - e))
    p = np.asarray(phase)[inner]
    # a noisy regressor biases the slope low (errors in variables): smooth the guide
    g = ndimage.uniform_filter1d(np.asarray(guide, dtype=np.float32), GUIDE_SMOOTHING, axis=0)
    g = ndimage.uniform_filter1d(g[inner], GUIDE_SMOOTHING, axis=1)
    dp = wrap(p[:, 1:] - p[:, :-1])
    dg = g[:, 1:] - g[:, :-1]
    keep = np.abs(dg) < np.pi / 2  # a steeper guide is noise or an edge, not surface
    if mask is not None:
        m = np.asarray(mask, dtype=bool)[inner]
        keep &= m[:, 1:] & m[:, :-1]
    dp = dp * keep
    dg = dg * keep
    energy = float(np.vdot(dg, dg))
    if energy <= 0:
        return 0.0
    return float(np.vdot(dg, dp)) / energy


def aperture_mask(
    shape: tuple[int, int],
    *,
    center: tuple[float, float] | None = None,
    radius: float | None = None,
) -> np.ndarray:
    """Return a disc-shaped aperture mask.

    Parameters
    ----------
    shape : tuple of int
        Mask shape ``(rows, cols)``.
    center : tuple of float, optional
        Disc centre ``(row, col)`` in pixels; the frame centre by default.
    radius : float, optional
        Disc radius in pixels; half the shorter side by default.

    Returns
    -------
    ndarray of bool
    """
    rows, cols = shape
    cy, cx = center if center is not None else ((rows - 1) / 2, (cols - 1) / 2)
    r = radius if radius is not None else min(rows, cols) / 2
    if r <= 0:
        raise InputError(f"aperture radius must be > 0 pixels, got {r}")
    y, x = np.ogrid[:rows, :cols]
    return (y - cy) ** 2 + (x - cx) ** 2 <= r * r
