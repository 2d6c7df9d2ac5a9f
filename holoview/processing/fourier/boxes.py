"""Where each peak's box comes from in the half spectrum, its window, and its constants.

A peak's box is a small ``(by, bx)`` patch of the spectrum centred on the FFT bin
nearest the carrier, laid out with that bin at index ``(0, 0)`` (FFT order), so that
its inverse FFT is the field with the carrier moved to the origin. Bins with
``fx < 0`` are not in the real FFT's half spectrum: they are read at ``-f`` and
conjugated. Geometries are cached by frame shape, box shape, carrier and window:
rebuilding a demodulator for relabelled peaks reuses them.

The FFT treats the frame as periodic, so near an edge the field mixes with the opposite
edge's over about the window's impulse response: :func:`border_mask` gives the box
pixels far enough from the edge to be trusted. Measured on the optics simulator
(``benchmarks/bench_borders.py``, 1024^2, Tukey window of radius 0.034 cycles/pixel),
the phase error is 15 times the interior's in the outer 2 pixels, 6 times at 2-5 pixels
and 1.4 to 1.5 times at 5-20 pixels. Tapering the frame's edge (apodisation over 16
pixels) made the 5-10 pixel band 1.7 times worse and changed nothing beyond; zero
padding to twice the size (qpretrieve's default) brings the outer pixels to twice the
interior's, at four times the FFT. So the border is marked untrusted,
:data:`UNTRUSTED_BORDER` over the radius wide (12 pixels at 0.034).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from holoview.processing.fourier.fastmath import TWO_PI
from holoview.processing.fourier.fftplans import fft_friendly
from holoview.processing.fourier.resample import box_positions
from holoview.processing.fourier.windows import radial_window, wrap_frequency

#: Width of the untrusted border, in cycles of the window radius: a peak demodulated
#: with radius ``r`` (cycles/pixel) is untrusted within ``UNTRUSTED_BORDER / r`` pixels
#: of the frame's edge (12 pixels at r = 0.034). Chosen by measurement
#: (``benchmarks/bench_borders.py``): beyond it the error is within 2 times the
#: interior's (1.4 times measured).
UNTRUSTED_BORDER = 0.4


#: A rectangle copied from the half spectrum into a box: (box rows, box columns, spectrum
#: rows, spectrum columns), the spectrum's slices stepping by +1 or -1.
Block = tuple[slice, slice, slice, slice]


@dataclass(frozen=True)
class BoxGeometry:
    """Where a peak's box comes from in the half spectrum, and its window (read-only arrays)."""

    index: np.ndarray  # flat indices into the half spectrum, box layout
    blocks: tuple[Block, ...]  # the same bins as rectangles (cut_box)
    columns: np.ndarray  # the half spectrum's columns where the box's window is not zero
    weights: np.ndarray  # float32 (re, im) pairs per bin: the window, -window on conjugated im
    ramp: np.ndarray  # complex64 unit modulus: the sub-bin plane wave on the box grid
    ramp_conj: np.ndarray  # its conjugate
    area_fraction: float


def _runs(values: np.ndarray, step: int) -> list[tuple[int, int]]:
    """Split ``values`` into maximal runs ``[i, j)`` where each next value is ``step`` more."""
    breaks = np.flatnonzero(np.diff(values) != step) + 1
    edges = [0, *breaks.tolist(), len(values)]
    return list(itertools.pairwise(edges))


def _source(start: int, length: int, step: int) -> slice:
    """The slice of ``length`` indices from ``start`` stepping by ``step`` (+1 or -1)."""
    stop = start + step * length
    return slice(start, None if stop < 0 else stop, step)


def _blocks(
    rows_direct: np.ndarray, rows_mirror: np.ndarray, src_cols: np.ndarray, direct: np.ndarray
) -> tuple[Block, ...]:
    """Rectangles of the half spectrum that make up a box (see :class:`BoxGeometry`)."""
    blocks: list[Block] = []
    flips = np.flatnonzero(np.diff(direct.astype(np.int8))) + 1
    edges = [0, *flips.tolist(), len(direct)]
    for a, b in itertools.pairwise(edges):
        step = 1 if direct[a] else -1
        src_rows = rows_direct if direct[a] else rows_mirror
        for c0, c1 in _runs(src_cols[a:b], step):
            cols = _source(int(src_cols[a + c0]), c1 - c0, step)
            for r0, r1 in _runs(src_rows, step):
                rows = _source(int(src_rows[r0]), r1 - r0, step)
                blocks.append((slice(r0, r1), slice(a + c0, a + c1), rows, cols))
    return tuple(blocks)


