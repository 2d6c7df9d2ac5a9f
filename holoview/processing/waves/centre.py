"""The centre of a field of partial waves, from a complex amplitude map at one frequency.

Map coordinates as in :mod:`.azimuthal`: ``x = col dx``, ``y = row dy`` (m).

:func:`find_centre` takes a lock-in map at the strongest frequency and returns the point
around which its power is spread over the fewest azimuthal numbers: the least entropy
of ``P_m = sum_r r |A_m(r)|^2`` over ``m`` (rings two pixels apart). A field of partial
waves around one centre puts its power in a few ``m``; seen from another point, each
spreads over ``m +- n`` with weights ``J_n(k delta)^2`` (Graf's addition theorem), so
the entropy's minimum is about ``1/k`` wide and beyond it lie local minima. The map's
mean is removed first: a uniform part (the reference arm's vibration in the RF and RB
maps) is ``m = 0`` around every point.

The search scans the region where the rings fit on a grid :data:`SCAN_STEP` ``/ k``
apart (``k`` the peak of the map's own radially averaged power spectrum; at most
:data:`SCAN_POINTS` points, with :data:`SCAN_RINGS` rings of 64 angles), refines the
:data:`SCAN_BEST` lowest local minima of the scan by Nelder-Mead on the full score, and
from the best of them fits a quadratic to the score on a grid of :data:`BOWL` x
:data:`BOWL` points a scan step either way: its vertex is the centre (fitted again
around the vertex). A grid of fixed size (7 x 7) was spaced farther apart than the
minimum is wide where the rings were small beside the maps: 7 of 20 sources (rings to
11 mm in maps of 64 mm) were found 27 to 80 pixels off, or refused as lying elsewhere.
Within a pixel of the least score the noise makes local minima (150 nm of noise on
maps of 10 to 20 nm waves: a few, a pixel apart, and the least of them 0.5 to 0.8 pixel
from the truth); the quadratic, fitted over the whole bowl, found it within 0.15 to
0.25 pixel.

The score samples the map's cubic spline (untrusted pixels zero after the mean is
removed) on the rings that keep :data:`CLEAR_PX` pixels from untrusted ones around
every point within a scan step of where a refinement (or the quadratic's grid) starts:
the same rings at every point scored there, so the score is smooth (a ring dropped as a
trial point neared the untrusted core made jumps larger than the noise's curvature). In
the scan, each point's own clear rings.

The search keeps to where the rings fit; a centre it finds at that region's edge is
sought again with rings to half the radius (:data:`WIDE_RINGS`), and one beyond the
region is refused with the radius that fits: held at the edge, a centre a pixel off took
2 to 3 % of the partial waves' amplitudes (``J_0(k delta)``;
``benchmarks/accuracy_waves.py``, maps of 180 pixels of 0.467 mm, rings to 38 mm).

:func:`centre_stderr` gives its error by the jackknife over the lock-ins of
:data:`CENTRE_SEGMENTS` consecutive segments of the record: the quadratic's vertex
around the record's centre, or around another of the scan's least minima where its
score is less, for the record less each segment (the mean of the other segments' maps),
``se^2 = (K - 1) / K sum (c_i - c.)^2``, widened by
Student's ``t`` with ``K - 1`` degrees of freedom over the normal's quantile (x 1.21 for
8 segments) so that ``+- 1.96 se`` holds 95 %. The entropy does not change with the
amplitude or phase of the field, so a ringdown or a tone off the lock-in's frequency
leaves the segments' centres alike. Half the difference of the centres of the record's
halves (one sample of the spread, and the halves searched from the record's centre)
fell short: 2 standard errors held 44 to 50 % of the errors at 150 nm of noise.
"""

from __future__ import annotations

import logging
import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage, special
from scipy.optimize import minimize

from holoview.errors import InputError
from holoview.processing.waves.azimuthal import ring_angles
from holoview.processing.waves.omega_k import pixel_pair

logger = logging.getLogger(__name__)

__all__ = ["CENTRE_SEGMENTS", "CENTRE_TOLERANCE_PX", "centre_stderr", "find_centre"]

