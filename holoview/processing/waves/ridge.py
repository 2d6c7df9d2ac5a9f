"""The ridge of an omega-k spectrum: in each wave-vector cell, the frequency of its wave.

:func:`find_ridge` takes, in every cell of the wave-vector plane between ``k_min`` and
``k_max``, the frequency of most power (interpolated between bins on the logarithm of
the power), where it stands ``min_contrast`` times above the cell's median power and
above its eight neighbours'. With few segments averaged, noise alone passes a contrast
of 10 in many cells: :func:`noise_contrast` gives the contrast it seldom reaches.

Each cell also says whether its line is **sharp**: as narrow as one wave's under the
Hann tapers of :mod:`~holoview.processing.waves.omega_k`, in frequency and in both
wave-vector directions. The curvature of the logarithm of a Hann line's power over
three bins is -2.77 (the wave on a bin) to -3.22 (half-way between two); a cell whose
curvature is flatter than :data:`SHARP` in any direction holds more than one line: the
spatial taper spreads each wave over about two cells either way, so in a field of many
waves the cell's peak is a blend of its own wave and its neighbours', and the
interpolated frequency is pulled towards theirs. Where the wavenumbers are few
(near the lowest), most neighbours lie outward, at higher frequencies, so the pull is
mostly upwards: on 300 simulated waves between 300 and 1800 rad/m (84 mm field, 256
cells a side, 128-frame segments) the blended cells below 700 rad/m stood 0.05 to 0.1
of a frequency bin above their wave, the sharp ones 0.02, and a fit on every cell put
the depth 2.5 % too deep on average (up to 6 %) against 0.7 % on the sharp cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.special import gammainccinv, gammaincinv

from holoview.processing.waves.omega_k import OmegaKSpectrum

__all__ = ["FALSE_CELLS", "SHARP", "Ridge", "find_ridge", "noise_contrast"]

#: Cells of noise alone expected to pass :func:`noise_contrast`'s contrast in a band.
FALSE_CELLS = 0.5

#: The flattest log-power curvature (over three bins) of a cell's line in frequency and
#: in each wave-vector direction for the line to be one wave's (module docstring; one
#: line under a Hann taper gives -2.77 to -3.22).
SHARP = -2.5


@dataclass(frozen=True)
class Ridge:
    """The frequency of most power in each wave-vector cell with a clear wave.

    Attributes
    ----------
    kx, ky : ndarray of float, shape (L,)
        Wave vector of each cell, rad/m (the direction the wave travels).
    omega : ndarray of float, shape (L,)
        Ridge frequency, rad/s.
    contrast : ndarray of float, shape (L,)
        Peak power over the cell's median power.
    sharp : ndarray of bool, shape (L,)
        The cell's line is one wave's (module docstring), not a blend of neighbours'.
    """

    kx: NDArray[np.float64]
    ky: NDArray[np.float64]
    omega: NDArray[np.float64]
    contrast: NDArray[np.float64]
    sharp: NDArray[np.bool_]

    def select(self, keep: NDArray[np.bool_]) -> Ridge:
        """Return the cells where ``keep`` is True."""
        return Ridge(
            self.kx[keep], self.ky[keep], self.omega[keep], self.contrast[keep], self.sharp[keep]
        )


def _vertex(left: np.ndarray, right: np.ndarray, curvature: np.ndarray) -> np.ndarray:
    """Offset (bins) of the vertex of the parabola through three log-powers (0 if none),
    from the outer two and the curvature ``left - 2 centre + right``."""
    concave = curvature < 0
    return np.where(concave, 0.5 * (left - right) / np.where(concave, curvature, -1.0), 0.0)


def find_ridge(
    spectrum: OmegaKSpectrum,
    model: NDArray[np.float64] | None = None,
    *,
    k_min: float,
    k_max: float,
    search: float = 0.15,
    min_contrast: float = 10.0,
) -> Ridge:
    """Return the ridge of an omega-k spectrum between ``k_min`` and ``k_max`` (rad/m).

    In each wave-vector cell, the frequency bin of most power; the cells kept are
    those whose peak power is the largest of their eight neighbours' and
    ``min_contrast`` times their median power (a wave's own cell, not the cells its
    taper spreads it into). The frequency and both wave-vector components are
    refined between bins by the vertex of a parabola through the logarithm of the
    power (exact for a Gaussian line, within a few hundredths of a bin for Hann's).

    Parameters
    ----------
    spectrum : OmegaKSpectrum
    model : ndarray of float, shape (R, C), optional
        Expected frequency of every cell, rad/s: the peak is sought within
        ``search`` of it (at least 3 bins either side). Without it, over every
        frequency but the two lowest and the highest bins.
    k_min, k_max : float
        Wavenumbers of the cells considered, rad/m.
    search : float
        Relative half-width of the search around the model.
    min_contrast : float
        Least ratio of a cell's peak power to its median power.

    Examples
    --------
    A single noiseless plane wave: its leakage stands out of the nothing in other
    cells too, but only its own cell's line is sharp:

    >>> from holoview.processing.waves.omega_k import OmegaKAccumulator
    >>> y, x = np.mgrid[0:32, 0:32] * 1e-3
    >>> acc = OmegaKAccumulator((32, 32), 1e-3, 0.01, segment=32)
    >>> for i in range(64):
    ...     acc.push(np.cos(1000.0 * x - 100.0 * i * 0.01), i * 0.01)
    >>> ridge = find_ridge(acc.spectrum(), k_min=100.0, k_max=2000.0)
    >>> int(ridge.sharp.size) > 1
    True
    >>> wave = ridge.select(ridge.sharp)
    >>> wave.omega.round(0).tolist(), wave.kx.round(-1).tolist(), wave.ky.round(-1).tolist()
    ([100.0], [1000.0], [0.0])
    """
    power = spectrum.power
    n_f, rows, cols = power.shape
    step = 2.0 * np.pi * spectrum.df
    if model is None:
        low = np.full((rows, cols), 2.0)
        high = np.full((rows, cols), n_f - 2.0)
    else:
        half = np.maximum(search * np.abs(model), 3.0 * step)
        low = np.maximum(np.floor((model - half) / step), 2.0)
        high = np.minimum(np.ceil((model + half) / step), n_f - 2.0)
    index = np.arange(n_f)[:, np.newaxis, np.newaxis]
    peak = np.argmax(np.where((index >= low) & (index <= high), power, -1.0), axis=0)
    top = np.take_along_axis(power, peak[np.newaxis], axis=0)[0].astype(np.float64)
    floor = np.median(power[1:], axis=0).astype(np.float64)
    tiny = np.finfo(np.float64).tiny
    contrast = top / np.maximum(floor, tiny)
    padded = np.pad(top, 1, constant_values=np.inf)
    neighbours = np.max(
        [
            padded[1 + dy : 1 + dy + rows, 1 + dx : 1 + dx + cols]
            for dy in (-1, 0, 1)
            for dx in (-1, 0, 1)
            if dy or dx
        ],
        axis=0,
    )
    k = spectrum.k
    keep = (
        (top > neighbours)
        & (contrast >= min_contrast)
        & (peak > low)
        & (peak < high)
        & (k >= k_min)
        & (k <= min(k_max, spectrum.k_cut))
    )
    keep[[0, -1], :] = False
    keep[:, [0, -1]] = False
    iy, ix = np.nonzero(keep)
    f = peak[iy, ix]

    def log_power(fi: np.ndarray, yi: np.ndarray, xi: np.ndarray) -> np.ndarray:
        return np.log(np.maximum(power[fi, yi, xi].astype(np.float64), tiny))

    centre = log_power(f, iy, ix)
    sides = [
        (log_power(f - 1, iy, ix), log_power(f + 1, iy, ix)),
        (log_power(f, iy - 1, ix), log_power(f, iy + 1, ix)),
        (log_power(f, iy, ix - 1), log_power(f, iy, ix + 1)),
    ]
    curvatures = [a - 2.0 * centre + b for a, b in sides]
    shift_f, shift_y, shift_x = (
        _vertex(a, b, c) for (a, b), c in zip(sides, curvatures, strict=True)
    )
    sharp = np.all([c <= SHARP for c in curvatures], axis=0)
    good = (np.abs(shift_f) <= 1) & (np.abs(shift_y) <= 1) & (np.abs(shift_x) <= 1)
    dky, dkx = spectrum.dk
    return Ridge(
        (spectrum.kx[ix] + shift_x * dkx)[good],
        (spectrum.ky[iy] + shift_y * dky)[good],
        ((f + shift_f) * step)[good],
        contrast[iy, ix][good],
        sharp[good],
    )


def noise_contrast(spectrum: OmegaKSpectrum, k_min: float, k_max: float) -> float:
    """The contrast (peak over median power) that noise alone reaches in a band of cells.

    A Welch average of ``S`` segments puts the power of noise in each bin on a gamma
    law of ``S`` degrees of freedom per bin's real and imaginary parts together; taken
    here with half of them (``S / 2``: overlapping segments are not independent, and a
    cell's median is of a few bins), the contrast that :data:`FALSE_CELLS` cells of the
    band ``k_min`` to ``k_max`` pass by chance, over every frequency searched. From
    about four segments it is below the fit's 10; with one or two, on maps of 180^2
    and 256^2 pixels, 10 let 11 to 45 cells of white noise through, enough for a fit
    that ran away, where this contrast (19 to 54) let none or one.

    Examples
    --------
    >>> from holoview.processing.waves.omega_k import OmegaKAccumulator
    >>> rng = np.random.default_rng(0)
    >>> acc = OmegaKAccumulator((64, 64), 1e-3, 0.01, segment=16)
    >>> for i in range(16):
    ...     acc.push(rng.normal(size=(64, 64)), i * 0.01)
    >>> round(noise_contrast(acc.spectrum(), 100.0, 3000.0))  # one segment
    39
    """
    cells = int(np.count_nonzero((spectrum.k >= k_min) & (spectrum.k <= k_max)))
    bins = max(spectrum.power.shape[0] - 3, 1)  # the bins find_ridge searches
    shape = max(spectrum.segments, 1) / 2.0
    chance = FALSE_CELLS / max(cells * bins, 1)
    return float(gammainccinv(shape, chance) / gammaincinv(shape, 0.5))
