"""What windows are matched to: the change a run's maps show, on a few frames and on many.

A peak's map is the phase of the spectrum around its carrier against a reference
(:mod:`holoview.processing.peaks.matched` chooses its window). What the map must show is
measured on the frames the demodulator itself sees (:func:`measure_spectrum`): a frame
and the reference the maps are taken against (the change), or a frame alone for
synthetic phases; the noise floor is the quiet part of the change's spectrum
(:func:`_noise_floor`).

A few frames show what stands above one frame's noise. A wave field coherent in time
(partial waves, a driven mode) can stand above the noise only over many frames: the
analyses that follow the maps (:mod:`holoview.processing.waves`) average it out of the
noise over the run, so the windows must pass it too. :class:`ChangeAverage` therefore
accumulates, frame after frame, the change around each carrier (turned by the carrier's
mean phase change, as the demodulator turns it) over many frames spread over the run
(:data:`MEAN_FRAMES`): its mean power and its variance over the frames
(:class:`MeanChange`). The variance is what changes from frame to frame (the reference's
own noise, common to every frame's change, drops out of it); its noise floor is the
frames' own, and the standard error of an annulus's variance is that floor over the
square root of the frames (a sqrt(M) finer test than one frame's power against its
noise).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import special

from holoview.errors import InputError
from holoview.processing.fourier.spectrum import rfft2
from holoview.processing.fourier.windows import auto_radii

__all__ = [
    "CENTRE_BINS",
    "MEAN_FRAMES",
    "MEASURABLE_SIGMAS",
    "ChangeAverage",
    "MeanChange",
    "SurfaceSpectrum",
    "average_change",
    "chi2_median",
    "measure_spectrum",
]

#: Radius (FFT bins) of a carrier's central bins: its own power (the peak of a sub-bin
#: carrier spreads over the bins next to it), and its mean phase change.
CENTRE_BINS = 2.0

#: Surface power counts as measured when the excess over the noise outside the carrier's
#: main lobe is this many standard errors of the noise above zero.
MEASURABLE_SIGMAS = 5.0

#: Frames whose change around each carrier is averaged (:class:`ChangeAverage`): a
#: wave field is judged against the noise of a mean over this many frames.
MEAN_FRAMES = 32

#: Fraction of its widest window (and :data:`CENTRE_BINS` bins) kept around each carrier
#: beyond that window, so that the bound of a carrier measured again stays inside.
REACH_MARGIN = 0.1

#: Fewest bins of a tile of the spectrum whose median gives one local noise floor.
FLOOR_TILE_BINS = 1024

#: Most tiles per side of the spectrum for the noise floor.
FLOOR_TILES = 8

#: The noise floor is this quantile of the tiles' floors (the quiet part of the spectrum).
FLOOR_QUANTILE = 0.25


def _bins(
    shape: tuple[int, int], carrier: tuple[float, float], radius: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Distances (cycles/pixel), half-spectrum rows, columns and conjugation of the bins
    within ``radius`` of ``carrier`` (the other half read from the twin)."""
    rows, cols = shape
    fx, fy = float(carrier[0]), float(carrier[1])
    kx = np.arange(int(np.floor((fx - radius) * cols)), int(np.ceil((fx + radius) * cols)) + 1)
    ky = np.arange(int(np.floor((fy - radius) * rows)), int(np.ceil((fy + radius) * rows)) + 1)
    rho = np.hypot(kx[None, :] / cols - fx, ky[:, None] / rows - fy)
    inside = rho <= radius
    yy, xx = np.broadcast_arrays(ky[:, None] % rows, kx[None, :] % cols)
    mirrored = xx > cols // 2
    yy = np.where(mirrored, (-yy) % rows, yy)
    xx = np.where(mirrored, cols - xx, xx)
    return rho[inside], yy[inside], xx[inside], mirrored[inside]


