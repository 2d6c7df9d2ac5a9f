"""Joint per-frame estimation: one height and one reference-arm phase from every peak.

Every identified peak ``m`` sees the same surface and the same reference arm (docs/design.md,
"The lattice"): between two frames its mean phase steps by

    ``s_m = alpha_m du + c_m dpsi + noise``,   ``du = 4 pi dh / wavelength``,

with ``alpha_m`` its prefactor, ``c_m`` its coupling to the reference-arm phase
``psi`` (its lattice coordinate along ``f_RF``: +1 for RF, -1 for every RB_j, 0 for
every FB_j, -2 for 2RB1), ``dh`` the height step (m) and ``dpsi`` the reference arm's
phase step (rad: vibration, air-path drift). The camera gives ``s_m`` only modulo
2 pi: ``s_m = y_m + 2 pi n_m`` with ``y_m`` the wrapped step and ``n_m`` unknown
integers. A peak that moves past pi per frame (the high orders, which carry the most
height per radian, first) cannot be unwrapped on its own; together the peaks can: the
integers that make all steps agree with one ``(du, dpsi)`` are found by integer least
squares, as multi-wavelength interferometry resolves its fringe orders (the excess
fractions of Benoit 1898; de Groot, Appl. Opt. 33, 5948 (1994); Falaggis, Towers and
Towers, Appl. Opt. 53, 3737 (2014)) and carrier-phase GNSS its cycle ambiguities
(Teunissen, J. Geodesy 70, 65 (1995)).

Per frame, :class:`JointEstimator` minimises

    ``J(n, dx) = sum_m (y_m + 2 pi n_m - A_m dx)^2 / v_m + (dx - dx_pred)' P^-1 (dx - dx_pred)``

over the integers ``n`` and ``dx = (du, dpsi)``. The second term is a prediction from
the past frames (the height keeps its last step, the reference-arm phase does not move;
``P`` is learned from how far the steps departed from it, widened four times), as a
Kalman filter carries a float solution in real-time kinematic GNSS. Across lost frames
(a step spanning ``n`` frame intervals, :mod:`.frame_gaps`) the height is predicted to
keep its step in each, ``n`` times the last, the prediction's spread ``n`` times wider.
The search runs in ``dx``-space, where the problem has two dimensions whatever the
number of peaks (the ambiguity function method of Counselman and Gourevitch, IEEE Trans.
Geosci. Remote Sens. GE-19, 244 (1981), searches position the same way): the integers
of the two peaks whose steps the prediction fixes best are enumerated over the
prediction's window (4.5 standard deviations, and one more integer each side), each
pair fixes a ``dx``,
every other peak's integer is rounded to it, and ``dx`` is solved again with them
(integer bootstrapping, Teunissen, J. Geodesy 72, 606 (1998)). The best ``J`` wins.

The margin of a frame is ``sqrt(J2 - J1) / 2`` with ``J2`` the best solution with another
height step: half the distance, in noise standard deviations, between the two solutions'
predictions, the distance noise would have to cover to swap them (the discrimination
test of Euler and Schaffrin, 1991, in its difference form). A frame is flagged only when
its margin is below ``min_margin`` (3 by default: a wrong choice about once in 700
frames at the threshold, less above it); its best solution is still used. The couplings
being integers, a whole turn of the reference arm changes no height: solutions that
differ by one have their own margin (``vibration_margin``), which only the RF and RB_j
series and the vibration series depend on; the smaller reference-arm step is taken.

With the integers, each peak's phase is unwrapped (its cumulative steps), and the
height and reference-arm phase since the first frame are the weighted least-squares
solution on the unwrapped phases of the frame (not the sum of the steps: noise does not
accumulate). That height is the fused depth; the reference-arm phase leaves it, and is
returned as the vibration series. Peaks missing from a frame (NaN) are carried over: a
peak's next step spans the frames it missed, predicted by the fused solution meanwhile;
a peak seen first later starts where the fused solution is.

Noise: each peak's phase noise (rad) may be given (for example ``noise / |value|`` of
its carrier value, the noise of a spectrum bin being the same for every peak);
otherwise it is learned from the residuals (exponentially weighted, the leverage of each
peak allowed for), starting from ``FIRST_SIGMA`` times the brightest peak's amplitude
over each peak's. :func:`estimate_joint` runs a whole recording twice: the second pass
with the noise and the prediction's spread the first one measured.

Phases are in rad, heights in m, times in s.
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from holoview.errors import InputError

logger = logging.getLogger(__name__)

__all__ = ["DEFAULT_MIN_MARGIN", "JointEstimator", "JointFrame"]

#: Frames are flagged below this margin (noise standard deviations).
DEFAULT_MIN_MARGIN = 3.0

#: First guess of the brightest peak's phase noise per frame, rad (learned from then on).
FIRST_SIGMA = 0.05

#: Half-width of the search window around the prediction, in its standard deviations.
WINDOW_SIGMAS = 4.5

#: The prediction's learned spread is widened this many times (variance).
INFLATE = 4.0

#: Smallest standard deviation of the prediction (rad of ``du`` and ``dpsi``).
FLOOR = 0.02

#: Frames over which learned noise and spread average (exponential weighting).
MEMORY = 50

#: Two solutions whose height steps differ by less than this (rad of ``du``) are one
#: height (a whole turn of the reference arm apart).
SAME_HEIGHT = 1e-3

#: Most candidate integer pairs enumerated per frame.
MAX_CANDIDATES = 4096

#: A best solution this far out of its chi-square (in its standard deviations) is
#: searched again over the first frame's wide window.
CHI2_SIGMAS = 5.0


@dataclass(frozen=True)
class JointFrame:
    """One frame's joint estimate.

    Attributes
    ----------
    height : float
        Fused height change since the first frame, m (the reference arm removed); NaN
        when no peak was measured.
    vibration : float
        Reference-arm phase since the first frame, rad (NaN when no peak couples to it).
    phases : ndarray, shape (M,)
        Each peak's phase unwrapped in time, rad, since its first frame (NaN where not
        measured).
    turns : ndarray of int, shape (M,)
        The whole turns added to each peak's wrapped step this frame.
    margin : float
        Noise standard deviations between the solution and the best one with another
        height step (inf without another).
    vibration_margin : float
        The same against the best solution a whole turn of the reference arm away (same
        height, the RF and RB_j phases a turn apart): small when the reference arm steps
        near pi a frame, which the height does not mind.
    flagged : bool
        ``margin < min_margin``: the frame's height step is not resolved with confidence.
    """

    height: float
    vibration: float
    phases: NDArray[np.float64]
    turns: NDArray[np.int64]
    margin: float
    vibration_margin: float
    flagged: bool


class JointEstimator:
    """Frame-by-frame joint unwrapping of many peaks (module documentation).

    Memory is bounded: the state is a few numbers per peak.

    Parameters
    ----------
    alphas : array_like of float, shape (M,)
        Each peak's prefactor on its stored twin, > 0.
    couplings : array_like of int, shape (M,)
        Each peak's coupling to the reference-arm phase (its lattice ``rf``
        coordinate: RF +1, RB_j -1, FB_j 0).
    wavelength : float
        Laser wavelength in vacuum, m.
    sigma : array_like of float, shape (M,), optional
        Each peak's phase noise per frame, rad; learned when omitted.
    min_margin : float
        Frames below this margin are flagged.
    spread : array_like of float, shape (2,), optional
        Standard deviation of the prediction of ``(du, dpsi)``, rad; learned when
        omitted.
    step : array_like of float, shape (2,), optional
        The first frame step's prediction ``(du, dpsi)``, rad; with ``spread`` it
        replaces the first frames' wide search (a second pass knows them).

    Examples
    --------
    RB1, RF and FB1 see a surface rising 50 nm a frame (for RF, more than a quarter
    wave: its phase steps past pi, which the joint estimate resolves):

    >>> alphas = np.array([0.333, 1.0, 1.333])
    >>> estimator = JointEstimator(alphas, [-1, 1, 0], 532e-9)
    >>> for h in (0.0, 50e-9, 100e-9, 150e-9):  # m
    ...     frame = estimator.update(np.exp(4j * np.pi * alphas * h / 532e-9))
    >>> round(frame.height * 1e9, 6), round(abs(frame.vibration), 6)  # nm, rad
    (150.0, 0.0)
    """

    def __init__(
        self,
        alphas: ArrayLike,
        couplings: ArrayLike,
        wavelength: float,
        *,
        sigma: ArrayLike | None = None,
        min_margin: float = DEFAULT_MIN_MARGIN,
        spread: ArrayLike | None = None,
        step: ArrayLike | None = None,
    ) -> None:
        alpha = np.asarray(alphas, dtype=np.float64).ravel()
        coupling = np.asarray(couplings, dtype=np.float64).ravel()
        if alpha.size == 0:
            raise InputError("the joint estimate needs at least one peak")
        if coupling.shape != alpha.shape:
            raise InputError(f"{coupling.size} couplings given for {alpha.size} peaks")
        if not np.all(np.isfinite(alpha) & (alpha > 0)):
            raise InputError("every peak's alpha must be positive and finite (on its stored twin)")
        if not np.all(coupling == np.round(coupling)):
            raise InputError("couplings must be whole numbers (lattice coordinates along f_RF)")
        if not (math.isfinite(wavelength) and wavelength > 0):
            raise InputError(f"wavelength must be positive, got {wavelength} m")
        if not min_margin > 0:
            raise InputError(f"min_margin must be positive, got {min_margin}")
        self.alphas = alpha
        self.couplings = coupling
        self.wavelength = float(wavelength)
        self.min_margin = float(min_margin)
        self._dims = 2 if np.any(coupling != 0) else 1
        self._design = np.column_stack([alpha, coupling])[:, : self._dims]
        self._fixed_sigma = None if sigma is None else self._check_sigma(sigma)
        self._fixed_spread = None if spread is None else self._check_spread(spread)
        self._initial = None if step is None else self._check_step(step)
        self.reset()

    def _check_sigma(self, sigma: ArrayLike) -> NDArray[np.float64]:
        s = np.asarray(sigma, dtype=np.float64).ravel()
        if s.shape != self.alphas.shape or not np.all(np.isfinite(s) & (s > 0)):
            raise InputError(f"sigma must be {self.alphas.size} positive phase noises (rad)")
        return s

    def _check_spread(self, spread: ArrayLike) -> NDArray[np.float64]:
        s = np.asarray(spread, dtype=np.float64).ravel()
        if s.size != 2 or not np.all(np.isfinite(s) & (s > 0)):
            raise InputError("spread must be two positive standard deviations (rad)")
        return s[: self._dims]

    def _check_step(self, step: ArrayLike) -> NDArray[np.float64]:
        s = np.asarray(step, dtype=np.float64).ravel()
        if s.size != 2 or not np.all(np.isfinite(s)):
            raise InputError("step must be two finite phases (du, dpsi), rad")
        return s[: self._dims]

    def reset(self) -> None:
        """Forget every frame: the next one starts the series at zero."""
        m = self.alphas.size
        self._frames = 0
        self._last = np.full(m, np.nan + 0j)
        self._last_variance = np.full(m, np.nan)
        self._phase = np.full(m, np.nan)
        self._x_at = np.full((m, self._dims), np.nan)
        self._x = np.zeros(self._dims)
        self._step = np.zeros(self._dims) if self._initial is None else self._initial.copy()
        self._sigma2 = None if self._fixed_sigma is None else self._fixed_sigma**2
        self._innovation = np.full(self._dims, np.nan)
        self._updates = 0
        self._learned = 0

    @property
    def sigma(self) -> NDArray[np.float64] | None:
        """Each peak's phase noise per frame in use, rad (None before the first frame)."""
        return None if self._sigma2 is None else np.sqrt(self._sigma2)

    @property
    def spread(self) -> NDArray[np.float64]:
        """Standard deviation of the prediction of ``(du, dpsi)`` in use, rad."""
        return np.sqrt(self._prior_variance())

    def _wide(self) -> NDArray[np.float64]:
        """The prediction's spread with no past to go by: the window reaches 1.5 pi of
        the slowest peak's phase and of the reference arm's, no further. For water in
        air the alphas are nearly multiples of 1/3 and the couplings whole numbers, so a
        height step 3/8 of a wavelength away, with the reference arm a quarter turn away,
        fits every peak as well: only the past tells them apart, and a first frame with
        nothing before it may be flagged."""
        return np.array([math.pi / (3 * float(np.min(self.alphas))), math.pi / 3])[: self._dims]

    def _prior_variance(self) -> NDArray[np.float64]:
        """The prediction's variance of ``(du, dpsi)`` (its covariance is diagonal), rad^2."""
        if self._fixed_spread is not None and (self._updates >= 3 or self._initial is not None):
            return INFLATE * self._fixed_spread**2 + FLOOR**2
        if self._updates < 3:
            return self._wide() ** 2
        return INFLATE * self._innovation + FLOOR**2

    def update(
        self, values: ArrayLike, sigma: ArrayLike | None = None, *, intervals: int = 1
    ) -> JointFrame:
        """Take one frame's carrier values and return the joint estimate.

        Parameters
        ----------
        values : array_like of complex, shape (M,)
            Each peak's complex carrier value on its stored twin (or its wrapped phase,
            rad); NaN where not measured.
        sigma : array_like of float, shape (M,), optional
            This frame's phase noise per peak, rad (else the given or learned ones).
        intervals : int
            Frame intervals since the frame before (more than one after lost frames:
            :func:`~holoview.processing.series.frame_gaps.intervals_of`).

        Returns
        -------
        JointFrame
        """
        z = np.asarray(values)
        if z.shape != self.alphas.shape:
            raise InputError(f"{z.size} values given for {self.alphas.size} peaks")
        z = z.astype(np.complex128) if np.iscomplexobj(z) else np.exp(1j * z.astype(np.float64))
        present = np.isfinite(z) & (z != 0)
        if self._sigma2 is None and np.any(present):
            level = np.abs(z[present])
            guess = np.full(self.alphas.size, FIRST_SIGMA * float(np.max(level)))
            guess[present] /= level
            guess[~present] = FIRST_SIGMA * 10
            self._sigma2 = guess**2
        now = self._sigma2 if sigma is None else self._check_sigma(sigma) ** 2
        if now is None:  # nothing measured yet: every peak at the fallback noise
            now = np.full(self.alphas.size, (FIRST_SIGMA * 10) ** 2)
        seen = present & np.isfinite(self._phase)
        turns = np.zeros(self.alphas.size, dtype=np.int64)
        margin, vibration_margin, flagged = math.inf, math.inf, False
        if np.any(seen):
            y = np.angle(z[seen] * np.conj(self._last[seen]))
            offset = self._design[seen] @ self._x - np.sum(
                self._design[seen] * self._x_at[seen], axis=1
            )
            before = self._last_variance[seen]
            variance = now[seen] + np.where(np.isfinite(before), before, now[seen])
            n, step, margin, vibration_margin = self._resolve(
                self._design[seen], y, offset, variance, intervals
            )
            turns[seen] = n
            flagged = margin < self.min_margin
            self._phase[seen] += y + 2 * np.pi * n
            self._learn(
                np.flatnonzero(seen),
                y + 2 * np.pi * n - offset,
                variance,
                step,
                flagged=flagged,
                noise=sigma is None,
                spread=intervals == 1,
            )
        fresh = present & ~np.isfinite(self._phase)
        x = self._solve(present & ~fresh, now)
        if np.any(seen):
            self._step = (x - self._x) / intervals
        self._x = x
        self._phase[fresh] = self._design[fresh] @ x
        self._x_at[present] = x
        self._last[present] = z[present]
        if now is not None:
            self._last_variance[present] = now[present]
        self._frames += 1
        phases = np.where(present, self._phase, np.nan)
        if flagged:
            logger.info("frame %d: ambiguity margin %.2f", self._frames - 1, margin)
        return JointFrame(
            height=float(x[0]) * self.wavelength / (4 * np.pi) if np.any(present) else math.nan,
            vibration=float(x[1]) if self._dims == 2 and np.any(present) else math.nan,
            phases=phases,
            turns=turns,
            margin=margin,
            vibration_margin=vibration_margin,
            flagged=flagged,
        )

    def _solve(self, rows: NDArray[np.bool_], variance: NDArray[np.float64]) -> NDArray[np.float64]:
        """Height and reference phase from the frame's unwrapped phases (weighted LSQ)."""
        if not np.any(rows):
            return self._x.copy()
        a = self._design[rows]
        w = 1.0 / variance[rows]
        if _rank(a) < self._dims:
            # one direction unseen (e.g. only RF): hold the reference phase
            held = self._x.copy()
            target = self._phase[rows] - (a[:, 1:] @ held[1:] if self._dims == 2 else 0.0)
            held[0] = float(np.sum(w * a[:, 0] * target) / np.sum(w * a[:, 0] ** 2))
            return held
        normal = a.T @ (w[:, None] * a)
        return np.linalg.solve(normal, a.T @ (w * self._phase[rows]))

    def _resolve(
        self,
        a: NDArray[np.float64],
        y: NDArray[np.float64],
        offset: NDArray[np.float64],
        variance: NDArray[np.float64],
        intervals: int,
    ) -> tuple[NDArray[np.int64], NDArray[np.float64], float, float]:
        """The integers, the step and the margins of one frame (module documentation)."""
        predicted = self._step * intervals
        if self._dims == 2:
            predicted[1] = 0.0
        prior = self._prior_variance() * intervals**2
        best = _search(a, y - offset, variance, predicted, prior)
        dof = max(a.shape[0] - self._dims, 1)
        if best.observed > dof + CHI2_SIGMAS * math.sqrt(2 * dof) + CHI2_SIGMAS**2:
            wide = _search(a, y - offset, variance, predicted, self._wide() ** 2)
            if wide.observed < best.observed:
                best = wide
        return best.turns, best.step, best.margin, best.vibration_margin

    def _learn(
        self,
        rows: NDArray[np.int64],
        steps: NDArray[np.float64],
        variance: NDArray[np.float64],
        step: NDArray[np.float64],
        *,
        flagged: bool,
        noise: bool,
        spread: bool,
    ) -> None:
        """Update the prediction's spread (every frame one interval after the last: a
        wrong step widens it) and the peaks' noise (frames resolved with confidence
        only) from a frame.

        ``rows`` are the peaks of ``steps`` (their unwrapped steps less the offsets of
        missed frames), ``step`` the frame's solution; ``noise``: learn the peaks'
        noise (not when this frame's was given); ``spread``: learn the spread.
        """
        if spread:
            rate = 1.0 / min(self._updates + 1, MEMORY)
            predicted = self._step * np.array([1.0, 0.0])[: self._dims]
            innovation = (step - predicted) ** 2
            if np.all(np.isfinite(self._innovation)):
                self._innovation = (1 - rate) * self._innovation + rate * innovation
            else:
                self._innovation = innovation
            self._updates += 1
        a = self._design[rows]
        if flagged or not noise or self._fixed_sigma is not None or rows.size <= self._dims:
            return
        if self._sigma2 is None:
            return
        w = 1.0 / variance
        hat = np.einsum("ij,jk,ik->i", a, np.linalg.pinv(a.T @ (w[:, None] * a)), a) * w
        keep = hat < 0.95
        if not np.any(keep):
            return
        residual = steps - a @ step
        estimate = residual[keep] ** 2 / (2 * (1 - hat[keep]))
        learn = 1.0 / min(self._learned + 2, MEMORY)
        target = rows[keep]
        self._sigma2[target] = (1 - learn) * self._sigma2[target] + learn * estimate
        self._learned += 1