#: The least standard error given to a centre, map pixels.
CENTRE_TOLERANCE_PX = 0.05

#: A centre found this close to the edge of where the rings fit (map pixels) is sought
#: again with rings to :data:`WIDE_RINGS` of the radius: the waves' centre may lie beyond.
CENTRE_EDGE_PX = 0.5

#: Fraction of the radius asked for that the rings of the second search reach.
WIDE_RINGS = 0.5

#: Spacing of the scan a search starts from, times ``1 / k``: at ``k delta = 0.35`` from
#: the nearest point, ``J_0^2`` keeps 97 % of an ``m``'s power.
SCAN_STEP = 0.5

#: Most points the scan scores (its spacing widens beyond; a warning past ``1 / k``).
SCAN_POINTS = 4096

#: Most rings the scan scores, spread over those asked for.
SCAN_RINGS = 8

#: Angles per ring in the scan.
SCAN_ANGLES = 64

#: Local minima of the scan refined.
SCAN_BEST = 3

#: Distance (pixels) from untrusted pixels of a ring scored: the cubic spline's reach.
CLEAR_PX = 2.0

#: Where Nelder-Mead stops, times the scan's spacing: the quadratic fitted around its
#: point (:data:`BOWL`) gives the centre.
REFINED = 0.1

#: Points a side of the grid a quadratic is fitted to around the least score found.
BOWL = 5

#: Fewest rings clear of untrusted pixels a point is scored with.
MIN_RINGS = 4

#: What a trial point beyond where the rings fit scores: above any entropy (at most
#: ``log(2 m_max + 1)``).
OUTSIDE = 1e3

#: Segments of the record whose lock-ins give the centre's error (jackknife).
CENTRE_SEGMENTS = 8


class _Score:
    """Entropy over ``m`` of the ring-summed ``|A_m|^2`` around points (pixels).

    ``coefficients`` are the cubic spline coefficients of the real and imaginary parts
    (untrusted pixels zero), ``clearance`` each pixel's distance to the nearest
    untrusted one (pixels). Each ring has ``n_theta`` angles (one count, or one per ring,
    rings of a count following one another).
    """

    def __init__(
        self,
        coefficients: np.ndarray,
        clearance: np.ndarray,
        radii: np.ndarray,
        n_theta: int | np.ndarray,
        m_max: int,
    ) -> None:
        self.coefficients = coefficients
        self.clearance = clearance
        self.radii = radii
        counts = np.broadcast_to(np.asarray(n_theta), radii.shape)
        self.groups = []  # (x and y offsets (Rg, n), the FFT's columns of m, n), rings out
        for n in np.unique(counts):
            theta = 2.0 * np.pi * np.arange(n) / n
            cos = radii[counts == n, np.newaxis] * np.cos(theta)
            sin = radii[counts == n, np.newaxis] * np.sin(theta)
            self.groups.append((cos, sin, np.arange(-m_max, m_max + 1) % n, int(n)))

    @staticmethod
    def _coordinates(points: np.ndarray, cos: np.ndarray, sin: np.ndarray) -> np.ndarray:
        """(2, P, Rg, n) rows and columns of the samples around ``points`` (P, 2)."""
        rows = points[:, 1, np.newaxis, np.newaxis] + sin
        cols = points[:, 0, np.newaxis, np.newaxis] + cos
        return np.stack([rows, cols])

    def rings(self, points: np.ndarray, reach: float = 0.0) -> np.ndarray:
        """(P, R) the rings around ``points`` (P, 2) clear of untrusted pixels.

        Clear: :data:`CLEAR_PX` from untrusted pixels around every point
        within ``reach`` (pixels) of ``points``.
        """
        least = [
            np.min(
                ndimage.map_coordinates(
                    self.clearance, self._coordinates(points, cos, sin), order=1, mode="nearest"
                ),
                axis=2,
            )
            for cos, sin, _, _ in self.groups
        ]
        return np.concatenate(least, axis=1) >= CLEAR_PX + reach

    def entropy(self, points: np.ndarray, rings: np.ndarray) -> np.ndarray:
        """(P,) entropies around ``points`` (P, 2) over the rings ``rings`` (P, R) marks."""
        parts = []
        for cos, sin, columns, n in self.groups:
            where = self._coordinates(points, cos, sin)
            real, imag = (
                ndimage.map_coordinates(part, where, order=3, mode="mirror", prefilter=False)
                for part in self.coefficients
            )
            parts.append(np.fft.fft(real + 1j * imag, axis=2)[:, :, columns] / n)
        modes = np.concatenate(parts, axis=1)  # (P, R, 2 m_max + 1)
        weight = np.where(rings, self.radii, 0.0)  # (P, R)
        power = np.einsum("pr,prm->pm", weight, np.abs(modes) ** 2)
        total = power.sum(axis=1, keepdims=True)
        share = power / np.where(total > 0, total, 1.0)
        logs = np.log(np.where(share > 0, share, 1.0))
        out = -np.sum(share * logs, axis=1)
        return np.where((total[:, 0] > 0) & (rings.sum(axis=1) >= MIN_RINGS), out, math.inf)

    def scan(self, points: np.ndarray, chunk: int = 256) -> np.ndarray:
        """(P,) entropies around ``points`` (P, 2), each over the rings clear there."""
        out = np.empty(len(points))
        for a in range(0, len(points), chunk):
            block = points[a : a + chunk]
            out[a : a + chunk] = self.entropy(block, self.rings(block))
        return out