def cut_box(half: np.ndarray, geometry: BoxGeometry, out: np.ndarray) -> np.ndarray:
    """Cut a peak's box out of the half spectrum and apply its window (and 1 / size).

    Parameters
    ----------
    half : ndarray of complex64, shape ``(rows, cols // 2 + 1)``
        The frame's half spectrum (exact at least in ``geometry.columns``); not modified.
    geometry : BoxGeometry
        The peak's box (:func:`box_geometry`).
    out : ndarray of complex64, C-contiguous, the box's shape
        Where the windowed box is written (an inverse FFT's input).

    Returns
    -------
    ndarray
        ``out``: bins read at ``-f`` conjugated, the carrier's bin at ``(0, 0)``.
    """
    for box_rows, box_cols, rows, cols in geometry.blocks:
        np.copyto(out[box_rows, box_cols], half[rows, cols])
    # window and conjugation in one pass over the box as (re, im) pairs (faster than
    # windowing each block while copying it: measured, twice)
    pairs = out.reshape(-1).view(np.float32)
    np.multiply(pairs, geometry.weights, out=pairs)
    return out


def _readonly(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class BoxLayout:
    """Where a peak's box bins come from, before any window (read-only arrays).

    Attributes
    ----------
    index : ndarray of intp, shape (by * bx,)
        Flat indices into the half spectrum, box layout.
    conjugate : ndarray of bool, shape (by * bx,)
        The bins read at ``-f`` (conjugated).
    rho : ndarray, shape (by, bx)
        Each bin's distance from the carrier, cycles/pixel.
    """

    index: np.ndarray
    conjugate: np.ndarray
    rho: np.ndarray


def _layout(
    frame_shape: tuple[int, int], box_shape: tuple[int, int], carrier: tuple[float, float]
) -> tuple[BoxLayout, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The box's layout, and its rows, mirrored rows, source columns and direct columns."""
    rows, cols = frame_shape
    by, bx = box_shape
    fx, fy = carrier
    k0y, k0x = round(fy * rows), round(fx * cols)
    dy = np.fft.fftfreq(by, 1.0 / by).round().astype(np.int64)
    dx = np.fft.fftfreq(bx, 1.0 / bx).round().astype(np.int64)
    ky = (k0y + dy) % rows
    kx = (k0x + dx) % cols
    half_cols = cols // 2 + 1
    direct_x = kx <= cols // 2
    src_rows = np.where(direct_x[None, :], ky[:, None], (-ky[:, None]) % rows)
    src_cols = np.where(direct_x, kx, (cols - kx) % cols)
    index = (src_rows * half_cols + src_cols[None, :]).astype(np.intp).ravel()
    conjugate = np.broadcast_to(~direct_x[None, :], (by, bx)).ravel()
    freq_y = wrap_frequency((k0y + dy) / rows - fy)
    freq_x = wrap_frequency((k0x + dx) / cols - fx)
    rho = np.hypot(freq_y[:, None], freq_x[None, :])
    return BoxLayout(index, conjugate, rho), ky, (-ky) % rows, src_cols, direct_x


def box_layout(
    frame_shape: tuple[int, int], box_shape: tuple[int, int], carrier: tuple[float, float]
) -> BoxLayout:
    """Return where a peak's box bins come from (not cached: for windows tried once).

    Parameters
    ----------
    frame_shape, box_shape : tuple of int
        ``(rows, cols)`` of the frame and of the box, pixels.
    carrier : tuple of float
        ``(fx, fy)``, cycles/pixel.
    """
    return _layout(frame_shape, box_shape, carrier)[0]


def box_weights(
    layout: BoxLayout,
    frame_shape: tuple[int, int],
    *,
    kind: str,
    radius: float,
    taper: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The window on a box's bins, and the box's float32 (re, im) weights of :func:`cut_box`.

    Returns
    -------
    w : ndarray, shape (by, bx)
        The window (:func:`~holoview.processing.fourier.windows.radial_window`).
    weights : ndarray of float32, shape (2 by bx,)
        ``(w, w)`` for a bin read directly, ``(w, -w)`` for one read at ``-f`` and
        conjugated, times 1 / (rows cols) (the box's inverse FFT runs unnormalised, so
        that the field comes out in counts).
    """
    rows, cols = frame_shape
    w = radial_window(kind, layout.rho, radius, taper=taper)
    scaled = (w * (1.0 / (rows * cols))).astype(np.float32).ravel()
    weights = np.empty(2 * scaled.size, dtype=np.float32)
    weights[0::2] = scaled
    weights[1::2] = np.where(layout.conjugate, -scaled, scaled)
    return w, weights


@lru_cache(maxsize=256)
def box_geometry(
    frame_shape: tuple[int, int],
    box_shape: tuple[int, int],
    *,
    carrier: tuple[float, float],
    kind: str,
    radius: float,
    taper: float,
) -> BoxGeometry:
    """Return the cached geometry of a peak's box.

    Parameters
    ----------
    frame_shape, box_shape : tuple of int
        ``(rows, cols)`` of the frame and of the box, pixels.
    carrier : tuple of float
        ``(fx, fy)``, cycles/pixel.
    kind, radius, taper
        The window (:func:`~holoview.processing.fourier.windows.radial_window`), radius in
        cycles/pixel.
    """
    rows, cols = frame_shape
    fx, fy = carrier
    k0y, k0x = round(fy * rows), round(fx * cols)
    layout, ky, ky_mirror, src_cols, direct_x = _layout(frame_shape, box_shape, carrier)
    w, weights = box_weights(layout, frame_shape, kind=kind, radius=radius, taper=taper)
    area = float((w * w).sum() / (rows * cols))
    y, x = box_positions(box_shape, frame_shape)
    sub_y = fy - k0y / rows
    sub_x = fx - k0x / cols
    ramp = np.exp(1j * TWO_PI * (sub_y * y[:, None] + sub_x * x[None, :])).astype(np.complex64)
    return BoxGeometry(
        index=_readonly(layout.index),
        blocks=_blocks(ky, ky_mirror, src_cols, direct_x),
        # the other columns are multiplied by zero: their row pass alone is enough
        columns=_readonly(np.unique(src_cols[(w > 0).any(axis=0)])),
        weights=_readonly(weights),
        ramp=_readonly(ramp),
        ramp_conj=_readonly(np.conj(ramp)),
        area_fraction=area,
    )


def box_shape_for(frame_shape: tuple[int, int], radius: float) -> tuple[int, int]:
    """Return the FFT-friendly box shape holding a window of ``radius`` (cycles/pixel).

    Each side is the smallest size with prime factors 2, 3, 5 covering the window's
    diameter in bins plus two, or the frame's side when that is not smaller.
    """
    sides = []
    for n in frame_shape:
        need = int(np.ceil(2 * radius * n)) + 2
        size = fft_friendly(need)
        sides.append(n if size >= n else size)
    return sides[0], sides[1]


def border_mask(
    box_shape: tuple[int, int],
    frame_shape: tuple[int, int],
    radius: float,
    cycles: float = UNTRUSTED_BORDER,
) -> np.ndarray:
    """Return the box pixels trusted near the frame's edge (read-only bool, ``box_shape``).

    A box pixel is trusted when its frame position lies at least ``cycles / radius``
    pixels (``radius`` in cycles/pixel) from the periodic seam between the frame's
    last and first row (and column).
    """
    width = cycles / radius
    y, x = box_positions(box_shape, frame_shape)
    rows, cols = frame_shape
    keep_y = np.minimum(y + 0.5, rows - 0.5 - y) >= width
    keep_x = np.minimum(x + 0.5, cols - 0.5 - x) >= width
    mask = keep_y[:, None] & keep_x[None, :]
    mask.setflags(write=False)
    return mask
