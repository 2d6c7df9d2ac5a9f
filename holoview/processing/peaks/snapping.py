"""One rule for naming a detected peak by a carrier: the nearest, on either twin, within a few bins.

A carrier a user gives (a click on the spectrum, a label following a peak that drifts
between detections, a carrier typed from ``holoview peaks``, an experiment file's) names
the detected peak nearest it on the periodic spectrum, on either twin, no further than
:data:`SNAP_BINS` FFT bins. The live window, ``holoview process`` and the lattice's labels
all call :func:`snap`. Carriers are in cycles per pixel, ``(fx, fy)``; one FFT bin is
``1 / cols`` by ``1 / rows``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["SNAP_BINS", "bin_distance", "snap"]

#: A carrier names the detected peak nearest it within this many FFT bins (either twin).
#: Wide enough for a click on a peak drawn a few screen pixels across, a label following
#: a peak that drifts between detections, and a carrier typed to four decimals; narrow
#: enough that it cannot reach a neighbour two window radii away at 256^2 and above.
SNAP_BINS = 12.0


def bin_distance(delta: ArrayLike, shape: tuple[int, int]) -> NDArray[np.float64]:
    """Length in FFT bins of carrier differences ``(..., 2)`` (cycles/pixel), wrapped."""
    d = np.asarray(delta, dtype=np.float64)
    d = d - np.rint(d)  # the periodic spectrum; a distance needs no sign at 0.5
    return np.hypot(d[..., 0] * shape[1], d[..., 1] * shape[0])


def snap(
    carrier: Sequence[float] | NDArray[np.float64],
    carriers: Sequence[Sequence[float]] | NDArray[np.float64],
    shape: tuple[int, int],
    tolerance: float = SNAP_BINS,
) -> tuple[int, bool] | None:
    """Return ``(index, twin)`` of the carrier in ``carriers`` nearest ``carrier``.

    Parameters
    ----------
    carrier : (float, float)
        Where the operator or a file points, cycles/pixel.
    carriers : sequence of (float, float)
        Detected carriers, cycles/pixel (either twin counts).
    shape : tuple of int
        Frame shape ``(rows, cols)``, pixels.
    tolerance : float
        Largest distance, FFT bins.

    Returns
    -------
    (int, bool) or None
        The index, and True when ``carrier`` points at that peak's other twin; None when
        no detected carrier lies within ``tolerance`` bins.
    """
    points = np.asarray(carriers, dtype=np.float64).reshape(-1, 2)
    if points.shape[0] == 0:
        return None
    target = np.asarray(carrier, dtype=np.float64)
    direct = bin_distance(points - target, shape)
    mirrored = bin_distance(points + target, shape)
    best = int(np.argmin(np.minimum(direct, mirrored)))
    if min(direct[best], mirrored[best]) > tolerance:
        return None
    return best, bool(mirrored[best] < direct[best])
