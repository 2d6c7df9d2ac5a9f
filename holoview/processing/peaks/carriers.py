"""Carriers below one FFT bin: the mean direction of the phase steps of each field.

The spectrum's maximum places a carrier within a few hundredths of a bin for a clean
fringe pattern, but an object in the beam broadens the peak: on a hologram of cells the
maximum moved up to 0.2 bins from the true carrier in the simulations of
``tests/processing/test_processing_carriers.py`` (0.94 bins on qpretrieve's HL60
hologram, by the issue's measurement). :func:`refine_frequencies` demodulates each peak
from the frame's plain spectrum against its current carrier and moves the carrier by the
mean phase step of the field between neighbouring pixels, each step weighted alike
(a two-dimensional version of Kay's frequency estimator with unit weights: dark cells
count as much as bright background), through a raised-cosine window (its smooth edge
keeps the frame's wrap-around local) and leaving out one window period at the frame's
edge; three rounds converge. Its uncertainty comes from the scatter of the same estimate over blocks
of the field, after a plane is fitted through the blocks' values (a curved reference
wave changes the local frequency across the frame: that is the carrier's definition
spread, not noise). The uncertainty ran two to three times the errors measured in
those simulations: it errs on the safe side.

Frequencies are in cycles per pixel, ``(fx, fy)``; errors in FFT bins.
"""

from __future__ import annotations

import numpy as np

from holoview.processing.fourier.boxes import border_mask, box_geometry, box_shape_for
from holoview.processing.fourier.fastmath import TWO_PI
from holoview.processing.fourier.fftplans import ifft2_plan

__all__ = ["REFINE_ITERATIONS", "refine_frequencies"]

#: Demodulate-and-move rounds of :func:`refine_frequencies`.
REFINE_ITERATIONS = 3

#: Width of the frame's edge left out, in cycles of the window radius (the edge's
#: wrap-around is coherent from pixel to pixel and biases the mean step).
EDGE_CYCLES = 1.0

#: Blocks per side over which the carrier's uncertainty is measured.
BLOCKS = 6

#: The window the carriers are measured through, and its taper.
WINDOW = "raised-cosine"
TAPER = 0.25


def _unit(products: np.ndarray) -> np.ndarray:
    """Neighbour products scaled to unit modulus (zeros stay zero)."""
    magnitude = np.abs(products)
    return np.divide(products, magnitude, out=np.zeros_like(products), where=magnitude > 0)


def _block_spread(steps: np.ndarray, keep: np.ndarray, mean_step: complex) -> float:
    """Standard error (rad) of the mean step, from its scatter over blocks about a plane."""
    rows, cols = steps.shape
    ys = np.linspace(0, rows, BLOCKS + 1).astype(int)
    xs = np.linspace(0, cols, BLOCKS + 1).astype(int)
    values, where = [], []
    turn = np.conj(mean_step) / abs(mean_step) if mean_step else 1.0
    for i in range(BLOCKS):
        for j in range(BLOCKS):
            block = (slice(ys[i], ys[i + 1]), slice(xs[j], xs[j + 1]))
            if np.count_nonzero(keep[block]) > 4:
                values.append(np.angle(np.sum(steps[block][keep[block]]) * turn))
                where.append((1.0, i, j))
    if len(values) <= 3:
        return float("nan")
    design = np.array(where)
    coef, *_ = np.linalg.lstsq(design, np.array(values), rcond=None)
    residual = np.array(values) - design @ coef
    scatter = np.sqrt(np.sum(residual**2) / (len(values) - 3))
    return float(scatter / np.sqrt(len(values)))


def refine_frequencies(
    half: np.ndarray,
    shape: tuple[int, int],
    carriers: np.ndarray,
    radii: np.ndarray,
    *,
    iterations: int = REFINE_ITERATIONS,
) -> tuple[np.ndarray, np.ndarray]:
    """Return the carriers moved to their fields' mean phase step, and their uncertainties.

    Parameters
    ----------
    half : ndarray of complex, shape (rows, cols // 2 + 1)
        The frame's half spectrum (``rfft2`` layout, unnormalised, no apodisation);
        not modified.
    shape : tuple of int
        Frame shape ``(rows, cols)``.
    carriers : ndarray, shape (n, 2)
        Approximate carriers ``(fx, fy)``, cycles/pixel.
    radii : ndarray, shape (n,)
        Each carrier's window radius, cycles/pixel (one that reaches no other peak).
    iterations : int
        Rounds (>= 1); each recentres the window on the last estimate.

    Returns
    -------
    carriers : ndarray of float64, shape (n, 2)
        Refined carriers, cycles/pixel. A carrier whose estimate would leave half its
        window radius, or is not finite, keeps its given value.
    errors : ndarray of float64, shape (n,)
        Each carrier's uncertainty in FFT bins (the two axes' standard errors added in
        quadrature); NaN where it could not be measured.
    """
    rows, cols = shape
    flat = np.ascontiguousarray(half).reshape(-1)
    start = np.asarray(carriers, dtype=np.float64).reshape(-1, 2)
    out = start.copy()
    errors = np.full(len(start), np.nan)
    for k, radius in enumerate(np.asarray(radii, dtype=np.float64)):
        box_shape = box_shape_for(shape, float(radius))
        by, bx = box_shape
        plan = ifft2_plan(box_shape, threads=1)
        keep = border_mask(box_shape, shape, float(radius), EDGE_CYCLES)
        keep_x = keep[:, 1:] & keep[:, :-1]
        keep_y = keep[1:, :] & keep[:-1, :]
        current = start[k].copy()
        for _ in range(max(1, iterations)):
            geo = box_geometry(
                shape,
                box_shape,
                carrier=(float(current[0]), float(current[1])),
                kind=WINDOW,
                radius=float(radius),
                taper=TAPER,
            )
            box = plan.input_array.reshape(-1)
            np.take(flat, geo.index, out=box)
            pairs = box.view(np.float32)
            np.multiply(pairs, geo.weights, out=pairs)
            plan.execute()
            residual = plan.output_array * geo.ramp_conj
            step_x = _unit(residual[:, 1:] * np.conj(residual[:, :-1]))
            step_y = _unit(residual[1:, :] * np.conj(residual[:-1, :]))
            mean_x = complex(np.sum(step_x[keep_x]))
            mean_y = complex(np.sum(step_y[keep_y]))
            moved = current + np.array(
                [np.angle(mean_x) / TWO_PI * bx / cols, np.angle(mean_y) / TWO_PI * by / rows]
            )
            if not (np.isfinite(moved).all() and np.hypot(*(moved - start[k])) < radius / 2):
                break
            current = moved
            spread_x = _block_spread(step_x, keep_x, mean_x) / TWO_PI * bx
            spread_y = _block_spread(step_y, keep_y, mean_y) / TWO_PI * by
            errors[k] = float(np.hypot(spread_x, spread_y))
        out[k] = current
    return out, errors
