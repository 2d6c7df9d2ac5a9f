"""Carrier peaks of a hologram's spectrum: the :class:`Peak` record and :func:`find_peaks`.

A carrier is stored in cycles per pixel, ``(fx, fy)``: fx along columns, fy along
rows, numpy's FFT sign. Every carrier of a real frame has a twin at ``-f``; a
physical peak is listed once. Without a prefactor to decide which twin is the one
whose phase grows with the surface height (docs/design.md), :func:`find_peaks` keeps
the twin in the *canonical half-plane*: ``fx > 0``, or ``fx == 0`` and ``fy > 0``
(on FFT bins; the Nyquist column and row count as positive). A user who knows
better calls :meth:`Peak.flipped`.

Flags a peak can carry:

- ``"harmonic"``: within a bin of ``+-2 f`` of a stronger peak (a second-order peak
  from camera nonlinearity or saturation, at twice the frequency and twice alpha);
- ``"sum"``: within a bin of ``+-f1 +- f2`` for two stronger peaks. In this setup a
  genuine carrier can sit on a sum (``f_FBj = f_RBj + f_RF``), so the flag is a hint
  for identification, not a rejection;
- ``"overlap"``: closer than two window radii to another peak or twin;
- ``"near_nyquist"``: its window reaches past the Nyquist frequency (it wraps);
- ``"weak"``: its significance is less than twice the detection threshold;
- ``"surface"``: a sideband the surface puts around a carrier, not a peak of its own
  (:mod:`~holoview.processing.peaks.sidebands`; :attr:`Peak.sideband_of` names the
  carrier). It bounds no window and makes no other peak ``"overlap"``.

A frame damaged in transfer (rows of one value,
:func:`~holoview.processing.fourier.frames.frame_damage`)
is not searched: :func:`find_peaks` raises
:class:`~holoview.processing.fourier.frames.DamagedFrameError` with the reason, at once. The
search is bounded on any frame: at most :data:`MAX_CANDIDATES` candidates are
measured, and the relations are found with k-d trees (harmonics and sums of the
:data:`RELATION_PEAKS` strongest peaks, overlaps of all), ``O(n log n)`` in the
number of peaks.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from holoview.errors import InputError
from holoview.processing.fourier.fftplans import DEFAULT_THREADS, rfft2_plan
from holoview.processing.fourier.frames import (
    DamagedFrameError,
    check_frame,
    check_frame_content,
    frame_damage,
)
from holoview.processing.fourier.windows import auto_radii, auto_radius, wrap_frequency
from holoview.processing.peaks.carriers import REFINE_ITERATIONS, refine_frequencies
from holoview.processing.peaks.sidebands import surface_sidebands

#: Default significance threshold: a peak's magnitude over the local background median.
DEFAULT_THRESHOLD = 8.0

#: Default radius (cycles/pixel) around zero frequency where no carrier is sought.
DEFAULT_DC_RADIUS = 0.03

#: Smallest window radius, in FFT bins, before close peaks are flagged as overlapping.
MIN_RADIUS_BINS = 4.0

#: Side (bins) of the blocks whose medians estimate the local spectral background.
BACKGROUND_BLOCK = 16

#: Inner and outer radius (bins) of the ring whose median is a candidate's own background.
ANNULUS_BINS = (5, 12)

#: Tolerance (bins) when matching a peak to a harmonic or a sum of other carriers.
RELATION_TOLERANCE_BINS = 1.5

#: Candidates measured at most, the largest magnitudes first (a clean frame has a few dozen).
MAX_CANDIDATES = 256

#: The strongest peaks whose harmonics and pairwise sums are looked for.
RELATION_PEAKS = 32

#: Peaks whose carriers :func:`find_peaks` refines, the strongest first (a damaged frame
#: that is not recognised as such can hold hundreds of spurious ones).
MAX_REFINED = 32

#: Every flag :func:`find_peaks` can put on a peak (see the module documentation).
FLAGS: tuple[str, ...] = ("harmonic", "sum", "overlap", "near_nyquist", "weak", "surface")


@dataclass(frozen=True)
class Peak:
    """One physical carrier peak.

    Attributes
    ----------
    carrier : tuple of float
        ``(fx, fy)`` in cycles/pixel, sub-bin estimate.
    amplitude : float
        ``|S(f)| / S(0)``: the amplitude of the carrier's complex exponential relative
        to the mean intensity (the paper's ``A_AB``; a fringe ``Y0 (1 + 2 A cos)``).
    snr : float
        Peak magnitude over the local spectral background (median) around it.
    flags : frozenset of str
        See the module documentation.
    label : str or None
        A name such as ``"RB1"``.
    alpha : float or None
        Phase-to-height prefactor (``delta_h = delta_phi lambda / (4 pi alpha)``).
    carrier_error : float or None
        Uncertainty of ``carrier`` in FFT bins (standard error, both axes in
        quadrature) where it was measured (:func:`refine_carriers`), else None.
    sideband_of : tuple of float or None
        For a surface sideband (flag ``"surface"``), the carrier it surrounds,
        ``(fx, fy)`` cycles/pixel, on the twin nearest it; else None.
    sideband_order : int
        For a surface sideband, 1 at a wave's ``+-q``, 2 at a sum of two, 3 elsewhere
        in the surface's band (:class:`~holoview.processing.peaks.sidebands.Sideband`);
        else 0.
    """

    carrier: tuple[float, float]
    amplitude: float
    snr: float
    flags: frozenset[str] = field(default_factory=frozenset)
    label: str | None = None
    alpha: float | None = None
    carrier_error: float | None = None
    sideband_of: tuple[float, float] | None = None
    sideband_order: int = 0

    @property
    def surface_offset(self) -> tuple[float, float] | None:
        """A sideband's offset ``q`` from its carrier, cycles/pixel (None for a peak)."""
        if self.sideband_of is None:
            return None
        q = wrap_frequency(np.subtract(self.carrier, self.sideband_of))
        return float(q[0]), float(q[1])

    def relabelled(self, label: str | None, alpha: float | None = None) -> Peak:
        """Return a copy named ``label`` with prefactor ``alpha``."""
        return dataclasses.replace(self, label=label, alpha=alpha)

    def flipped(self) -> Peak:
        """Return the twin: the carrier negated, everything else kept.

        The phase at ``-f`` is minus the phase at ``+f``, so with the same positive
        alpha the twin reports heights of the opposite sign: this is how a user
        makes the phase grow with the height.
        """
        fx, fy = self.carrier
        parent = self.sideband_of
        return dataclasses.replace(
            self,
            carrier=(-fx, -fy),
            sideband_of=None if parent is None else (-parent[0], -parent[1]),
        )

    def with_flags(self, flags: frozenset[str] | set[str]) -> Peak:
        """Return a copy carrying ``flags`` instead of the current ones."""
        return dataclasses.replace(self, flags=frozenset(flags))


def _hann(n: int) -> np.ndarray:
    return (0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)).astype(np.float32)


