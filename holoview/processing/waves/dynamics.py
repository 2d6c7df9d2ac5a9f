"""Surface waves from a sequence of height maps: the space-time spectrum and dispersion.

A sequence of delta-h maps is a sampled wave field ``h(t, y, x)``. Its three-dimensional
Fourier transform, averaged over the direction of the wave vector, gives the power
``P(omega, k)`` against the angular frequency ``omega`` (rad/s) and the wavenumber
``k = |k|`` (rad/m). Free surface waves put their power on the capillary-gravity
dispersion relation (:func:`holoview.optics.surfaces.dispersion_omega`)

    omega^2 = (g k + sigma k^3 / rho) tanh(k d)

for depth ``d`` (m), surface tension ``sigma`` (N/m), density ``rho`` (kg/m^3) and
gravity ``g`` (m/s^2). :func:`compare_dispersion` finds the ridge of the measured power
(the frequency of most power at each wavenumber) and sets it against the model. The paper
names this use in its conclusion; holoview is the tool that offers it.

Both the time and space axes are tapered with a Hann window before the transform, so
that the finite record and field of view leak little power off the ridge. Maps of the
relative reconstruction (height steps between frames) work as well as absolute ones:
the ridge is the same, only the weighting over ``omega`` differs.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError
from holoview.optics.surfaces import GRAVITY, dispersion_omega

logger = logging.getLogger(__name__)

__all__ = [
    "DispersionComparison",
    "SpaceTimeSpectrum",
    "compare_dispersion",
    "space_time_spectrum",
]


@dataclass(frozen=True)
class SpaceTimeSpectrum:
    """Power of a wave field against frequency and wavenumber.

    Attributes
    ----------
    omega : ndarray of float, shape (F,)
        Angular frequencies in rad/s, from 0 to the Nyquist frequency.
    k : ndarray of float, shape (K,)
        Wavenumbers in rad/m at the centres of the radial bins (width: one cell of the
        larger map side), from 0 to the Nyquist wavenumber of the pixel grid.
    power : ndarray of float, shape (F, K)
        Mean spectral power of the cells of each radial bin, in m^2, waves travelling
        either way together (for display).
    cell_k : ndarray of float, shape (rows, cols)
        Wavenumber in rad/m of every spatial-frequency cell (numpy's FFT order).
    cell_bin : ndarray of int, shape (rows, cols)
        Radial bin of every cell (``K`` or more beyond the Nyquist wavenumber).
    cell_omega : ndarray of float, shape (rows, cols)
        Ridge frequency of every cell in rad/s: the power-weighted mean frequency over
        the frequencies whose power is at least a tenth of the cell's maximum.
    cell_peak : ndarray of float, shape (rows, cols)
        Maximum power of every cell over the non-zero frequencies, in m^2.
    cell_contrast : ndarray of float, shape (rows, cols)
        ``cell_peak`` over the cell's median power (dimensionless): small where no
        wave is.
    """

    omega: NDArray[np.float64]
    k: NDArray[np.float64]
    power: NDArray[np.float64]
    cell_k: NDArray[np.float64]
    cell_bin: NDArray[np.intp]
    cell_omega: NDArray[np.float64]
    cell_peak: NDArray[np.float64]
    cell_contrast: NDArray[np.float64]

    @property
    def omega_step(self) -> float:
        """Frequency resolution in rad/s."""
        return float(self.omega[1] - self.omega[0])


#: Share of a cell's maximum power a frequency needs to count in the cell's ridge.
RIDGE_LEVEL = 0.1


def _hann(n: int) -> NDArray[np.float64]:
    """A periodic Hann window of ``n`` samples (the symmetric one ends on zeros)."""
    return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)


def space_time_spectrum(
    maps: ArrayLike, frame_interval: float, pixel_size: float
) -> SpaceTimeSpectrum:
    """Space-time power spectrum of a sequence of height maps.

    Parameters
    ----------
    maps : array_like of float, shape (N, rows, cols)
        Height (or height-change) maps in m, evenly spaced in time; each pixel's mean
        over time is removed first. NaN is not allowed (fill masked pixels first).
    frame_interval : float
        Time between frames in s.
    pixel_size : float
        Pixel pitch on the fluid surface in m (square pixels).

    Returns
    -------
    SpaceTimeSpectrum

    Raises
    ------
    InputError
        For fewer than four frames, maps smaller than 4 x 4, NaN values or
        non-positive spacings.

    Notes
    -----
    Works on the whole stack at once: peak memory is about 6 times the input's size in
    float64 (600 maps of 128 x 128, 79 MB, peak at about 0.45 GB); pass maps at the demodulator's
    box resolution rather than upsampled ones.
    """
    field = np.asarray(maps, dtype=np.float64)
    if field.ndim != 3:
        raise InputError(f"maps must be a (frames, rows, cols) stack, got shape {field.shape}")
    n_frames, rows, cols = field.shape
    if n_frames < 4:
        raise InputError(f"a space-time spectrum needs at least 4 frames, got {n_frames}")
    if rows < 4 or cols < 4:
        raise InputError(f"maps of {rows} x {cols} pixels are too small (at least 4 x 4)")
    if not np.all(np.isfinite(field)):
        raise InputError("the maps contain NaN or infinity; fill masked pixels first")
    if not (frame_interval > 0 and pixel_size > 0):
        raise InputError(
            f"frame interval ({frame_interval} s) and pixel size ({pixel_size} m) must be positive"
        )
    taper = (
        _hann(n_frames)[:, np.newaxis, np.newaxis]
        * _hann(rows)[np.newaxis, :, np.newaxis]
        * _hann(cols)[np.newaxis, np.newaxis, :]
    )
    tapered = (field - field.mean(axis=0)) * taper
    # Real transform over time (axis 0, listed last): frequencies 0 .. Nyquist only.
    spectrum = np.fft.rfftn(tapered, axes=(1, 2, 0))
    power = (spectrum.real**2 + spectrum.imag**2) / float(np.sum(taper**2))
    n_omega = power.shape[0]
    # Per cell, waves travelling either way: the cell and its mirror -k together.
    mirror = power[:, (-np.arange(rows)) % rows][:, :, (-np.arange(cols)) % cols]
    both = (power + mirror)[1:]
    cell_peak = both.max(axis=0)
    median = np.median(both, axis=0)
    cell_contrast = np.where(median > 0, cell_peak / np.where(median > 0, median, 1.0), np.inf)
    weights = np.where(both >= RIDGE_LEVEL * cell_peak, both, 0.0)
    index = np.arange(1, n_omega, dtype=np.float64)[:, np.newaxis, np.newaxis]
    total = weights.sum(axis=0)
    omega_step = 2.0 * np.pi / (n_frames * frame_interval)
    cell_omega = (weights * index).sum(axis=0) / np.where(total > 0, total, 1.0) * omega_step
    # Radial bins of width 1 / max(rows, cols) cycles per pixel, up to Nyquist.
    fy = np.fft.fftfreq(rows)[:, np.newaxis]
    fx = np.fft.fftfreq(cols)[np.newaxis, :]
    size = max(rows, cols)
    bins = np.rint(np.hypot(fy, fx) * size).astype(np.intp)
    n_k = size // 2 + 1
    flat_bins = bins.ravel()
    inside = flat_bins < n_k
    counts = np.bincount(flat_bins[inside], minlength=n_k).astype(np.float64)
    radial = np.stack(
        [
            np.bincount(flat_bins[inside], weights=row.ravel()[inside], minlength=n_k)
            for row in power
        ]
    ) / np.where(counts > 0, counts, 1.0)
    return SpaceTimeSpectrum(
        omega=np.arange(n_omega) * omega_step,
        k=2.0 * np.pi * np.arange(n_k) / (size * pixel_size),
        power=radial,
        cell_k=2.0 * np.pi * np.hypot(fy, fx) / pixel_size,
        cell_bin=bins,
        cell_omega=cell_omega,
        cell_peak=cell_peak,
        cell_contrast=cell_contrast,
    )


@dataclass(frozen=True)
class DispersionComparison:
    """Measured ridge against the capillary-gravity dispersion relation.

    Attributes
    ----------
    k : ndarray of float, shape (L,)
        Wavenumbers compared, in rad/m (centres of the radial bins with waves).
    omega_measured : ndarray of float, shape (L,)
        Ridge frequency in rad/s, averaged over the bin's cells weighted by their power.
    omega_model : ndarray of float, shape (L,)
        Model frequency in rad/s at the same cells, with the same weights.
    relative_deviation : ndarray of float, shape (L,)
        ``omega_measured / omega_model - 1``.
    rms_deviation : float
        RMS over the cells compared of their relative deviations, weighted by their
        power (dimensionless).
    power_near_model : float
        Share of the power of the cells compared whose ridge lies within two frequency
        bins of the model (0 to 1).
    """

    k: NDArray[np.float64]
    omega_measured: NDArray[np.float64]
    omega_model: NDArray[np.float64]
    relative_deviation: NDArray[np.float64]
    rms_deviation: float
    power_near_model: float


def compare_dispersion(
    spectrum: SpaceTimeSpectrum,
    depth: float,
    surface_tension: float,
    density: float,
    gravity: float = GRAVITY,
    *,
    min_contrast: float = 20.0,
) -> DispersionComparison:
    """Compare the ridge of a space-time spectrum with the capillary-gravity dispersion.

    Each spatial-frequency cell is compared at its own wavenumber (a radial bin spans
    frequencies several bins apart at small k), then the cells are gathered by bin. Only
    cells whose power is a local maximum among their eight neighbours count: the spatial
    taper spreads each wave over its neighbours, at the wave's frequency, not theirs.

    Parameters
    ----------
    spectrum : SpaceTimeSpectrum
    depth : float
        Fluid depth in m.
    surface_tension : float
        Surface tension in N/m.
    density : float
        Fluid density in kg/m^3.
    gravity : float
        Gravitational acceleration in m/s^2.
    min_contrast : float
        Cells whose peak power is below this multiple of their median power are left
        out (no wave there), as are ``k = 0``, cells beyond the Nyquist wavenumber and
        cells whose model frequency is within one bin of the Nyquist frequency.

    Returns
    -------
    DispersionComparison

    Raises
    ------
    InputError
        When no cell has a clear ridge.
    """
    model = np.asarray(
        dispersion_omega(spectrum.cell_k, depth, g=gravity, sigma=surface_tension, rho=density)
    )
    n_k = spectrum.k.size
    step = spectrum.omega_step
    peak = spectrum.cell_peak
    neighbours = np.max(
        [np.roll(peak, (dy, dx), axis=(0, 1)) for dy in (-1, 0, 1) for dx in (-1, 0, 1)],
        axis=0,
    )
    keep = (
        (peak >= neighbours)
        & (spectrum.cell_k > 0)
        & (spectrum.cell_bin < n_k)
        & (spectrum.cell_contrast >= min_contrast)
        & (model > step)
        & (model < spectrum.omega[-1] - step)
    )
    if not np.any(keep):
        raise InputError(
            f"no wave to compare: no spatial frequency has a ridge {min_contrast:g} times "
            "above its median power within the Nyquist frequency"
        )
    weight = spectrum.cell_peak[keep]
    measured = spectrum.cell_omega[keep]
    expected = model[keep]
    bins = spectrum.cell_bin[keep]
    deviation = measured / expected - 1.0
    total = float(weight.sum())
    rms = float(np.sqrt(np.sum(weight * deviation**2) / total))
    near = float(weight[np.abs(measured - expected) <= 2.0 * step].sum() / total)
    bin_weight = np.bincount(bins, weights=weight, minlength=n_k)
    used = bin_weight > 0
    omega_measured = np.bincount(bins, weights=weight * measured, minlength=n_k)[used]
    omega_model = np.bincount(bins, weights=weight * expected, minlength=n_k)[used]
    omega_measured /= bin_weight[used]
    omega_model /= bin_weight[used]
    logger.info(
        "dispersion over %d cells: RMS deviation %.3g, %.3g of the power near the model",
        int(np.count_nonzero(keep)),
        rms,
        near,
    )
    return DispersionComparison(
        k=spectrum.k[used],
        omega_measured=omega_measured,
        omega_model=omega_model,
        relative_deviation=omega_measured / omega_model - 1.0,
        rms_deviation=rms,
        power_near_model=near,
    )
