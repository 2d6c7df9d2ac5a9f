"""Vectorised phase of complex maps, several times faster than ``np.angle`` for float32.

numpy's ``arctan2`` runs the scalar libm routine per element (about 30 ns here),
which at four 144 x 144 maps per frame costs more than the frame's whole FFT.
:func:`angle` evaluates the same function with a few SIMD-friendly array passes:
octant reduction to ``t = min(|x|, |y|) / max(|x|, |y|)`` in [0, 1], an odd
polynomial for ``arctan(t)`` (least-maximum-error fit of degree 13 on [0, 1], made
for this module; error below 3e-7 rad, under float32's own rounding of the
phase), then the octant restored.
"""

from __future__ import annotations

import numpy as np

#: Coefficients of ``t, t^3, ..., t^13`` approximating ``arctan(t)`` on [0, 1].
_ATAN_COEFFICIENTS = (
    0.999996112,
    -0.333173694,
    0.198078283,
    -0.132333916,
    0.0796245939,
    -0.0336050337,
    0.00681206669,
)

#: Largest difference from ``np.arctan2`` (rad), in float64 arithmetic.
MAX_ERROR = 3e-7

_COEFFICIENTS32 = tuple(np.float32(c) for c in _ATAN_COEFFICIENTS)


class AngleWorkspace:
    """Scratch buffers for :func:`angle` on maps of one shape (reuse it frame after frame).

    Fresh temporaries of a few hundred kilobytes cost page faults that, measured
    here, made the computation 4 times slower than the arithmetic itself.
    """

    def __init__(self, shape: tuple[int, int]) -> None:
        self.shape = (int(shape[0]), int(shape[1]))
        self._buffers = [np.empty(self.shape, dtype=np.float32) for _ in range(6)]


def angle(
    z: np.ndarray, *, out: np.ndarray | None = None, workspace: AngleWorkspace | None = None
) -> np.ndarray:
    """Return the phase of complex values in (-pi, pi], like ``np.angle``, as float32.

    Parameters
    ----------
    z : ndarray of complex64 or complex128, 2-D
        Complex values; not modified. ``angle(0) == 0``.
    out : ndarray of float32, optional
        Where to write the result (shape of ``z``); a new array by default.
    workspace : AngleWorkspace, optional
        Scratch buffers of ``z``'s shape, to avoid allocating them.

    Returns
    -------
    ndarray of float32, shape of ``z``
        Phase (rad), within :data:`MAX_ERROR` of ``np.angle(z)`` plus float32 rounding.
    """
    z = np.asarray(z)
    if workspace is None or workspace.shape != z.shape:
        workspace = AngleWorkspace(z.shape)
    if out is None:
        out = np.empty(z.shape, dtype=np.float32)
    x, y, ax, ay, t, r = workspace._buffers
    np.copyto(x, z.real, casting="same_kind")
    np.copyto(y, z.imag, casting="same_kind")
    np.abs(x, out=ax)
    np.abs(y, out=ay)
    np.minimum(ax, ay, out=t)
    np.maximum(ax, ay, out=out)
    out += np.float32(1e-30)  # 0 / tiny = 0 at the origin, and no division by zero
    t /= out
    s = out
    np.multiply(t, t, out=s)
    r.fill(_COEFFICIENTS32[-1])
    for c in reversed(_COEFFICIENTS32[:-1]):
        r *= s
        r += c
    r *= t
    # masked ufunc calls and np.where are slow: restore octants by arithmetic on 0/1 factors
    fix = s
    np.multiply(r, np.float32(-2), out=fix)
    fix += np.float32(np.pi / 2)
    fix *= np.greater(ay, ax)
    r += fix
    np.multiply(r, np.float32(-2), out=fix)
    fix += np.float32(np.pi)
    fix *= np.less(x, 0)
    r += fix
    return np.copysign(r, y, out=out)