@dataclass(frozen=True)
class _Solution:
    turns: NDArray[np.int64]
    step: NDArray[np.float64]
    cost: float
    observed: float
    margin: float
    vibration_margin: float


def _search(
    a: NDArray[np.float64],
    y: NDArray[np.float64],
    variance: NDArray[np.float64],
    predicted: NDArray[np.float64],
    prior_variance: NDArray[np.float64],
) -> _Solution:
    """Integer least squares in ``dx``-space over the prediction's window.

    ``y`` are the wrapped steps less the offsets of missed frames: ``y + 2 pi n = a dx``;
    ``prior_variance`` the prediction's (diagonal) variance of ``dx``.
    """
    dims = a.shape[1]
    w = 1.0 / variance
    prior_weight = 1.0 / prior_variance
    prior = np.diag(prior_weight)
    inverse = _inverse(a.T @ (w[:, None] * a) + prior)
    half = WINDOW_SIGMAS * np.sqrt(prior_variance)
    corners = _corners(dims) * half + predicted
    reach = corners @ a.T - y  # (corners, peaks): 2 pi n at the window's corners
    low = np.floor(reach.min(axis=0) / (2 * np.pi)) - 1
    high = np.ceil(reach.max(axis=0) / (2 * np.pi)) + 1
    count = high - low + 1
    pivots = _pivots(a, count, dims)
    grids = [np.arange(low[p], high[p] + 1) for p in pivots]
    combos = np.array(np.meshgrid(*grids, indexing="ij")).reshape(len(pivots), -1).T
    if combos.shape[0] > MAX_CANDIDATES:
        centre = np.array([(a[p] @ predicted - y[p]) / (2 * np.pi) for p in pivots])
        order = np.argsort(np.sum((combos - centre) ** 2, axis=1))
        combos = combos[order[:MAX_CANDIDATES]]
    # each pivot pair fixes a step (with the prediction, should the pivots not span)
    rows = a[pivots]
    w_rows = w[pivots]
    pivot_inverse = _inverse(rows.T @ (w_rows[:, None] * rows) + prior)
    target = y[pivots] + 2 * np.pi * combos
    trial = (pivot_inverse @ ((target * w_rows) @ rows + prior @ predicted).T).T
    for _ in range(2):
        turns = np.rint((trial @ a.T - y) / (2 * np.pi))
        target = y + 2 * np.pi * turns
        trial = (inverse @ ((target * w) @ a + prior @ predicted).T).T
    residual = target - trial @ a.T
    observed = np.sum(residual**2 * w, axis=1)
    deviation = trial - predicted
    cost = observed + (deviation**2) @ prior_weight
    first = _first_of_each(turns)
    first = first[np.argsort(cost[first])]
    best = int(first[0])
    # Solutions a whole turn of the reference arm apart (couplings are integers) give the
    # same height: they bear on the vibration series, not on the height's.
    same_height = np.abs(trial[first, 0] - trial[best, 0]) <= SAME_HEIGHT
    margins = []
    for group in (~same_height, same_height):
        others = first[group & (first != best)]
        gap = float(np.min(cost[others]) - cost[best]) if others.size else math.inf
        margins.append(math.sqrt(max(gap, 0.0)) / 2)
    return _Solution(
        turns=turns[best].astype(np.int64),
        step=trial[best],
        cost=float(cost[best]),
        observed=float(observed[best]),
        margin=margins[0],
        vibration_margin=margins[1],
    )