class _Search:
    """The centre search over where rings to ``outer`` (m) fit (module docstring)."""

    def __init__(
        self,
        field: np.ndarray,
        pixel_size: tuple[float, float],
        inner: float,
        outer: float,
        m_max: int,
        *,
        step: float | None = None,
    ) -> None:
        dy, dx = pixel_size
        rows, cols = field.shape
        finite = np.isfinite(field)
        if not np.any(finite):
            raise InputError("no centre can be found: the amplitude map is all NaN")
        filled = np.where(finite, field - field[finite].mean(), 0.0)
        if not np.any(filled):
            raise InputError("no centre can be found: the amplitude map is zero")
        self.scale = np.array([dx, dy])
        self.pixel = min(dx, dy)
        margin = outer + 2.0 * self.pixel
        self.low = np.array([margin, margin])
        self.high = np.array([(cols - 1) * dx - margin, (rows - 1) * dy - margin])
        if np.any(self.high < self.low):
            raise InputError(
                f"rings of {outer * 1e3:.3g} mm do not fit in maps of "
                f"{(cols - 1) * dx * 1e3:.3g} x {(rows - 1) * dy * 1e3:.3g} mm"
            )
        coefficients = np.stack(
            [
                ndimage.spline_filter(part, order=3, mode="mirror")
                for part in (filled.real, filled.imag)
            ]
        )
        if np.all(finite):
            clearance = np.full(field.shape, float(rows + cols))
        else:
            clearance = ndimage.distance_transform_edt(finite)
        ring_step = 2.0 * self.pixel
        radii = np.arange(inner, outer + 1e-9 * ring_step, ring_step) / self.pixel
        n_theta = ring_angles(radii, 2.0, fewest=16)  # 2 pixels apart on each ring
        self.score = _Score(coefficients, clearance, radii, n_theta, m_max)
        few = radii[np.unique(np.linspace(0, radii.size - 1, SCAN_RINGS).round().astype(int))]
        self.coarse = _Score(coefficients, clearance, few, SCAN_ANGLES, m_max)
        self.step = self._scan_step(filled) if step is None else step

    def _scan_step(self, filled: np.ndarray) -> float:
        """The scan's spacing (pixels): :data:`SCAN_STEP` ``/ k``, within bounds."""
        k = _wavenumber(filled, float(self.scale[0]), float(self.scale[1]))
        size = (self.high - self.low) / self.scale  # pixels
        step = SCAN_STEP / (k * self.pixel)
        fewest = float(np.prod(size / step + 1.0))
        if fewest > SCAN_POINTS:
            step *= math.sqrt(fewest / SCAN_POINTS)
        if step * k * self.pixel > 1.0:  # wider than the entropy's minimum
            logger.warning(
                "the centre scan is %.3g pixels apart (%.3g / k): the rings are small "
                "beside the maps; the search may miss the centre",
                step,
                step * k * self.pixel,
            )
        return float(np.clip(step, 1.0, max(float(size.max()) / 6.0, 1.0)))

    def outside(self, point: np.ndarray) -> bool:
        """Whether ``point`` (pixels) lies beyond where the rings fit."""
        metres = point * self.scale
        return bool(np.any(metres < self.low) or np.any(metres > self.high))

    def _rings(self, point: np.ndarray) -> np.ndarray:
        """(1, R) the rings clear around every point within a step of ``point`` (pixels).

        Those clear around ``point`` alone where fewer than :data:`MIN_RINGS` are (small
        rings beside an untrusted core).
        """
        rings = self.score.rings(point[np.newaxis], self.step)
        if np.count_nonzero(rings) >= MIN_RINGS:
            return rings
        return self.score.rings(point[np.newaxis])

    def refine(self, start: np.ndarray) -> tuple[np.ndarray, float]:
        """Nelder-Mead from ``start`` (pixels) and its least entropy.

        The rings scored are those clear around every point within a step of ``start``:
        the same at every trial point near it, so the score is smooth there.
        """
        rings = self._rings(start)
        if np.count_nonzero(rings) < MIN_RINGS:
            return start, math.inf

        def score(point: np.ndarray) -> float:
            if self.outside(point):
                return OUTSIDE
            return float(self.score.entropy(point[np.newaxis], rings)[0])

        simplex = start + np.array([[0.0, 0.0], [self.step, 0.0], [0.0, self.step]])
        result = minimize(
            score,
            start,
            method="Nelder-Mead",
            options={"initial_simplex": simplex, "xatol": REFINED * self.step, "fatol": math.inf},
        )
        return np.asarray(result.x, dtype=np.float64), float(result.fun)

    def candidates(self) -> list[tuple[np.ndarray, float]]:
        """The :data:`SCAN_BEST` least local minima of the scan, refined (pixels, entropy)."""
        low, high = self.low / self.scale, self.high / self.scale
        counts = np.floor((high - low) / self.step).astype(int) + 1
        xs = (
            low[0]
            + (high[0] - low[0] - (counts[0] - 1) * self.step) / 2
            + self.step * np.arange(counts[0])
        )
        ys = (
            low[1]
            + (high[1] - low[1] - (counts[1] - 1) * self.step) / 2
            + self.step * np.arange(counts[1])
        )
        grid = np.stack(np.meshgrid(xs, ys), axis=-1)  # (ny, nx, 2)
        values = self.coarse.scan(grid.reshape(-1, 2)).reshape(grid.shape[:2])
        if not np.any(np.isfinite(values)):
            raise InputError("no centre can be found: the rings meet untrusted pixels everywhere")
        lowest = ndimage.minimum_filter(values, size=3, mode="constant", cval=math.inf)
        minima = np.flatnonzero((values == lowest) & np.isfinite(values))
        order = minima[np.argsort(values.ravel()[minima])][:SCAN_BEST]
        return [self.refine(grid.reshape(-1, 2)[i]) for i in order]

    def bowl(self, around: np.ndarray) -> np.ndarray | None:
        """The vertex (pixels) of a quadratic fitted to the score on a grid ``around``.

        :data:`BOWL` points a side, a step either way, the rings those clear around
        every point of it; None where the fit is not a bowl or its vertex lies beyond
        the grid; within where the rings fit.
        """
        offsets = np.linspace(-self.step, self.step, BOWL)
        dx, dy = (a.ravel() for a in np.meshgrid(offsets, offsets))
        rings = self._rings(around)
        if np.count_nonzero(rings) < MIN_RINGS:
            return None
        points = around + np.column_stack([dx, dy])
        values = self.score.entropy(points, np.repeat(rings, len(points), axis=0))
        design = np.column_stack([np.ones_like(dx), dx, dy, dx * dx, dx * dy, dy * dy])
        c = np.linalg.lstsq(design, values, rcond=None)[0]
        hessian = np.array([[2.0 * c[3], c[4]], [c[4], 2.0 * c[5]]])
        if not np.all(np.isfinite(values)) or np.any(np.linalg.eigvalsh(hessian) <= 0):
            return None
        vertex = np.linalg.solve(hessian, -c[1:3])
        if np.any(np.abs(vertex) > self.step):
            return None
        return np.clip(around + vertex, self.low / self.scale, self.high / self.scale)

    def polish(self, point: np.ndarray) -> tuple[np.ndarray, float]:
        """The bowl's vertex around ``point``, then around that vertex, and its entropy.

        Where no bowl fits around ``point``, Nelder-Mead's least score from there.
        """
        first = self.bowl(point)
        if first is None:
            point = self.refine(point)[0]
        else:
            second = self.bowl(first)
            point = first if second is None else second
        rings = self._rings(point)
        return point, float(self.score.entropy(point[np.newaxis], rings)[0])

    def centre(self) -> np.ndarray:
        """The centre (pixels): the least entropy of the candidates, polished."""
        point = min(self.candidates(), key=lambda item: item[1])[0]
        return self.polish(point)[0]