def _turned_change(
    half: np.ndarray,
    reference: np.ndarray | None,
    where: tuple[np.ndarray, np.ndarray, np.ndarray],
    centre: np.ndarray,
) -> np.ndarray:
    """The change at bins ``where`` (rows, columns, conjugation): ``S - exp(i phi) S_ref``.

    ``phi`` is the carrier's mean phase change over its ``centre`` bins (as the
    demodulator takes the maps against the reference); ``S`` alone without a reference.
    """
    yy, xx, mirrored = where
    value = half[yy, xx].astype(np.complex128)
    value = np.where(mirrored, np.conj(value), value)
    if reference is None:
        return value
    ref = reference[yy, xx].astype(np.complex128)
    ref = np.where(mirrored, np.conj(ref), ref)
    turn = np.sum(value[centre] * np.conj(ref[centre]))
    return value - (turn / abs(turn) if abs(turn) > 0 else 1.0) * ref


def chi2_median(dof: float) -> float:
    """The median of a chi-square distribution of ``dof`` degrees of freedom.

    ``2 P^-1(dof / 2, 1 / 2)``, ``P`` the regularised lower incomplete gamma function:
    what ``scipy.stats.chi2.median`` computes, without importing ``scipy.stats`` (a
    second to import alone, for its distributions' docstrings; 0.3 s of the window's
    start beside what it shares with the rest).

    Examples
    --------
    >>> round(chi2_median(2.0), 6)  # exponential of mean 2: 2 ln 2
    1.386294
    """
    return 2.0 * float(special.gammaincinv(dof / 2.0, 0.5))


@dataclass(frozen=True)
class MeanChange:
    """The change around each carrier over many frames (:class:`ChangeAverage`).

    Attributes
    ----------
    carriers : tuple of (float, float)
        ``(fx, fy)``, cycles/pixel.
    reach : tuple of float
        Radius (cycles/pixel) of the bins kept around each carrier: its widest window.
    rho : tuple of ndarray
        Each carrier's bins' distances from it, cycles/pixel.
    power : tuple of ndarray
        Mean power of the change at those bins over the frames, counts^2.
    varying : tuple of ndarray
        Its variance over the frames (what changes from frame to frame), counts^2.
    frames : float
        Effective number of frames, ``(sum w)^2 / sum w^2`` (their count, unweighted).
    floor : float
        Noise floor of ``varying`` (power per bin of the frames' own noise), counts^2.
    """

    carriers: tuple[tuple[float, float], ...]
    reach: tuple[float, ...]
    rho: tuple[np.ndarray, ...]
    power: tuple[np.ndarray, ...]
    varying: tuple[np.ndarray, ...]
    frames: float
    floor: float

    def at(self, carrier: tuple[float, float], radius: float, shape: tuple[int, int]) -> int | None:
        """Index of the carrier within one FFT bin of ``carrier`` kept out to ``radius``."""
        per_bin = 1.0 / min(shape)
        for i, (c, reach) in enumerate(zip(self.carriers, self.reach, strict=True)):
            near = np.hypot(c[0] - carrier[0], c[1] - carrier[1]) <= per_bin
            if near and radius <= reach + 1e-12:
                return i
        return None