def _first_of_each(turns: NDArray[np.float64]) -> NDArray[np.int64]:
    """The index of each distinct row's first occurrence, rows in lexicographic order.

    ``np.unique(turns, axis=0, return_index=True)[1]``, through one integer key per row
    (the rows are small whole numbers): a third of its time on a frame's candidates.
    """
    rows = turns.astype(np.int64)
    low = rows.min(axis=0)
    span = rows.max(axis=0) - low + 1
    if math.prod(int(s) for s in span) >= 2**62:  # keys past int64: numpy's own
        return np.asarray(np.unique(turns, axis=0, return_index=True)[1], dtype=np.int64)
    key = np.zeros(rows.shape[0], dtype=np.int64)
    for j in range(rows.shape[1]):
        key = key * span[j] + (rows[:, j] - low[j])
    return np.unique(key, return_index=True)[1]


@lru_cache(maxsize=8)
def _corners(dims: int) -> NDArray[np.float64]:
    """The ``2**dims`` corners of the unit box, ``(-1 or 1, ...)``."""
    return np.array(list(itertools.product(*[(-1.0, 1.0)] * dims)))


def _inverse(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """``np.linalg.inv(m)`` of a 1 x 1 or 2 x 2 matrix in closed form (else LAPACK's)."""
    if m.shape == (1, 1):
        return 1.0 / m
    if m.shape == (2, 2):
        (p, q), (r, t) = m
        return np.array([[t, -q], [-r, p]], dtype=np.float64) / float(p * t - q * r)
    return np.asarray(np.linalg.inv(m), dtype=np.float64)


def _pivots(a: NDArray[np.float64], count: NDArray[np.float64], dims: int) -> list[int]:
    """The peaks with the fewest integers in the window, independent of one another."""
    order = [int(i) for i in np.argsort(count, kind="stable")]
    chosen = [order[0]]
    for i in order[1:]:
        if len(chosen) == dims:
            break
        if _rank(a[[*chosen, i]]) == len(chosen) + 1:
            chosen.append(i)
    return chosen


def _rank(a: NDArray[np.float64]) -> int:
    """``np.linalg.matrix_rank(a)``, remembered: a run's design rows are few, its frames many."""
    rows = np.ascontiguousarray(a, dtype=np.float64)
    return _rank_of(rows.tobytes(), rows.shape[0], rows.shape[1])


@lru_cache(maxsize=1024)
def _rank_of(data: bytes, rows: int, cols: int) -> int:
    return int(np.linalg.matrix_rank(np.frombuffer(data, dtype=np.float64).reshape(rows, cols)))