def _hann_gain(offset: np.ndarray) -> np.ndarray:
    """Relative response of a Hann-apodised DFT to a tone ``offset`` bins off a bin centre."""
    d = np.asarray(offset, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.sinc(d) / (1.0 - d * d)
    return np.where(np.isclose(np.abs(d), 1.0), 0.5, gain)


def _full_magnitude(half: np.ndarray, cols: int) -> np.ndarray:
    """Expand a half spectrum's magnitude to the full, uncentred spectrum."""
    rows = half.shape[0]
    magnitude = np.empty((rows, cols), dtype=np.float32)
    nh = half.shape[1]
    magnitude[:, :nh] = np.abs(half)
    mirrored_rows = (-np.arange(rows)) % rows
    mirrored_cols = cols - np.arange(nh, cols)
    magnitude[:, nh:] = magnitude[:, mirrored_cols].take(mirrored_rows, axis=0)
    return magnitude


def _local_background(magnitude: np.ndarray) -> np.ndarray:
    """Median magnitude around each bin: block medians, smoothed by a median over blocks."""
    rows, cols = magnitude.shape
    b = BACKGROUND_BLOCK if min(rows, cols) >= 8 * BACKGROUND_BLOCK else 4
    by, bx = -(-rows // b), -(-cols // b)
    padded = np.pad(magnitude, ((0, by * b - rows), (0, bx * b - cols)), mode="wrap")
    blocks = padded.reshape(by, b, bx, b).transpose(0, 2, 1, 3).reshape(by, bx, b * b)
    coarse = np.median(blocks, axis=-1)
    coarse = ndimage.median_filter(coarse, size=5, mode="wrap")
    coarse = np.maximum(coarse, np.finfo(np.float32).tiny)
    return np.repeat(np.repeat(coarse, b, axis=0), b, axis=1)[:rows, :cols]


def _annulus_median(magnitude: np.ndarray, ky: int, kx: int) -> float:
    """Median magnitude on a ring of radii ANNULUS_BINS around bin (ky, kx) (periodic)."""
    inner, outer = ANNULUS_BINS
    offsets = np.arange(-outer, outer + 1)
    ring = np.hypot(offsets[:, None], offsets[None, :])
    ring = (ring >= inner) & (ring <= outer)
    rows, cols = magnitude.shape
    patch = magnitude[np.ix_((ky + offsets) % rows, (kx + offsets) % cols)]
    return float(np.median(patch[ring]))


def _refine(log_mag: np.ndarray, ky: int, kx: int) -> tuple[float, float]:
    """Sub-bin offsets (dy, dx) of a maximum by a parabola through the log magnitudes."""
    rows, cols = log_mag.shape
    offsets = []
    for axis, (k, n) in enumerate(((ky, rows), (kx, cols))):
        if axis == 0:
            left, mid, right = log_mag[(k - 1) % n, kx], log_mag[k, kx], log_mag[(k + 1) % n, kx]
        else:
            left, mid, right = log_mag[ky, (k - 1) % n], log_mag[ky, k], log_mag[ky, (k + 1) % n]
        denom = left - 2 * mid + right
        offsets.append(
            float(np.clip(0.5 * (left - right) / denom, -0.5, 0.5)) if denom < 0 else 0.0
        )
    return offsets[0], offsets[1]


def _canonical(ky: int, kx: int, rows: int, cols: int) -> bool:
    """Whether bin (ky, kx) of the full uncentred spectrum is on the kept twin's side."""
    if 0 < kx < (cols + 1) // 2:
        return True
    if kx == 0 or (cols % 2 == 0 and kx == cols // 2):
        return 0 < ky <= rows // 2 or (ky == 0 and kx != 0)
    return False


def _on_torus(points: np.ndarray, box: tuple[float, float]) -> np.ndarray:
    """``points`` (N, 2) folded into ``[0, box)`` (rounding can make ``mod`` return the side)."""
    folded = np.mod(points, box)
    return np.where(folded >= box, 0.0, folded)


def _periodic_tree(points: np.ndarray, box: tuple[float, float]) -> cKDTree:
    """A k-d tree of ``points`` (N, 2) on the torus of side ``box`` (periodic distances)."""
    return cKDTree(_on_torus(points, box), boxsize=box)


def _matches(
    tree: cKDTree, targets: np.ndarray, box: tuple[float, float], tol: float
) -> list[list[int]]:
    """For each target point, the indices of the tree's points within ``tol`` of it."""
    if len(targets) == 0:
        return []
    return list(tree.query_ball_point(_on_torus(targets, box), r=tol))


def flag_relations(
    peaks: Sequence[Peak], shape: tuple[int, int], *, radius: float | None = None
) -> list[Peak]:
    """Return the peaks with the harmonic, sum, overlap and near-Nyquist flags recomputed.

    Parameters
    ----------
    peaks : sequence of Peak
        Peaks of one frame; harmonics and sums are matched against stronger ones
        (by amplitude), among the :data:`RELATION_PEAKS` strongest.
    shape : tuple of int
        Frame shape ``(rows, cols)`` in pixels.
    radius : float, optional
        Window radius (cycles/pixel); by default :func:`auto_radius` of the carriers,
        at least :data:`MIN_RADIUS_BINS` bins.

    Notes
    -----
    ``O(n log n)`` in the number of peaks n: k-d trees on the torus of the spectrum
    (bins for the relations, cycles/pixel for the overlaps), queried at ``+-2 f`` for
    each of the strongest peaks and at ``+-f1 +- f2`` for each pair of them.
    """
    if not peaks:
        return []
    carriers = np.array([p.carrier for p in peaks], dtype=np.float64)
    amplitudes = np.array([p.amplitude for p in peaks], dtype=np.float64)
    own = np.array(["surface" not in p.flags for p in peaks])
    if radius is None:
        radius = auto_radius(
            carriers[own] if own.any() else carriers, min_radius=MIN_RADIUS_BINS / min(shape)
        )
    rows, cols = shape
    bins = carriers * (cols, rows)
    box = (float(cols), float(rows))
    tree = _periodic_tree(bins, box)
    strongest = np.argsort(-amplitudes, kind="stable")[:RELATION_PEAKS]
    harmonic = np.zeros(len(peaks), dtype=bool)
    summed = np.zeros(len(peaks), dtype=bool)
    doubled = np.concatenate([2 * bins[strongest], -2 * bins[strongest]])
    for q, found in enumerate(_matches(tree, doubled, box, RELATION_TOLERANCE_BINS)):
        j = strongest[q % len(strongest)]
        for i in found:
            harmonic[i] |= amplitudes[i] < amplitudes[j]
    pairs = [(j, k) for a, j in enumerate(strongest) for k in strongest[a + 1 :]]
    if pairs:
        first, second = np.array(pairs).T
        sums = [s1 * bins[first] + s2 * bins[second] for s1 in (1, -1) for s2 in (1, -1)]
        found_all = _matches(tree, np.concatenate(sums), box, RELATION_TOLERANCE_BINS)
        for q, found in enumerate(found_all):
            j, k = pairs[q % len(pairs)]
            weaker_than = min(amplitudes[j], amplitudes[k])
            for i in found:
                summed[i] |= amplitudes[i] < weaker_than
    overlap = np.zeros(len(peaks), dtype=bool)
    mine = np.flatnonzero(own)  # sidebands bound no window and overlap nothing
    if len(mine):
        everything = np.concatenate([carriers[mine], -carriers[mine]])
        neighbours = _periodic_tree(everything, (1.0, 1.0))
        k = min(3, len(everything))
        _, index = neighbours.query(_on_torus(carriers[mine], (1.0, 1.0)), k=k)
        for i, near in enumerate(np.reshape(index, (len(mine), k))):
            others = everything[[j for j in near.tolist() if j != i]]
            gap = wrap_frequency(carriers[mine[i]] - others)  # exact, as the window's own test
            overlap[mine[i]] = bool(np.hypot(gap[:, 0], gap[:, 1]).min() < 2 * radius)
    near_nyquist = own & (np.abs(carriers).max(axis=1) + radius > 0.5)
    out = []
    for i, peak in enumerate(peaks):
        flags = set(peak.flags) - {"harmonic", "sum", "overlap", "near_nyquist"}
        for flag, on in (
            ("harmonic", harmonic[i]),
            ("sum", summed[i]),
            ("overlap", overlap[i]),
            ("near_nyquist", near_nyquist[i]),
        ):
            if on:
                flags.add(flag)
        out.append(peak.with_flags(flags))
    return out


def find_peaks(
    frame: np.ndarray,
    *,
    threshold: float = DEFAULT_THRESHOLD,
    dc_radius: float = DEFAULT_DC_RADIUS,
    max_peaks: int | None = None,
    min_separation: int = 3,
    radius: float | None = None,
    threads: int | None = None,
    refine: bool = True,
) -> list[Peak]:
    """Find every significant carrier of a hologram, each physical peak once.

    The frame is apodised (Hann) to keep its edges from smearing the spectrum, then
    a bin is a peak when it is the largest within ``min_separation`` bins and its
    magnitude exceeds ``threshold`` times the median magnitude of the spectrum
    around it: the larger of the median over blocks of :data:`BACKGROUND_BLOCK`
    bins (smoothed over 5 blocks) and the median on a ring of radii
    :data:`ANNULUS_BINS` around it, which discounts the speckle of an object's own
    sideband.
    Bins within ``dc_radius`` of zero frequency are skipped. Of each twin pair the
    canonical one is kept (module documentation). Carriers are refined below one bin
    by a parabola through the log magnitudes, and amplitudes corrected for the
    Hann window's response at that offset; then, with ``refine``, moved to the mean
    phase step of each one's field (:func:`refine_carriers`; the strongest
    :data:`MAX_REFINED`), which an object that
    broadens the peak does not pull aside as it pulls the maximum.

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        Pixel values (counts), any bit depth; square or not; not modified.
    threshold : float
        Significance over the local background (ratio of magnitudes), > 1.
    dc_radius : float
        Radius (cycles/pixel) around zero frequency excluded from the search.
    max_peaks : int, optional
        Keep only this many, the strongest.
    min_separation : int
        A peak is the maximum within this many bins (>= 1).
    radius : float, optional
        Window radius (cycles/pixel) for the overlap and near-Nyquist flags; by
        default from the carriers (:func:`flag_relations`).
    threads : int, optional
        FFTW threads.

    Returns
    -------
    list of Peak
        Sorted by decreasing amplitude.

    Raises
    ------
    DamagedFrameError
        For a frame damaged in transfer (rows of one value: lost packets), with the
        reason; nothing is searched.
    InputError
        For a frame that is not a 2-D monochrome image, holds NaN or is constant,
        or for parameters out of range.
    """
    array = check_frame(frame)
    check_frame_content(array)
    damage = frame_damage(array)
    if damage is not None:
        raise DamagedFrameError(f"frame is damaged: {damage}; no peaks searched", damage)
    if not threshold > 1:
        raise InputError(f"threshold must be > 1 (a ratio to the background), got {threshold}")
    if not 0 <= dc_radius < 0.5:
        raise InputError(f"dc_radius must be in [0, 0.5) cycles/pixel, got {dc_radius}")
    if max_peaks is not None and max_peaks < 1:
        raise InputError(f"max_peaks must be >= 1, got {max_peaks}")
    if min_separation < 1:
        raise InputError(f"min_separation must be >= 1 bin, got {min_separation}")
    rows, cols = array.shape
    plan = rfft2_plan(array.shape, threads=threads or DEFAULT_THREADS)
    apodise = np.outer(_hann(rows), _hann(cols))
    mean = float(np.mean(array, dtype=np.float64))
    buffer = plan.input_array
    np.subtract(array, np.float32(mean), out=buffer, casting="unsafe")
    np.multiply(buffer, apodise, out=buffer)
    plan()
    dc = mean * float(apodise.sum(dtype=np.float64))
    magnitude = _full_magnitude(plan.output_array, cols)
    background = _local_background(magnitude)
    size = 2 * min_separation + 1
    local_max = magnitude == ndimage.maximum_filter(magnitude, size=size, mode="wrap")
    significant = magnitude > threshold * background
    fy = np.fft.fftfreq(rows)[:, None]
    fx = np.fft.fftfreq(cols)[None, :]
    outside_dc = np.hypot(fx, fy) > dc_radius
    candidates = [
        (int(ky), int(kx))
        for ky, kx in np.argwhere(local_max & significant & outside_dc)
        if _canonical(int(ky), int(kx), rows, cols)
    ]
    if len(candidates) > MAX_CANDIDATES:
        strength = np.array([magnitude[ky, kx] for ky, kx in candidates])
        keep = np.argsort(-strength, kind="stable")[:MAX_CANDIDATES]
        candidates = [candidates[i] for i in sorted(keep.tolist())]
    log_mag = np.log(np.maximum(magnitude, np.finfo(np.float32).tiny))
    found = []
    for ky, kx in candidates:
        dy, dx = _refine(log_mag, int(ky), int(kx))
        gain = float(_hann_gain(np.array(dy)) * _hann_gain(np.array(dx)))
        carrier = (
            float(wrap_frequency((kx + dx) / cols)),
            float(wrap_frequency((ky + dy) / rows)),
        )
        snr = float(magnitude[ky, kx]) / max(
            float(background[ky, kx]), _annulus_median(magnitude, int(ky), int(kx))
        )
        if snr <= threshold:
            continue
        flags = {"weak"} if snr < 2 * threshold else set()
        amplitude = float(magnitude[ky, kx]) / (gain * dc) if dc > 0 else float("inf")
        found.append(Peak(carrier, amplitude, snr, frozenset(flags)))
    found.sort(key=lambda p: p.amplitude, reverse=True)

    def level(point: np.ndarray) -> float:
        """The amplitude at (x, y), bins: the largest of its 3 x 3 bins, if significant."""
        kx, ky = int(np.rint(point[0])), int(np.rint(point[1]))
        near = magnitude[np.ix_(np.arange(ky - 1, ky + 2) % rows, np.arange(kx - 1, kx + 2) % cols)]
        top = float(near.max())
        significant = top > 0.5 * threshold * float(background[ky % rows, kx % cols])
        return top / dc if significant and dc > 0 else 0.0

    found = _mark_sidebands(found, (rows, cols), level)
    if max_peaks is not None:
        found = found[:max_peaks]
    if refine and found:
        np.copyto(buffer, array, casting="unsafe")
        plan()
        found = _refine_peaks(plan.output_array, (rows, cols), found)
    return flag_relations(found, (rows, cols), radius=radius)


def _mark_sidebands(
    peaks: list[Peak], shape: tuple[int, int], level: Callable[[np.ndarray], float]
) -> list[Peak]:
    """The peaks, those that are the surface's sidebands flagged ``"surface"``."""
    carriers = np.array([p.carrier for p in peaks], dtype=np.float64).reshape(-1, 2)
    amplitudes = np.array([p.amplitude for p in peaks], dtype=np.float64)
    out = list(peaks)
    for i, sideband in enumerate(surface_sidebands(carriers, amplitudes, shape, level)):
        if sideband is not None:
            parent = carriers[sideband.parent] * sideband.sign
            out[i] = dataclasses.replace(
                peaks[i],
                flags=peaks[i].flags | {"surface"},
                sideband_of=(float(parent[0]), float(parent[1])),
                sideband_order=sideband.order,
            )
    return out


def _refine_peaks(half: np.ndarray, shape: tuple[int, int], peaks: list[Peak]) -> list[Peak]:
    """The strongest :data:`MAX_REFINED` peaks that are not sidebands, refined; sidebands'
    carriers followed (their offsets kept)."""
    own = [i for i, p in enumerate(peaks) if "surface" not in p.flags]
    chosen, rest = own[:MAX_REFINED], own[MAX_REFINED:]
    out = list(peaks)
    refined = _refined(half, shape, [peaks[i] for i in chosen], [peaks[i].carrier for i in rest])
    moved = {}
    for i, peak in zip(chosen, refined, strict=True):
        out[i] = peak
        moved[peaks[i].carrier] = peak.carrier
    for i, peak in enumerate(peaks):
        parent = peak.sideband_of
        if parent is None:
            continue
        sign = 1.0 if parent in moved else -1.0
        new = moved.get(parent if sign > 0 else (-parent[0], -parent[1]))
        if new is not None:
            out[i] = dataclasses.replace(peak, sideband_of=(sign * new[0], sign * new[1]))
    return out


def _refined(
    half: np.ndarray,
    shape: tuple[int, int],
    peaks: Sequence[Peak],
    neighbours: Sequence[tuple[float, float]] = (),
) -> list[Peak]:
    """The peaks with carriers refined from the frame's plain half spectrum, errors set."""
    carriers = np.array([p.carrier for p in peaks], dtype=np.float64)
    radii = auto_radii(carriers, neighbours=neighbours, min_radius=MIN_RADIUS_BINS / min(shape))
    moved, errors = refine_frequencies(half, shape, carriers, radii, iterations=REFINE_ITERATIONS)
    return [
        dataclasses.replace(
            p,
            carrier=(float(c[0]), float(c[1])),
            carrier_error=float(e) if np.isfinite(e) else None,
        )
        for p, c, e in zip(peaks, moved, errors, strict=True)
    ]


def refine_carriers(
    frame: np.ndarray,
    peaks: Sequence[Peak],
    *,
    neighbours: Sequence[tuple[float, float]] = (),
    threads: int | None = None,
) -> list[Peak]:
    """Return the peaks with carriers moved to their fields' mean phase step.

    Each peak is demodulated from the frame's spectrum through a window of the widest
    radius that reaches no other peak, twin, neighbour or the zero order, and
    its carrier moved by the mean phase step between neighbouring pixels, three times
    (:func:`~holoview.processing.peaks.carriers.refine_frequencies`); ``carrier_error`` is
    set to the carrier's uncertainty in FFT bins.

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        A hologram (counts); not modified.
    peaks : sequence of Peak
        Peaks with approximate carriers; labels, alphas and flags are kept.
    neighbours : sequence of (fx, fy)
        Other peaks of the spectrum (cycles/pixel) the windows must not reach.
    threads : int, optional
        FFTW threads of the frame's FFT.

    Returns
    -------
    list of Peak
        The same peaks, in the same order, with refined carriers (cycles/pixel).
    """
    array = check_frame(frame)
    check_frame_content(array)
    if not peaks:
        return []
    plan = rfft2_plan(array.shape, threads=threads or DEFAULT_THREADS)
    np.copyto(plan.input_array, array, casting="unsafe")
    plan()
    return _refined(plan.output_array, array.shape, peaks, neighbours)