def _wavenumber(field: np.ndarray, dx: float, dy: float) -> float:
    """The peak of the radially averaged power spectrum of ``field`` (rad/m)."""
    rows, cols = field.shape
    power = np.abs(np.fft.fft2(field)) ** 2
    ky = 2.0 * np.pi * np.fft.fftfreq(rows, dy)
    kx = 2.0 * np.pi * np.fft.fftfreq(cols, dx)
    k = np.hypot(ky[:, np.newaxis], kx[np.newaxis, :])
    width = 2.0 * np.pi / (max(rows * dy, cols * dx))  # a bin of the longer side
    bins = np.floor(k / width).astype(int).ravel()
    mean = np.bincount(bins, power.ravel()) / np.maximum(np.bincount(bins), 1)
    mean[:2] = 0.0  # the map's extent, not its waves
    return float((np.argmax(mean) + 0.5) * width)


def _inner(pair: tuple[float, float], r_min: float | None) -> float:
    """The inner radius of the rings (m): ``r_min``, else four pixels."""
    return 4.0 * min(pair) if r_min is None else float(r_min)


def find_centre(
    amplitude: ArrayLike,
    pixel_size: float | ArrayLike,
    *,
    radius: float,
    r_min: float | None = None,
    m_max: int = 8,
    start: tuple[float, float] | None = None,
) -> tuple[float, float]:
    """Return the centre ``(x0, y0)`` (m) of a field of partial waves (module docstring).

    Parameters
    ----------
    amplitude : array_like of complex, shape (rows, cols)
        Complex amplitude of the field at one frequency (m; NaN where untrusted).
    pixel_size : float or (float, float)
        m.
    radius : float
        Outer radius of the rings scored, m (the centre is sought where they fit).
    r_min : float, optional
        Inner radius, m (default four pixels).
    m_max : int
        Largest ``|m|`` scored.
    start : (float, float), optional
        A point near the centre, m: the search is refined from there alone (no scan,
        no second search), then the quadratic fitted.

    Raises
    ------
    InputError
        The map is all NaN or zero, no centre leaves room for the rings, or the waves'
        centre lies where they do not fit (the message gives the radius that does).

    Examples
    --------
    >>> find_centre(lockin.amplitude[0], 0.5e-3, radius=18e-3)  # doctest: +SKIP
    """
    field = np.asarray(amplitude, dtype=np.complex128)
    pair = pixel_pair(pixel_size)
    inner = _inner(pair, r_min)
    search = _Search(field, pair, inner, radius, m_max)
    if start is not None:
        found, _ = search.refine(np.asarray(start, dtype=np.float64) / search.scale)
        found = search.polish(found)[0] * search.scale
        return float(found[0]), float(found[1])
    found = search.centre() * search.scale
    edge = CENTRE_EDGE_PX * search.pixel
    outer = max(WIDE_RINGS * radius, inner + 8.0 * search.pixel)
    at_edge = np.any(found - search.low < edge) or np.any(search.high - found < edge)
    if outer < radius and at_edge:
        # held at the edge of where the rings fit: the waves' centre may lie beyond it
        wide = _Search(field, pair, inner, outer, m_max)
        beyond = wide.centre() * wide.scale
        slack = 2.0 * CENTRE_TOLERANCE_PX * search.pixel
        if np.any(beyond < search.low - slack) or np.any(beyond > search.high + slack):
            rows, cols = field.shape
            width, height = (cols - 1) * pair[1], (rows - 1) * pair[0]
            room = min(beyond[0], width - beyond[0], beyond[1], height - beyond[1])
            room -= 2.0 * search.pixel
            raise InputError(
                f"the waves' centre, near ({beyond[0] * 1e3:.4g}, {beyond[1] * 1e3:.4g}) mm, "
                f"leaves room for rings up to {math.floor(room * 1e4) / 10:.1f} mm only, "
                f"not {radius * 1e3:.3g} mm: ask for rings to at most that"
            )
    logger.info("centre found at (%.4g, %.4g) mm", found[0] * 1e3, found[1] * 1e3)
    return float(found[0]), float(found[1])


