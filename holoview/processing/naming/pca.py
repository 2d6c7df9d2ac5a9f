"""Principal component analysis of the phases of many peaks (paper section 3.2, supplement IV).

Every peak ``m`` sees the same surface: a change ``delta_h`` of the height moves its
phase by ``2 k0 alpha_m delta_h`` (``k0 = 2 pi / wavelength``). Stacked as a vector over
the ``M`` peaks, the phases therefore move along one fixed axis ``v = (alpha_1, ...,
alpha_M)``: the principal component of their covariance. Its eigenvalue share is the
confidence ``sg_p`` of the paper (main text definition, between 0 and 1); the ratios of
its entries are the ratios of the prefactors, so one known prefactor gives them all.

The samples are frames (temporal PCA: the mean phase of each peak per frame, unwrapped in
time) or pixels (spatial PCA: the unwrapped phase maps of the peaks at one time). A
missing sample (NaN) removes that frame or pixel for every peak.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError

logger = logging.getLogger(__name__)

__all__ = ["PhasePCA", "phase_pca", "spatial_phase_pca", "temporal_phase_pca"]


@dataclass(frozen=True)
class PhasePCA:
    """The principal component of the phases of ``M`` peaks.

    Attributes
    ----------
    component : ndarray of float, shape (M,)
        The principal eigenvector, unit length. Its overall sign is arbitrary until a
        labelled peak fixes it (:meth:`prefactors`); the relative signs between peaks
        are meaningful.
    eigenvalues : ndarray of float, shape (M,)
        Eigenvalues of the covariance, descending, in rad^2.
    confidence : float
        ``sg_p = lambda_p / sum(lambda)``: 1 when all variation lies along the component.
    explained : ndarray of float, shape (M,)
        Per peak, the fraction of its phase variance that the component carries
        (``lambda_p v_m^2 / C_mm``, between 0 and 1). A peak with a low value is weakly
        correlated with the surface (the paper's grey points).
    std : ndarray of float, shape (M,)
        Standard deviation of each peak's phase over the samples, in rad.
    n_samples : int
        Number of frames or pixels used (those finite for every peak).
    """

    component: NDArray[np.float64]
    eigenvalues: NDArray[np.float64]
    confidence: float
    explained: NDArray[np.float64]
    std: NDArray[np.float64]
    n_samples: int

    def ratios(self, reference: int) -> NDArray[np.float64]:
        """Return ``v_m / v_reference``: each peak's prefactor over the reference peak's.

        Parameters
        ----------
        reference : int
            Index of the peak the ratios are taken against.

        Raises
        ------
        InputError
            If the index is out of range, or the reference peak does not move with the
            component (its entry is zero: it cannot fix the others).
        """
        n_peaks = self.component.size
        if not -n_peaks <= reference < n_peaks:
            raise InputError(f"reference peak {reference} is not one of the {n_peaks} peaks")
        ref = self.component[reference]
        if abs(ref) < 1e-6 * np.max(np.abs(self.component)):
            raise InputError(
                f"reference peak {reference} is uncorrelated with the principal component; "
                "label another peak"
            )
        return self.component / ref

    def prefactors(self, reference: int, alpha: float) -> NDArray[np.float64]:
        """Return every peak's prefactor alpha, given the reference peak's.

        The global sign comes from the labelled peak: with ``alpha > 0`` for it, a peak
        whose phase moves the other way gets a negative prefactor (it sits on the other
        twin of the twin rule and can be flipped).

        Parameters
        ----------
        reference : int
            Index of the labelled peak (e.g. the brightest, RB1).
        alpha : float
            Its prefactor (dimensionless, e.g. ``n2 - n1`` for RB1).
        """
        return self.ratios(reference) * float(alpha)


def phase_pca(samples: ArrayLike) -> PhasePCA:
    """Principal component of phases given as ``(samples, peaks)``.

    Parameters
    ----------
    samples : array_like of float, shape (N, M)
        Unwrapped phases in rad: ``N`` frames or pixels, ``M`` peaks. Rows with a NaN
        in any column are left out.

    Returns
    -------
    PhasePCA

    Raises
    ------
    InputError
        With fewer than two peaks, fewer than two common samples, or no variation.
    """
    data = np.asarray(samples, dtype=np.float64)
    if data.ndim != 2:
        raise InputError(f"phases must be a 2-D array (samples, peaks), got shape {data.shape}")
    n_total, n_peaks = data.shape
    if n_peaks < 2:
        raise InputError(f"PCA needs at least two peaks, got {n_peaks}")
    if n_total < 2:
        raise InputError(f"PCA needs at least two frames or pixels, got {n_total}")
    common = np.all(np.isfinite(data), axis=1)
    n_common = int(np.count_nonzero(common))
    if n_common == 0:
        raise InputError("the peaks have no common frames or pixels (every row has a NaN)")
    if n_common < 2:
        raise InputError(f"the peaks share only {n_common} frame or pixel; PCA needs two")
    used = data[common]
    centred = used - used.mean(axis=0)
    covariance = centred.T @ centred / (n_common - 1)
    variances = np.diag(covariance).copy()
    total = float(np.sum(variances))
    if total <= 0.0:
        raise InputError("the phases do not vary: PCA has nothing to align")
    eigenvalues, eigenvectors = np.linalg.eigh(covariance)
    order = np.argsort(eigenvalues)[::-1]
    eigenvalues = np.clip(eigenvalues[order], 0.0, None)
    component = eigenvectors[:, order[0]]
    # A deterministic sign: the largest entry positive (the labelled peak fixes it later).
    component = component * np.sign(component[np.argmax(np.abs(component))])
    explained = eigenvalues[0] * component**2 / np.where(variances > 0, variances, np.inf)
    result = PhasePCA(
        component=component,
        eigenvalues=eigenvalues,
        confidence=float(eigenvalues[0] / np.sum(eigenvalues)),
        explained=np.clip(explained, 0.0, 1.0),
        std=np.sqrt(variances),
        n_samples=n_common,
    )
    if n_common < n_total:
        logger.debug("PCA used %d of %d samples (others had NaN)", n_common, n_total)
    return result


def temporal_phase_pca(series: ArrayLike) -> PhasePCA:
    """Temporal PCA: the phases of ``M`` peaks over ``N`` frames.

    Parameters
    ----------
    series : array_like of float, shape (N, M)
        Per frame and peak, the mean phase unwrapped in time, in rad (for example
        :func:`holoview.processing.series.phase_series.unwrap_in_time`). NaN marks a frame where the
        peak was not measured.
    """
    return phase_pca(series)


def spatial_phase_pca(maps: ArrayLike, mask: ArrayLike | None = None) -> PhasePCA:
    """Spatial PCA: the phase maps of ``M`` peaks over the pixels of one time.

    Parameters
    ----------
    maps : array_like of float, shape (M, rows, cols)
        Unwrapped phase maps in rad, registered on common pixels. NaN marks a pixel
        a peak does not cover.
    mask : array_like of bool, shape (rows, cols), optional
        Pixels to use (True); all by default.
    """
    stack = np.asarray(maps, dtype=np.float64)
    if stack.ndim != 3:
        raise InputError(f"phase maps must be a 3-D stack (peaks, rows, cols), got {stack.shape}")
    samples = stack.reshape(stack.shape[0], -1).T
    if mask is not None:
        keep = np.asarray(mask, dtype=bool)
        if keep.shape != stack.shape[1:]:
            raise InputError(f"mask shape {keep.shape} does not match the maps {stack.shape[1:]}")
        samples = samples[keep.ravel()]
    return phase_pca(samples)