class ChangeAverage:
    """Accumulate the change around each carrier, frame after frame (module documentation).

    Parameters
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)``.
    carriers : sequence of (float, float)
        The carriers whose maps are made, cycles/pixel: the bins within each one's widest
        window (:func:`~holoview.processing.fourier.windows.auto_radii` of them and the
        ``neighbours``, and :data:`REACH_MARGIN`) are kept.
    neighbours : sequence of (float, float)
        Other peaks (not the carriers nor their twins) that bound the windows.
    horizon : int, optional
        Live: the older frames weigh less, as ``(1 - 1 / horizon)`` per frame added, so
        that the mean follows the last ``horizon`` or so; None (headless) weighs every
        frame the same.
    threads : int, optional
        FFTW threads.

    Notes
    -----
    Memory: a complex and a real half spectrum (the floor of the variance, from its quiet
    tiles) and a few numbers per bin kept around each carrier.
    """

    def __init__(
        self,
        shape: tuple[int, int],
        carriers: Sequence[tuple[float, float]],
        *,
        neighbours: Sequence[tuple[float, float]] = (),
        horizon: int | None = None,
        threads: int | None = None,
    ) -> None:
        self.shape = (int(shape[0]), int(shape[1]))
        self.carriers = tuple((float(c[0]), float(c[1])) for c in carriers)
        if not self.carriers:
            raise InputError("no carrier to average the change around")
        widest = auto_radii(self.carriers, neighbours=neighbours)
        margin = CENTRE_BINS / min(self.shape)
        self.reach = tuple(float(r) * (1.0 + REACH_MARGIN) + margin for r in widest)
        self.horizon = horizon
        self.threads = threads
        rows, cols = self.shape
        self._where = [
            _bins(self.shape, c, r) for c, r in zip(self.carriers, self.reach, strict=True)
        ]
        self._centre = [w[0] <= CENTRE_BINS / max(rows, cols) for w in self._where]
        self._sum = [np.zeros(w[0].shape, np.complex128) for w in self._where]
        self._square = [np.zeros(w[0].shape) for w in self._where]
        half = (rows, cols // 2 + 1)
        self._all_sum = np.zeros(half, np.complex128)
        self._all_square = np.zeros(half)
        self._weight = 0.0
        self._weight_square = 0.0
        self._reference: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
        #: frames added
        self.count = 0

    def add(self, frame: np.ndarray, reference: np.ndarray | None = None) -> None:
        """Add one frame's change against ``reference``: each a frame, or its half spectrum.

        Both in counts, not modified; ``reference`` None for synthetic phases. A half
        spectrum (complex, :func:`~holoview.processing.fourier.spectrum.rfft2`'s) may be
        made beforehand, elsewhere (in parallel, frames at a time: each thread has its
        own plan): the same numbers as the frame's.
        """
        half = frame if np.iscomplexobj(frame) else rfft2(frame, threads=self.threads)
        if reference is not None and reference.shape != half.shape:
            if reference is not self._reference[0]:  # one transform for a fixed reference
                self._reference = (reference, rfft2(reference, threads=self.threads))
            reference = self._reference[1]
        if half.shape[0] != self.shape[0]:
            raise InputError("the frames the change is averaged over differ in shape")
        keep = 1.0 if self.horizon is None else 1.0 - 1.0 / max(self.horizon, 2)
        for total in (*self._sum, *self._square, self._all_sum, self._all_square):
            np.multiply(total, keep, out=total)
        self._weight = keep * self._weight + 1.0
        self._weight_square = keep * keep * self._weight_square + 1.0
        change = half.astype(np.complex128) if reference is None else half - reference
        self._all_sum += change
        self._all_square += change.real**2 + change.imag**2
        for i, (_, yy, xx, mirrored) in enumerate(self._where):
            value = _turned_change(half, reference, (yy, xx, mirrored), self._centre[i])
            self._sum[i] += value
            self._square[i] += value.real**2 + value.imag**2
        self.count += 1

    def _variance(self, total: np.ndarray, square: np.ndarray) -> np.ndarray:
        """Weighted variance over the frames (unbiased), counts^2 per bin."""
        w, w2 = self._weight, self._weight_square
        mean_square = square / w
        mean = total / w
        return (mean_square - (mean.real**2 + mean.imag**2)) / (1.0 - w2 / (w * w))

    def result(self) -> MeanChange | None:
        """The mean change so far; None before two frames or without a noise floor."""
        if self.count < 2:
            return None
        frames = self._weight**2 / self._weight_square
        varying = self._variance(self._all_sum, self._all_square)
        tile_floors = _tile_medians(varying[:, 1:-1])
        # a variance over n frames is a chi-square of 2 (n - 1) degrees of freedom / 2 (n - 1)
        dof = 2.0 * max(frames - 1.0, 1.0)
        median = chi2_median(dof) / dof
        floor = float(np.quantile(tile_floors, FLOOR_QUANTILE)) / median
        if not (np.isfinite(floor) and floor > 0):
            return None
        return MeanChange(
            self.carriers,
            self.reach,
            tuple(w[0] for w in self._where),
            tuple(s / self._weight for s in self._square),
            tuple(self._variance(t, s) for t, s in zip(self._sum, self._square, strict=True)),
            float(frames),
            floor,
        )


def average_change(
    shape: tuple[int, int],
    carriers: Sequence[tuple[float, float]],
    pairs: Iterable[tuple[np.ndarray, np.ndarray | None]],
    *,
    neighbours: Sequence[tuple[float, float]] = (),
    threads: int | None = None,
) -> MeanChange | None:
    """The change around ``carriers`` over ``(frame, reference)`` pairs, equally weighed.

    See :class:`ChangeAverage` (None under two pairs or without a noise floor).
    """
    average = ChangeAverage(shape, carriers, neighbours=neighbours, threads=threads)
    for frame, reference in pairs:
        average.add(frame, reference)
    return average.result()


@dataclass(frozen=True)
class SurfaceSpectrum:
    """What windows are matched to: frames' half spectra, their reference's, the noise floor.

    Attributes
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)``.
    frames : tuple of ndarray of complex64, shape (rows, cols // 2 + 1)
        The frames' half spectra (``rfft2`` layout), counts: a run's maps are made of
        frames like them.
    reference : ndarray of complex64 or None
        The reference's (the frame the maps are taken against), same layout; None for
        synthetic phases.
    floor : float
        Noise power per bin of what a map shows (the change, or the frame), counts^2:
        the quiet quarter of the spectrum's tiles, each tile's median over ln 2 (noise
        power is exponentially distributed; :func:`_noise_floor`).
    band : float
        The surface's waves as peak detection saw them, cycles/pixel: the largest
        offset of a wave's sidebands (:func:`~holoview.processing.peaks.radii.surface_band`;
        0 when none was seen). Every matched window passes them.
    mean : MeanChange or None
        The change around the carriers over many frames (:class:`ChangeAverage`);
        None where it was not measured (then ``frames`` alone).
    """

    shape: tuple[int, int]
    frames: tuple[np.ndarray, ...]
    reference: np.ndarray | None
    floor: float
    band: float = 0.0
    mean: MeanChange | None = field(default=None, repr=False)

    def around(
        self, carrier: tuple[float, float], radius: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The maps' content near a carrier: distances, powers and their variation.

        Returns
        -------
        rho : ndarray
            Distances (cycles/pixel) of the bins within ``radius`` of ``carrier``.
        power : ndarray
            ``|S - exp(i phi) S_ref|^2`` with the carrier's mean phase change ``phi``
            (module documentation), or ``|S|^2``, averaged over the frames (the many
            frames of :attr:`mean` where it holds the carrier), counts^2.
        varying : ndarray or None
            The variance of that change over the many frames (:attr:`MeanChange.varying`);
            None without them.
        """
        held = None if self.mean is None else self.mean.at(carrier, radius, self.shape)
        if self.mean is not None and held is not None:
            rho = self.mean.rho[held]
            inside = rho <= radius
            return rho[inside], self.mean.power[held][inside], self.mean.varying[held][inside]
        rho, yy, xx, mirrored = _bins(self.shape, carrier, radius)
        rows, cols = self.shape
        centre = rho <= CENTRE_BINS / max(rows, cols)
        power = np.zeros(rho.shape)
        for frame in self.frames:
            value = _turned_change(frame, self.reference, (yy, xx, mirrored), centre)
            power += value.real**2 + value.imag**2
        return rho, power / len(self.frames), None


def measure_spectrum(
    frames: np.ndarray | Sequence[np.ndarray],
    reference: np.ndarray | None = None,
    *,
    band: float = 0.0,
    mean: MeanChange | None = None,
    threads: int | None = None,
) -> SurfaceSpectrum:
    """Return what windows are matched to (module documentation).

    Parameters
    ----------
    frames : ndarray, shape (rows, cols), or sequence of them
        Holograms (counts; not modified) whose maps the windows are to serve: for a run
        against its first frame, a few frames spread over it.
    reference : ndarray, optional
        The hologram the maps are taken against (the run's first frame, the background),
        same shape; None for synthetic phases.
    band : float
        The surface's waves seen by peak detection, cycles/pixel
        (:attr:`SurfaceSpectrum.band`).
    mean : MeanChange, optional
        The change over many frames (:meth:`ChangeAverage.result`).
    threads : int, optional
        FFTW threads.

    Raises
    ------
    InputError
        For no frame, frames of different shapes, or spectra without a noise floor.
    """
    arrays = [frames] if isinstance(frames, np.ndarray) else list(frames)
    if not arrays:
        raise InputError("no frame to match the windows to")
    shape = (int(np.shape(arrays[0])[0]), int(np.shape(arrays[0])[1]))
    if any(np.shape(a) != shape for a in arrays) or (
        reference is not None and np.shape(reference) != shape
    ):
        raise InputError("the frames the windows are matched to differ in shape")
    halves = tuple(rfft2(a, threads=threads) for a in arrays)
    other = None if reference is None else rfft2(reference, threads=threads)
    floor = _noise_floor(halves, other)
    if floor is None:
        raise InputError("the spectrum has no noise floor (constant, equal or non-finite frames)")
    return SurfaceSpectrum(shape, halves, other, floor, float(band), mean)


def _tile_medians(power: np.ndarray) -> list[float]:
    """Medians of the tiles of ``power`` (:data:`FLOOR_TILE_BINS`, :data:`FLOOR_TILES`)."""
    rows, cols = power.shape
    side = int(np.clip(np.sqrt(rows * cols / FLOOR_TILE_BINS), 1, FLOOR_TILES))
    return [
        float(
            np.median(
                power[
                    i * rows // side : (i + 1) * rows // side,
                    k * cols // side : (k + 1) * cols // side,
                ]
            )
        )
        for i in range(side)
        for k in range(side)
    ]


def _noise_floor(halves: tuple[np.ndarray, ...], other: np.ndarray | None) -> float | None:
    """The noise floor of the changes (power per bin), averaged over the frames that have one.

    The half spectrum is cut into tiles of at least :data:`FLOOR_TILE_BINS` bins (at most
    :data:`FLOOR_TILES` a side); each tile's median power over ln 2 is its floor, and the
    floor is their :data:`FLOOR_QUANTILE` quantile: the quiet part of the spectrum. The
    change a surface makes is not confined to its peaks' main lobes: the phase
    modulation's harmonics and the terms between families spread it over much of the
    spectrum, and the median of every bin stood 22-30 % above the noise of the change
    (``benchmarks/bench_wavy.py``'s scene, against the same frames without noise), which
    made the noise a window passes look larger, and so what it cuts smaller (the matched
    windows too narrow). The quiet quarter of the tiles stood within 0-2 % of it.

    A frame equal to the reference (a background taken from the run's own first frame)
    changes nothing and has none; None where no frame has one.
    """
    floors = []
    for half in halves:
        change = (half if other is None else half - other)[:, 1:-1]
        power = change.real.astype(np.float64) ** 2 + change.imag.astype(np.float64) ** 2
        floor = float(np.quantile(_tile_medians(power), FLOOR_QUANTILE)) / np.log(2)
        if np.isfinite(floor) and floor > 0:
            floors.append(floor)
    return float(np.mean(floors)) if floors else None