def centre_stderr(
    amplitudes: ArrayLike,
    pixel_size: float | ArrayLike,
    centre: tuple[float, float],
    *,
    radius: float,
    r_min: float | None = None,
    m_max: int = 8,
    workers: int = 1,
) -> tuple[float, float]:
    """Return the standard error ``(se_x, se_y)`` (m) of a centre, by the jackknife.

    Parameters
    ----------
    amplitudes : array_like of complex, shape (K, rows, cols)
        Lock-in maps of ``K >= 3`` consecutive segments of the record, about as long
        (m; NaN where untrusted), as :func:`find_centre` took for the whole record.
    pixel_size : float or (float, float)
        m.
    centre : (float, float)
        The record's centre (m), around which the quadratic is fitted to the score of
        the record less each segment (the mean of the other segments' maps), and
        around the scan's other least minima: the least of them is that record's.
    radius, r_min, m_max
        As given to :func:`find_centre`.
    workers : int
        Threads the records less a segment are searched on (the interpolation releases
        the GIL; the centres are those of one thread).

    Returns
    -------
    (float, float)
        ``se`` along x and y, m: the jackknife's, widened by Student's ``t`` with
        ``K - 1`` degrees of freedom at 95 % over the normal's; at least
        :data:`CENTRE_TOLERANCE_PX`.

    Raises
    ------
    InputError
        Fewer than three segments, or a map :func:`find_centre` refuses.
    """
    maps = np.asarray(amplitudes, dtype=np.complex128)
    count = maps.shape[0]
    if count < 3:
        raise InputError(f"the centre's error needs at least 3 segments, got {count}")
    finite = np.isfinite(maps)
    sums = np.where(finite, maps, 0.0).sum(axis=0)
    counts = finite.sum(axis=0)
    pair = pixel_pair(pixel_size)
    setting = (pair, _inner(pair, r_min), radius, m_max)
    whole = _Search(np.where(counts > 0, sums / np.maximum(counts, 1), np.nan), *setting)
    given = np.asarray(centre, dtype=np.float64) / whole.scale
    others = [
        p for p, v in whole.candidates() if math.isfinite(v) and math.dist(p, given) > whole.step
    ]

    def less(i: int) -> np.ndarray:  # the record less segment i: from its centre or another
        rest = counts - finite[i]
        remainder = sums - np.where(finite[i], maps[i], 0.0)
        field = np.where(rest > 0, remainder / np.maximum(rest, 1), np.nan)
        search = _Search(field, *setting, step=whole.step)
        return min((search.polish(p) for p in [given, *others]), key=lambda item: item[1])[0]

    with ThreadPoolExecutor(max_workers=max(1, min(workers, count))) as pool:
        centres = list(pool.map(less, range(count)))
    spread = np.asarray(centres) * np.array(pair[::-1])
    variance = (count - 1) / count * np.sum((spread - spread.mean(axis=0)) ** 2, axis=0)
    widen = special.stdtrit(count - 1, 0.975) / special.ndtri(0.975)
    floor = CENTRE_TOLERANCE_PX * np.array(pair[::-1])
    se = np.maximum(widen * np.sqrt(variance), floor)
    return float(se[0]), float(se[1])
