"""Carrier values of every frame without a full FFT: a separable DFT at the exact carriers.

The mean-phase series (trends, rates, temporal unwrapping, PCA) needs one complex
number per peak and frame: the spectrum at the peak's exact sub-bin carrier, whose
phase is the spatially averaged phase of that hologram (paper section 4.2; what
:attr:`~holoview.processing.maps.demodulate.PeakResult.carrier_value` gives from the
maps). :class:`CarrierProbe` computes it directly. With the frame ``I(y, x)`` and a
separable apodisation ``a(y) b(x)``, the value at carrier ``(fx, fy)`` is::

    v = sum_y a(y) exp(-2 pi i fy y) sum_x b(x) exp(-2 pi i fx x) I(y, x) / (sum a  sum b)

that is two small matrix products: the frame times a ``(cols, 2 P + 1)`` float32
matrix of apodised column cosines and sines and the apodisation itself (for the mean;
padded to :data:`COLUMN_TILE` columns), then per peak a dot product of the
``(rows,)`` results with its row phasors. About ``2 P`` multiply-adds per pixel,
against about ``2.5 log2(rows cols)`` for a real FFT, and no box, window, inverse
FFT or phase map.

Conventions (docs/design.md, as :mod:`holoview.processing.maps.demodulate`): carriers in
cycles/pixel, ``(fx, fy)``; a term ``Y0 A exp(i (2 pi f.r + phi))`` of the frame
gives ``v = Y0 A exp(i phi)`` in counts, phase origin at pixel ``(0, 0)``, so ``v``
is the demodulator's ``carrier_value`` up to the leakage and weighting below. Give
each peak on its stored twin (the one whose phase grows with the height); the other
twin gives the complex conjugate.

Apodisation, chosen by measurement (``benchmarks/bench_carriers.py``, section 3):
every other term of the frame (the zero order, other peaks and their twins, ghosts,
second orders) adds to ``v`` its amplitude times the apodisation's spectrum at the
distance between the two. The phase error this gives was measured on noise-free
simulated frames of a uniform level swept over 5 um (every relative phase turns),
for seven setups (the default bench, a Gaussian beam, a field stop, a reference
ghost, other tilts, camera gamma 0.7 with its second order, near carriers) at
128^2 to 1024^2:

- no apodisation (uniform weights) leaks like ``1 / (pi distance in bins)`` per axis:
  up to 0.12 rad at 256^2 and 9e-3 rad at 1024^2;
- a Tukey taper whose edges hold :data:`TAPER_CYCLES` beat periods of the nearest
  other term (:func:`auto_taper`; 4 was chosen against 1, 2, 8 and 16) leaks at most
  6e-4 rad at 256^2 and 6e-5 rad at 1024^2, at most a tenth of the weakest peak's
  mean-phase shot noise (6e-3 and 1.4e-3 rad at 800 photons per pixel); the map
  path's own carrier value leaks up to 4.6e-2 and 3.3e-3 rad (its box holds the
  neighbours' spectral leakage from the frame's edges);
- a field stop inside the frame is an edge that no taper at the frame's border
  removes (0.33 rad at 256^2); given the ``aperture`` mask, the apodisation falls to
  zero smoothly inside it instead (1.5e-5 rad).

A longer taper costs noise: a Hann window ``x 1.5`` in phase noise, Blackman-Harris
``x 2.0``; the automatic taper ``x 1.02-1.08`` at 1024^2, ``x 1.08-1.4`` at 256^2.
It also weights the frame's edges less than the map path's uniform mean: on a
uniform level change (evaporation) the two series differ by 0.15 to 0.25 of the
per-frame shot noise at 1024^2, on standing waves of 30 nm rms by 0.3 to 0.6 nm rms,
with the same fitted rates (within a quarter of their standard errors).

Speed (1024^2, 5 peaks, uint16, one core of a loaded 2-core AVX2 machine): about
1.1 ms per frame, 1.3 ms with the noise estimate, against 3.6 ms for one
single-threaded real FFT and 4.9 ms for the whole demodulation without unwrapping
(2048^2: 5.6, 28 and 37 ms). The first product runs in row blocks of at most
:data:`GEMM_SINGLE_THREAD_WORK` multiply-adds, which OpenBLAS (numpy's BLAS) keeps on
the calling thread: one product over the whole frame wakes its thread pool, which on
the busy two-core machine stalled for 5 to 50 ms. Integer and float64 frames are
converted to float32 block by block, in cache, never as a whole; C-contiguous
float32 frames are used as they are.

The probe keeps no state between frames: it is a pure function of the frame, with
its constants precomputed. It creates no thread; use one probe per thread.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import ndimage

from holoview.errors import InputError
from holoview.processing.fourier.frames import MIN_SIDE
from holoview.processing.fourier.windows import wrap_frequency
from holoview.processing.peaks.detection import Peak

logger = logging.getLogger(__name__)

#: Beat periods of the nearest other term held by the taper's length (see the module).
TAPER_CYCLES = 4.0

#: Largest multiply-add count of one matrix product that OpenBLAS runs on the calling
#: thread (``65536 * GEMM_MULTITHREAD_THRESHOLD``, 4 by default; interface/gemm.c).
GEMM_SINGLE_THREAD_WORK = 65536 * 4

#: Column count of the frame's matrix product is padded to a multiple of this: OpenBLAS's
#: float32 kernel works on whole tiles (measured at 1024^2: 8 columns 0.54 ms, 11 columns
#: 1.25 ms, 12 0.94 ms, 16 0.89 ms).
COLUMN_TILE = 8

#: Empty spectral points per carrier column whose values measure the noise.
NOISE_POINTS = 4

#: Candidate rows (frequencies along the column) among which they are chosen.
NOISE_CANDIDATES = 64

#: Terms nearest a carrier's column whose clearance bounds the search for the rest
#: (:func:`_noise_rows`).
NEAREST_TERMS = 1024

#: Flags :class:`CarrierValues` can carry.
FLAGS: tuple[str, ...] = ("nonfinite", "saturated")

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class CarrierValues:
    """What one frame gives for its carriers.

    Attributes
    ----------
    values : ndarray of complex128, shape (P,)
        One value per carrier (counts), in the probe's order; NaN for a frame flagged
        ``"nonfinite"``.
    noise : ndarray of float64, shape (P,)
        Standard deviation of each value's phase from the frame's noise (rad),
        estimated at empty points of the spectrum (:class:`CarrierProbe`); NaN when
        the probe estimates none or the frame is flagged.
    mean_counts : float
        Mean pixel value (counts), weighted by the apodisation; NaN for a flagged frame.
    flags : frozenset of str
        ``"nonfinite"``: NaN, infinite or float32-overflowing pixels (nothing
        measured); ``"saturated"``: pixels at the saturation level (checked on every
        4th row and column), when the probe was given one.
    """

    values: np.ndarray
    noise: np.ndarray
    mean_counts: float
    flags: frozenset[str]


def tukey(n: int, taper: float) -> np.ndarray:
    """Return a symmetric Tukey window of ``n`` samples (float64).

    Parameters
    ----------
    n : int
        Samples (>= 2).
    taper : float
        Fraction of the samples in the two cosine edges together, in [0, 1]: 0 is
        uniform, 1 a Hann window.
    """
    if not 0 <= taper <= 1:
        raise InputError(f"taper must be in [0, 1], got {taper}")
    x = np.arange(n) / (n - 1)
    w = np.ones(n)
    if taper > 0:
        edge = np.minimum(x, 1.0 - x) / (taper / 2)
        inside = edge < 1
        w[inside] = 0.5 * (1.0 - np.cos(np.pi * edge[inside]))
    return w


def _carriers(carriers: Sequence[Peak | tuple[float, float]], shape: tuple[int, int]) -> np.ndarray:
    """Check the carriers and return them as an ``(P, 2)`` float64 array of ``(fx, fy)``."""
    items = list(carriers)
    if not items:
        raise InputError("no carriers to probe: give at least one")
    out = np.empty((len(items), 2))
    for i, item in enumerate(items):
        if isinstance(item, Peak):
            carrier, name = item.carrier, f"peak {i}" + (f" ({item.label})" if item.label else "")
        else:
            carrier, name = item, f"carrier {i}"
        try:
            fx, fy = (float(c) for c in carrier)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{name} must be (fx, fy) in cycles/pixel, got {carrier!r}") from exc
        if not (math.isfinite(fx) and math.isfinite(fy)):
            raise InputError(f"{name} has a non-finite carrier ({fx}, {fy})")
        if abs(fx) > 0.5 or abs(fy) > 0.5:
            raise InputError(
                f"{name} carrier ({fx:.4g}, {fy:.4g}) is outside the spectrum "
                "(|fx|, |fy| <= 0.5 cycles/pixel)"
            )
        if abs(fx) * shape[1] < 1 and abs(fy) * shape[0] < 1:
            raise InputError(
                f"{name} carrier ({fx:.4g}, {fy:.4g}) is within one bin of zero frequency: "
                "it has no phase of its own"
            )
        out[i] = fx, fy
    return out


def structure(carriers: np.ndarray) -> np.ndarray:
    """Return where the spectrum holds terms: zero, every carrier, twin, sum and difference.

    Parameters
    ----------
    carriers : ndarray, shape (P, 2)
        ``(fx, fy)``, cycles/pixel.

    Returns
    -------
    ndarray of float64, shape (K, 2)
        Points (cycles/pixel, wrapped into [-0.5, 0.5)): zero frequency, ``+-f_i``,
        ``+-(f_i + f_j)`` and ``+-(f_i - f_j)`` (second orders at ``2 f_i`` included).
    """
    f = np.asarray(carriers, dtype=np.float64).reshape(-1, 2)
    sums = (f[:, None, :] + f[None, :, :]).reshape(-1, 2)
    differences = (f[:, None, :] - f[None, :, :]).reshape(-1, 2)
    points = np.concatenate([np.zeros((1, 2)), f, -f, sums, -sums, differences])
    return wrap_frequency(points)


def nearest_term(carriers: np.ndarray) -> float:
    """Return the smallest distance (cycles/pixel) from a carrier to zero, a carrier or a twin.

    Distances are periodic; a carrier's own twin at ``-f`` counts. Repeated carriers
    (the same point given twice) are not each other's neighbours.
    """
    f = np.asarray(carriers, dtype=np.float64).reshape(-1, 2)
    others = np.concatenate([np.zeros((1, 2)), f, -f])
    delta = wrap_frequency(f[:, None, :] - others[None, :, :])
    distance = np.hypot(delta[..., 0], delta[..., 1])
    distance[distance < 1e-12] = np.inf
    return float(distance.min())


def auto_taper(n: int, spacing: float) -> float:
    """Return the Tukey taper fraction whose edges hold :data:`TAPER_CYCLES` beat periods.

    Parameters
    ----------
    n : int
        Samples along the axis (pixels).
    spacing : float
        Distance to the nearest other term (cycles/pixel), :func:`nearest_term`.

    Returns
    -------
    float
        Taper fraction in (0, 1]: each edge is ``TAPER_CYCLES / spacing`` pixels long,
        at most half the axis (a Hann window).
    """
    if not spacing > 0:
        return 1.0
    return float(min(1.0, 2.0 * TAPER_CYCLES / (n * spacing)))


@lru_cache(maxsize=16)
def _tukey_cached(n: int, taper: float) -> np.ndarray:
    w = tukey(n, taper)
    w.setflags(write=False)
    return w


def aperture_apodisation(aperture: np.ndarray, length: float) -> np.ndarray:
    """Return a smooth apodisation that falls to zero at the edge of a trusted region.

    The region is eroded by half the edge length and blurred by a Gaussian of an
    eighth of it, then cut to the region: smooth everywhere (a pixelated edge, or a
    distance map's kinks, would leak the zero order into every carrier), about 3e-5 at
    the edge, 1 deeper inside than the edge length.

    Parameters
    ----------
    aperture : ndarray of bool, shape (rows, cols)
        Trusted pixels (inside the field stop); the frame's border counts as an edge.
    length : float
        Length of the edge (pixels), measured inward from the region's edge; shortened
        for a region too small to hold it.

    Returns
    -------
    ndarray of float32, shape of ``aperture``
        Weights in [0, 1], 0 outside the region.
    """
    mask = np.asarray(aperture, dtype=bool)
    distance = ndimage.distance_transform_edt(np.pad(mask, 1))[1:-1, 1:-1]
    depth = min(max(length, 2.0), float(distance.max())) / 2
    inner = (distance > depth).astype(np.float64)
    weights = ndimage.gaussian_filter(inner, depth / 4, mode="constant")
    weights[~mask] = 0.0
    return weights.astype(np.float32)


class CarrierProbe:
    """Measure the complex value of fixed carriers in frame after frame of one shape.

    Parameters
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)``, pixels.
    carriers : sequence of Peak or (fx, fy)
        The carriers (cycles/pixel), each on the twin to report (module documentation).
    taper : float or tuple of float, optional
        Tukey taper fraction in [0, 1] of the rows' and the columns' apodisation (one
        value for both); by default from the nearest other term (:func:`auto_taper`).
        Pass it explicitly to keep the same weighting when the carriers change.
    aperture : ndarray of bool, optional
        Trusted region (a field stop), shape ``shape``: the apodisation then falls to
        zero inward from its edge (:func:`aperture_apodisation`, over twice the
        columns' taper length: its smooth edge rises over about half of that) instead
        of at the frame's border. Costs one multiply per pixel (about 0.3 ms at 1024^2).
    noise : bool
        Estimate each value's phase noise (:attr:`CarrierValues.noise`) from
        :data:`NOISE_POINTS` empty spectral points per carrier column, chosen as far
        as possible from :func:`structure`; costs about 10 % more.
    saturation : float, optional
        Pixel value (counts) at which the camera saturates: frames reaching it are
        flagged ``"saturated"``.

    Raises
    ------
    InputError
        For a bad shape, no carrier, a carrier outside the spectrum, non-finite, or
        within a bin of zero frequency, a taper outside [0, 1], or an aperture of
        another shape or with no pixel.

    Examples
    --------
    A fringe pattern of one carrier, phase 0.5 rad:

    >>> y, x = np.mgrid[:256, :256]
    >>> frame = 100 + 20 * np.cos(2 * np.pi * (0.125 * x + 0.0625 * y) + 0.5)
    >>> probe = CarrierProbe((256, 256), [(0.125, 0.0625)])
    >>> result = probe.measure(frame)
    >>> round(float(np.angle(result.values[0])), 4)  # its mean phase, rad
    0.5
    """

    def __init__(
        self,
        shape: tuple[int, int],
        carriers: Sequence[Peak | tuple[float, float]],
        *,
        taper: float | tuple[float, float] | None = None,
        aperture: np.ndarray | None = None,
        noise: bool = True,
        saturation: float | None = None,
    ) -> None:
        if len(shape) != 2 or min(int(shape[0]), int(shape[1])) < MIN_SIDE:
            raise InputError(f"frame shape must be (rows, cols), each >= {MIN_SIDE}; got {shape}")
        rows, cols = self.shape = (int(shape[0]), int(shape[1]))
        f = _carriers(carriers, self.shape)
        self.carriers: tuple[tuple[float, float], ...] = tuple((float(a), float(b)) for a, b in f)
        self.spacing = nearest_term(f)
        if taper is None:
            tapers = (auto_taper(rows, self.spacing), auto_taper(cols, self.spacing))
        else:
            pair = np.ravel(np.asarray(taper, dtype=float))
            pair = np.repeat(pair, 2) if pair.size == 1 else pair
            if pair.size != 2 or not np.all((pair >= 0) & (pair <= 1)):
                raise InputError(f"taper must be in [0, 1] (or a pair of such), got {taper!r}")
            tapers = (float(pair[0]), float(pair[1]))
        self.taper: tuple[float, float] = tapers
        self._explicit_taper = taper
        self.saturation = saturation
        self.aperture: np.ndarray | None = None
        self._apodisation: np.ndarray | None = None  # 2-D, float32, when an aperture is given
        if aperture is not None:
            ap = np.array(aperture, dtype=bool)
            if ap.shape != self.shape:
                raise InputError(f"aperture mask has shape {ap.shape}, frames have {self.shape}")
            if not ap.any():
                raise InputError("aperture mask holds no pixel")
            ap.setflags(write=False)
            self.aperture = ap
            self._apodisation = aperture_apodisation(ap, tapers[1] * cols)
            self._apodisation.setflags(write=False)
            row_weights, col_weights = np.ones(rows), np.ones(cols)
            norm = float(self._apodisation.sum(dtype=np.float64))
            squares = float(np.square(self._apodisation, dtype=np.float64).sum())
        else:
            row_weights = _tukey_cached(rows, tapers[0])
            col_weights = _tukey_cached(cols, tapers[1])
            norm = float(row_weights.sum() * col_weights.sum())
            squares = float(np.square(row_weights).sum() * np.square(col_weights).sum())
        #: phase noise relative to uniform weights over the whole frame (>= 1)
        self.noise_gain = math.sqrt(squares * rows * cols) / norm
        p = len(f)
        x, y = np.arange(cols), np.arange(rows)
        angle_x = _TWO_PI * np.outer(x, f[:, 0])
        width = COLUMN_TILE * math.ceil((2 * p + 1) / COLUMN_TILE)
        columns = np.zeros((cols, width))
        columns[:, 0 : 2 * p : 2] = col_weights[:, None] * np.cos(angle_x)
        columns[:, 1 : 2 * p : 2] = col_weights[:, None] * np.sin(angle_x)
        columns[:, 2 * p] = col_weights
        # sum_x b(x) I(y, x) exp(-2 pi i fx x) = (I @ b cos)(y) - i (I @ b sin)(y), per carrier;
        # column 2P is the apodised row sum (the mean); the rest pad to a whole tile
        self._columns = columns.astype(np.float32)
        self._mean_rows = (row_weights / norm).astype(np.float64)
        row_frequencies = [f[:, 1][:, None]]
        self.noise_frequencies: np.ndarray | None = None
        if noise:
            self.noise_frequencies = _noise_rows(f)
            row_frequencies.append(self.noise_frequencies)
        fy = np.concatenate(row_frequencies, axis=1)  # (P, K): the value, then noise points
        phasors = (row_weights / norm)[None, None, :] * np.exp(
            -1j * _TWO_PI * fy[:, :, None] * y[None, None, :]
        )  # (P, K, rows): a(y) exp(-2 pi i fy y) / norm
        #: real and imaginary parts stacked, (P, 2 K, rows): see :meth:`measure`
        self._rows = np.concatenate([phasors.real, phasors.imag], axis=1)
        self._block_rows = int(max(1, min(rows, GEMM_SINGLE_THREAD_WORK // (cols * width))))
        self._block = np.empty((self._block_rows, cols), dtype=np.float32)
        self._products = np.empty((rows, width), dtype=np.float32)
        logger.debug(
            "probing %d carrier(s) of %s frames: taper %.3g x %.3g, noise x%.3f, %d-row blocks",
            p,
            self.shape,
            tapers[0],
            tapers[1],
            self.noise_gain,
            self._block_rows,
        )

    def with_carriers(self, carriers: Sequence[Peak | tuple[float, float]]) -> CarrierProbe:
        """Return a probe of other carriers with the same shape and settings.

        The automatic taper is recomputed from the new carriers unless the taper was
        given; the rebuild costs about 0.6 ms at 1024^2, 0.14 s with an aperture (its
        apodisation is computed again).
        """
        return CarrierProbe(
            self.shape,
            carriers,
            taper=self._explicit_taper,
            aperture=self.aperture,
            noise=self.noise_frequencies is not None,
            saturation=self.saturation,
        )

    def _check(self, frame: np.ndarray) -> np.ndarray:
        array = np.asarray(frame)
        if array.ndim != 2:
            raise InputError(f"frame must be 2-D (rows, cols), got shape {array.shape}")
        if array.shape != self.shape:
            raise InputError(f"frame has shape {array.shape}; this probe expects {self.shape}")
        if array.dtype.kind not in "uif":
            raise InputError(
                f"frame has dtype {array.dtype}: expected integer or real pixel values"
            )
        return array

    def _column_products(self, frame: np.ndarray) -> np.ndarray:
        """Return ``apodised frame @ columns``, ``(rows, width)`` float32 (an internal buffer)."""
        out, columns, step = self._products, self._columns, self._block_rows
        direct = self._apodisation is None and frame.dtype == np.float32
        direct = direct and frame.flags.c_contiguous and frame.flags.aligned
        for start in range(0, self.shape[0], step):
            stop = min(start + step, self.shape[0])
            if direct:
                np.matmul(frame[start:stop], columns, out=out[start:stop])
                continue
            block = self._block[: stop - start]
            if self._apodisation is None:
                np.copyto(block, frame[start:stop], casting="unsafe")
            else:
                np.multiply(frame[start:stop], self._apodisation[start:stop], out=block)
            np.matmul(block, columns, out=out[start:stop])
        return out

    def measure(self, frame: np.ndarray) -> CarrierValues:
        """Return the carriers' values in one frame (never modified).

        Parameters
        ----------
        frame : ndarray, shape ``shape``
            A hologram (counts): any integer or real dtype, any strides.

        Returns
        -------
        CarrierValues
            NaN values and the ``"nonfinite"`` flag for a frame holding NaN or
            infinity.

        Raises
        ------
        InputError
            For a frame of another shape, not 2-D, or not of real numbers.
        """
        array = self._check(frame)
        p = len(self.carriers)
        with np.errstate(invalid="ignore", over="ignore"):  # NaN or inf pixels: flagged below
            products = self._column_products(array)
            rows = self.shape[0]
            # per carrier, (rows, [c, s]) in float64, with the column sums c - i s and the
            # row phasors r = u + i w: sum_y r (c - i s) = (u.c + w.s) + i (w.c - u.s)
            pairs = products[:, : 2 * p].reshape(rows, p, 2).transpose(1, 0, 2).astype(np.float64)
            dots = np.matmul(self._rows, pairs)  # (P, 2 K, 2)
            k = self._rows.shape[1] // 2
            sums = (dots[:, :k, 0] + dots[:, k:, 1]) + 1j * (dots[:, k:, 0] - dots[:, :k, 1])
            mean = float(np.dot(self._mean_rows, products[:, 2 * p]))
        flags: set[str] = set()
        values = sums[:, 0]
        noise = np.full(p, np.nan)
        if not (np.isfinite(sums).all() and math.isfinite(mean)):
            flags.add("nonfinite")
            values = np.full(p, np.nan, dtype=np.complex128)
            mean = math.nan
        elif self.noise_frequencies is not None:
            power = np.square(np.abs(sums[:, 1:])).ravel()
            # |n|^2 of a circular complex Gaussian is exponential: its median is sigma^2 ln 2
            sigma2 = float(np.median(power)) / math.log(2)
            with np.errstate(divide="ignore"):
                noise = np.sqrt(sigma2 / 2) / np.abs(values)
        if self.saturation is not None and (array[::4, ::4] >= self.saturation).any():
            flags.add("saturated")
        return CarrierValues(values=values, noise=noise, mean_counts=mean, flags=frozenset(flags))


def _noise_rows(carriers: np.ndarray) -> np.ndarray:
    """Return, per carrier column ``fx``, the :data:`NOISE_POINTS` row frequencies farthest
    from every term of :func:`structure` (cycles/pixel), shape ``(P, NOISE_POINTS)``.

    The terms number about three times the carriers squared (197121 for 256 peaks): a
    candidate's clearance is taken over the terms near the carrier's column only, those
    closer in ``fx`` than the largest clearance the nearest few terms leave (the others
    cannot be nearer), so memory and time stay small for any number of peaks.
    """
    terms = structure(carriers)
    term_fx = wrap_frequency(terms[:, 0])
    candidates = (np.arange(NOISE_CANDIDATES) + 0.5) / NOISE_CANDIDATES - 0.5
    rows = np.empty((len(carriers), NOISE_POINTS))
    for i, fx in enumerate(wrap_frequency(carriers[:, 0])):
        dx = np.abs(fx - term_fx)  # (T,), the periodic distance below
        np.minimum(dx, 1.0 - dx, out=dx)
        few = min(NEAREST_TERMS, len(dx))
        nearest = np.argpartition(dx, few - 1)[:few]
        bound = _clearance(dx[nearest], terms[nearest, 1], candidates).max()
        near = dx <= bound
        clearance = _clearance(dx[near], terms[near, 1], candidates)
        best = np.sort(np.argsort(-clearance, kind="stable")[:NOISE_POINTS])
        rows[i] = candidates[best]
    return rows


def _clearance(dx: np.ndarray, fy: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """Each candidate row frequency's distance to the nearest of the terms ``(dx, fy)``."""
    dy = wrap_frequency(candidates[:, None] - fy[None, :])
    return np.hypot(dx[None, :], dy).min(axis=1)
