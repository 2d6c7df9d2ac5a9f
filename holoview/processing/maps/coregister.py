"""Co-registration of the peaks' maps: measured displacements, accumulated over frames.

Each hologram images a laterally shifted patch of the surface (paper section 2,
``h_AB(r) = h(r + delta_AB)``), so the peaks' maps must be moved onto one grid
before they are fused. :class:`DisplacementEstimator` measures each map's shift
against a reference peak's map from their cross-power spectrum, summed over frames:
the surface's structure adds up coherently from frame to frame, the peaks'
independent noise does not (maps of opposite signs, such as phases of peaks whose
alphas differ in sign, are recognised), so a shift too small to see in one noisy
relative map (a fraction of a pixel) becomes measurable over tens of frames. A
surface without structure (uniform evaporation) gives no measurable shift, and
needs none.

Estimate: with ``moving(r) = reference(r - d)`` the summed cross-power
``C(k) = sum_t F_ref(k) conj(F_moving(k))`` is ``|F_ref|^2 exp(2 pi i k.d)``. The
whole-pixel part of ``d`` is the peak of the cross-correlation (the inverse FFT of
``C``); the rest is a weighted least-squares fit of the remaining phase ramp over
the coherent bins, weights ``|C|``, which also gives its standard error (the
window couples neighbouring bins: the fit's error is scaled by how many of them are
independent). Each map is compared with the reference on the pixels both trust, the
two mean-subtracted there, Hann-windowed, and brought to zero at the pixels either
does not trust by a raised-cosine edge :data:`EDGE_TAPER_PX` wide: the edges of the
peaks' trusted pixels (border widths set by their windows, amplitude) differ, and a
step at an edge that one map has and the other not would count as structure.

The window stays put while the surface moves under it, which pulls a single
estimate towards zero: by a few per cent for detail a few pixels across, but on a
simulated standing wave a box long the shift came out at a third of the model's.
So the estimate is iterated as frames come: each frame's moving maps are first
co-registered with the current estimate, and after :data:`UPDATE_EVERY` frames
(then twice as many each time, up to :data:`MAX_UPDATE_EVERY`: later updates,
smaller, average more frames) the residual shift measured on them is added to it
and the sums start again. The residual, and with it the pull, shrinks at each
update. On detail a few pixels across the first update is within 0.02 pixel of the
model's displacement. On a standing wave a box long, the shifts across the wave
came within 10 % in 200 frames. The shifts along it still fell short by up to half,
and the smallest one, 0.04 map pixel, came out with the wrong sign.

A residual counts as measured when the cross-correlation's peak stands out of what
the maps' noise alone would give (:data:`MIN_SIGNIFICANCE`) and its standard
errors are below :data:`MAX_STDERR`; a surface without structure in common leaves
the estimate where it was (zero at first). A measured residual moves the estimate
only when it stands :data:`MIN_STEP_SIGMAS` standard errors from zero; one within
its errors confirms it. Where the surface's structure spans the maps (a damped mode
about a wavelength across them: the ringdown simulation), the pull makes each
residual mostly noise; added all the same, update after update, they walked the
estimate away: RF a camera pixel in each axis in 512 frames, and the fused map's
centre 0.6 map pixel off, where the truth has no shift.
Shifts are in pixels of the maps' grid, ``(dy, dx)``, with ``moving(r) = reference(r - d)``:
:func:`~holoview.processing.maps.map_moves.coregister` moves each map by ``-d`` onto the
reference's grid.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from holoview.errors import InputError
from holoview.processing.maps.map_moves import coregister

#: Smallest side (pixels) of maps the estimator takes; smaller maps are not co-registered.
MIN_MAP_SIDE = 8

#: A shift is taken as measured when both standard errors are below this (pixels).
MAX_STDERR = 0.1

#: Bins whose coherence ``|C| / sqrt(P_ref P_moving)`` is below this are left out of the fit.
MIN_COHERENCE = 0.5

#: Fewest coherent bins a fit needs.
MIN_BINS = 8

#: A measured residual moves the estimate when it is this many standard errors from zero.
MIN_STEP_SIGMAS = 3.0

#: Frames summed before the first update of the current estimate.
UPDATE_EVERY = 10

#: Most frames summed between two updates.
MAX_UPDATE_EVERY = 80

#: The normalised correlation peak must exceed this many times its noise-only spread,
#: ``1 / sqrt(n_eff frames / NOISE_AREA)`` with ``n_eff`` the window's effective
#: pixel count.
MIN_SIGNIFICANCE = 8.0

#: Width (pixels) of the raised-cosine edge by which the maps fall to zero at the pixels
#: untrusted in any of them (module documentation).
EDGE_TAPER_PX = 4.0

#: Masks of trusted pixels whose pair weights :class:`DisplacementEstimator` keeps.
WEIGHTS_KEPT = 16

#: Pixels over which a map's noise is correlated (the spectral window's footprint);
#: conservative, so that noise alone is not taken for structure.
NOISE_AREA = 4.0


@dataclass(frozen=True)
class Displacement:
    """One map's shift against the reference map.

    Attributes
    ----------
    shift : tuple of float
        ``(dy, dx)`` in pixels of the maps' grid: ``map(r) ~ reference(r - shift)``;
        ``(0, 0)`` when not measured.
    stderr : tuple of float
        Standard errors (pixels) of the latest measured step of the estimate; infinite
        when none was measured.
    measured : bool
        Whether any step of the estimate was measured (significant correlation, both
        standard errors below :data:`MAX_STDERR`).
    bins : int
        Coherent spectral bins that step's fit used.
    """

    shift: tuple[float, float]
    stderr: tuple[float, float]
    measured: bool
    bins: int


_UNMEASURED = Displacement((0.0, 0.0), (float("inf"), float("inf")), False, 0)


def _hann(n: int) -> np.ndarray:
    return np.hanning(n + 2)[1:-1]  # no zero at the ends: every pixel counts


def _moves(residual: Displacement) -> bool:
    """Whether a residual moves the estimate: measured, and :data:`MIN_STEP_SIGMAS` of its
    standard errors from zero.

    A residual within its errors of zero confirms the estimate. Added all the same, the
    residuals of a surface whose structure spans the maps (a mode a box long: the
    window's pull makes each one mostly noise) walked the estimate away from the truth,
    update after update (module documentation).
    """
    if not residual.measured:
        return False
    with np.errstate(divide="ignore", invalid="ignore"):
        sigmas = np.hypot(*(np.divide(residual.shift, residual.stderr)))
    return bool(sigmas >= MIN_STEP_SIGMAS) or not np.isfinite(sigmas)


def _edge_taper(trusted: np.ndarray) -> np.ndarray:
    """A weight rising as a raised cosine from 0 at the untrusted pixels to 1 at
    :data:`EDGE_TAPER_PX` pixels from them (1 everywhere when all are trusted)."""
    if trusted.all():
        return np.ones(trusted.shape)
    if not trusted.any():
        return np.zeros(trusted.shape)
    distance = ndimage.distance_transform_edt(trusted)
    return 0.5 - 0.5 * np.cos(np.pi * np.clip(distance / (EDGE_TAPER_PX + 1.0), 0.0, 1.0))


def _weighted(
    values: np.ndarray, trusted: np.ndarray, weight: np.ndarray, total: float
) -> np.ndarray:
    """``values`` less their weighted mean over ``trusted``, times ``weight``; 0 elsewhere.

    ``total``: the sum of ``weight`` over ``trusted``.
    """
    if not total > 0:
        return np.zeros(values.shape)
    # the plain mean first: a constant map is then exactly zero, not rounding residue
    # that every map of a flat surface shares
    centred = values - values[trusted].mean()
    mean = float(np.sum(centred[trusted] * weight[trusted])) / total
    return np.where(trusted, centred - mean, 0.0) * weight


class DisplacementEstimator:
    """Estimate the maps' shifts from frame after frame, iteratively (module documentation).

    Parameters
    ----------
    shape : tuple of int
        ``(rows, cols)`` of every map.
    count : int
        Maps per frame (peaks), at least 2.
    reference : int
        Index of the map the others are registered to.
    update_every : int
        Frames summed before the first update of the current estimate (then twice as
        many each time, up to :data:`MAX_UPDATE_EVERY`).
    """

    def __init__(
        self,
        shape: tuple[int, int],
        count: int,
        reference: int = 0,
        update_every: int = UPDATE_EVERY,
    ) -> None:
        rows, cols = int(shape[0]), int(shape[1])
        if min(rows, cols) < MIN_MAP_SIDE:
            raise InputError(
                f"maps of shape {shape} are too small to co-register "
                f"(>= {MIN_MAP_SIDE} x {MIN_MAP_SIDE})"
            )
        if count < 2:
            raise InputError(f"co-registration needs at least 2 maps, got {count}")
        if not 0 <= reference < count:
            raise InputError(f"reference map {reference} is not one of the {count} maps")
        if update_every < 1:
            raise InputError(f"update_every must be >= 1 frame, got {update_every}")
        self.shape = (rows, cols)
        self.count = int(count)
        self.reference = int(reference)
        self.update_every = int(update_every)
        self._window = np.outer(_hann(rows), _hann(cols))
        #: independent pixels the windows of the frames summed leave, for white noise
        self._independent = np.zeros(count)
        #: frames each pair of maps added since the last update (with pixels in common)
        self._paired = np.zeros(count)
        self._energy = np.zeros((count, 2))
        spectrum_shape = (rows, cols // 2 + 1)
        self._cross = np.zeros((count, *spectrum_shape), dtype=np.complex128)
        self._power = np.zeros((count, 2, *spectrum_shape), dtype=np.float64)
        #: per pixels trusted (their mask's bytes): the pair's weight, the sum of the weight
        #: over them, and the independent pixels it leaves (:meth:`_pair_weight`)
        self._weights: dict[bytes, tuple[np.ndarray, float, float]] = {}
        self.reset()

    def reset(self) -> None:
        """Forget every frame added and the current estimate."""
        #: Frames added since construction or :meth:`reset`.
        self.frames = 0
        self._interval = self.update_every
        self._start_sums()
        self._current = [(0.0, 0.0)] * self.count
        self._last = [_UNMEASURED] * self.count
        self._answer: list[Displacement] | None = None

    def _start_sums(self) -> None:
        self._summed = 0
        self._independent[...] = 0
        self._paired[...] = 0
        self._cross[...] = 0
        self._power[...] = 0
        self._energy[...] = 0

    def add(self, maps: Sequence[np.ndarray]) -> None:
        """Add one frame's maps (NaN where untrusted; not modified).

        Raises
        ------
        InputError
            For another number of maps or another shape.
        """
        if len(maps) != self.count:
            raise InputError(f"{len(maps)} maps given, the estimator holds {self.count}")
        for values in maps:
            if np.shape(values) != self.shape:
                raise InputError(
                    f"map of shape {np.shape(values)}; the estimator holds {self.shape}"
                )
        moved = [np.asarray(m, np.float64) for m in coregister(maps, self._current)]
        reference = moved[self.reference]
        sides: dict[bytes, tuple[np.ndarray, np.ndarray, float]] = {}
        for j, values in enumerate(moved):
            if j != self.reference:
                self._add_pair(j, reference, values, sides)
        self.frames += 1
        self._summed += 1
        self._answer = None
        if self._summed >= self._interval:
            self._update()
            self._interval = min(2 * self._interval, max(self.update_every, MAX_UPDATE_EVERY))

    def _add_pair(
        self,
        j: int,
        reference: np.ndarray,
        values: np.ndarray,
        sides: dict[bytes, tuple[np.ndarray, np.ndarray, float]],
    ) -> None:
        """Add the cross-power of map ``j`` and the reference on the pixels both trust.

        Both fall to zero by the same tapered window (:func:`_edge_taper`) at the pixels
        either does not trust: the edges of their trusted pixels, which differ from peak
        to peak (border widths, amplitude), are not taken for structure in common.
        ``sides``: this frame's reference side of a pair (its spectrum, power and energy)
        by the pixels trusted, the same for every map that trusts the same pixels.
        """
        trusted = np.isfinite(reference) & np.isfinite(values)
        key = trusted.tobytes()
        weight, total, independent = self._pair_weight(trusted, key)
        if not independent > 0:
            return
        side = sides.get(key)
        if side is None:
            weighted = _weighted(reference, trusted, weight, total)
            ref = np.fft.rfft2(weighted)
            side = sides[key] = (ref, (ref * np.conj(ref)).real, float(np.vdot(weighted, weighted)))
        ref, ref_power, ref_energy = side
        weighted = _weighted(values, trusted, weight, total)
        spectrum = np.fft.rfft2(weighted)
        self._cross[j] += ref * np.conj(spectrum)
        self._power[j, 0] += ref_power
        self._power[j, 1] += (spectrum * np.conj(spectrum)).real
        self._energy[j] += (ref_energy, float(np.vdot(weighted, weighted)))
        self._independent[j] += independent
        self._paired[j] += 1

    def _pair_weight(self, trusted: np.ndarray, key: bytes) -> tuple[np.ndarray, float, float]:
        """The weight of a pair whose pixels ``trusted`` both trust (Hann window, edge
        taper), its sum over them, and the independent pixels it leaves for white noise
        (0: no weight anywhere).

        Kept by mask: the trusted pixels are most often those of earlier frames (the
        border, the aperture), and the taper's distance transform is the costliest step
        of adding a pair (the same numbers, computed once). ``key``: ``trusted``'s bytes.
        """
        known = self._weights.get(key)
        if known is not None:
            return known
        weight = self._window * _edge_taper(trusted)
        squared = weight**2
        independent = float(squared.sum() ** 2 / (squared**2).sum()) if squared.any() else 0.0
        if len(self._weights) >= WEIGHTS_KEPT:
            self._weights.clear()  # a surface whose masks keep changing: start over
        known = (weight, float(weight[trusted].sum()), independent)
        self._weights[key] = known
        return known

    def _update(self) -> None:
        """Add each measured residual that stands out of its errors to the current
        estimate (:func:`_moves`); start the sums again."""
        for j, residual in enumerate(self._residuals()):
            if residual.measured:
                self._last[j] = residual
            if _moves(residual):
                dy, dx = self._current[j]
                self._current[j] = (dy + residual.shift[0], dx + residual.shift[1])
        self._start_sums()

    def _residuals(self) -> list[Displacement]:
        return [
            _UNMEASURED if j == self.reference or self._summed == 0 else self._fit(j)
            for j in range(self.count)
        ]

    def displacements(self) -> list[Displacement]:
        """Return each map's shift against the reference (the reference's own is zero).

        The current estimate plus the residual measured on the frames summed since the
        last update, when that is measured. ``stderr`` is the latest measured
        residual's; ``measured`` says whether any update or the residual was. Kept
        until the next frame is added.
        """
        if self._answer is not None:
            return list(self._answer)
        out = []
        for j, residual in enumerate(self._residuals()):
            if j == self.reference:
                out.append(Displacement((0.0, 0.0), (0.0, 0.0), True, 0))
                continue
            dy, dx = self._current[j]
            last = self._last[j]
            if residual.measured:
                last = residual
            if _moves(residual):
                dy, dx = dy + residual.shift[0], dx + residual.shift[1]
            out.append(Displacement((dy, dx), last.stderr, last.measured, last.bins))
        self._answer = out
        return list(out)

    def _fit(self, j: int) -> Displacement:
        rows, cols = self.shape
        cross = self._cross[j]
        energy = self._energy[j, 0] * self._energy[j, 1]
        independent = float(self._independent[j])
        if not energy > 0:
            return _UNMEASURED
        # whole pixels: the cross-correlation peaks at -d (see the module documentation),
        # negative for maps of opposite signs (phases of peaks with alphas of both signs)
        correlation = np.fft.irfft2(cross, s=self.shape)
        py, px = np.unravel_index(int(np.argmax(np.abs(correlation))), self.shape)
        peak = abs(float(correlation[py, px])) / np.sqrt(energy)
        if not independent > 0:
            return _UNMEASURED
        if peak < MIN_SIGNIFICANCE / np.sqrt(independent / NOISE_AREA):
            return _UNMEASURED
        if correlation[py, px] < 0:
            cross = -cross
        d0 = (-(((py + rows // 2) % rows) - rows // 2), -(((px + cols // 2) % cols) - cols // 2))
        ky = np.fft.fftfreq(rows)[:, None]
        kx = np.fft.rfftfreq(cols)[None, :]
        residual = cross * np.exp(-2j * np.pi * (ky * d0[0] + kx * d0[1]))
        with np.errstate(invalid="ignore", divide="ignore"):
            coherence = np.abs(cross) / np.sqrt(self._power[j, 0] * self._power[j, 1])
        use = coherence >= MIN_COHERENCE
        use[0, 0] = False
        n = int(np.count_nonzero(use))
        if n < MIN_BINS:
            return _UNMEASURED
        weights = np.abs(residual[use])
        phase = np.angle(residual[use])
        design = (
            2
            * np.pi
            * np.stack(
                [np.broadcast_to(ky, use.shape)[use], np.broadcast_to(kx, use.shape)[use]], axis=1
            )
        )
        weighted = design * weights[:, None]
        normal = design.T @ weighted
        try:
            covariance_unit = np.linalg.inv(normal)
        except np.linalg.LinAlgError:
            return _UNMEASURED
        fine = covariance_unit @ (weighted.T @ phase)
        misfit = phase - design @ fine
        dof = max(n - 2, 1)
        scale = float(np.sum(weights * misfit**2) / dof)
        # the window couples neighbouring bins: of the n bins fitted, about n times the
        # window's independent pixels over all pixels are independent
        coupled = rows * cols * float(self._paired[j]) / independent
        stderr = np.sqrt(np.diag(covariance_unit) * scale * coupled)
        shift = (float(d0[0] + fine[0]), float(d0[1] + fine[1]))
        err = (float(stderr[0]), float(stderr[1]))
        measured = bool(np.all(np.isfinite(stderr)) and max(err) < MAX_STDERR)
        if not measured:
            return Displacement((0.0, 0.0), err, False, n)
        return Displacement(shift, err, True, n)


def fuse_coregistered(
    maps: Sequence[np.ndarray],
    noises: Sequence[float | None],
    shifts: Sequence[tuple[float, float]] | None = None,
    *,
    method: str = "spline",
) -> np.ndarray:
    """Fuse maps (NaN: untrusted) weighted by ``1 / noise^2``, co-registered first.

    Parameters
    ----------
    maps : sequence of ndarray, shape (rows, cols)
        Maps of one quantity (delta-h in m); not modified.
    noises : sequence of float or None
        Each map's noise (unit of the maps). When any is not a positive number (a
        reference frame, whose maps are zero), the maps are averaged unweighted.
    shifts : sequence of (dy, dx), optional
        Each map's :attr:`Displacement.shift` (pixels); the maps are moved onto the
        grid of the map whose shift is zero (:func:`coregister`).
    method : {"spline", "cubic"}
        The interpolation of :func:`coregister`.

    Returns
    -------
    ndarray of float32
        NaN where no map is trusted.
    """
    sigma = np.asarray(noises, dtype=np.float64)
    if not (np.all(np.isfinite(sigma)) and np.all(sigma > 0)):
        sigma = np.ones(len(maps))
    if shifts is not None:
        maps = coregister(maps, shifts, method=method)
    if not maps:
        raise InputError("no maps to fuse")
    # sum(w m) / sum(w) over the trusted maps of each pixel (heights.fuse's rule), one
    # map at a time: no stack of the frame's maps in float64
    shape = np.shape(maps[0])
    total = np.zeros(shape, dtype=np.float64)
    weight = np.zeros(shape, dtype=np.float64)
    for values, s in zip(maps, sigma, strict=True):
        array = np.asarray(values, dtype=np.float32)
        if array.shape != shape:
            raise InputError(f"maps of shapes {shape} and {array.shape} cannot be fused")
        trusted = np.isfinite(array)
        w = 1.0 / float(s) ** 2
        total += np.where(trusted, array, np.float32(0.0)) * w
        weight += trusted * w
    with np.errstate(invalid="ignore", divide="ignore"):
        fused = total / weight
    fused[weight == 0] = np.nan
    return fused.astype(np.float32)
