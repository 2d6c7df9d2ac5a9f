"""Fast hologram synthesis: ``|sum of fields|**2``, shot noise, camera response.

:class:`HologramSynthesizer` precomputes, once per setup, each beam's complex field on
the pixel grid without its height term (amplitude, illumination profile at the beam's
entry point, field stop, carrier ramp, constant phase; see :mod:`holoview.optics.beams`
for the model). A frame then costs, per beam, one complex multiply-add by the beam's
height phasor ``exp(2 i k0 kappa h(r + c))`` (a scalar for a uniform level; for a
height map, the map shifted by the beam's walk-off centroid with bilinear
interpolation and exponentiated through a 65536-entry phase table, 1e-4 rad steps),
plus ``|E|**2``, the noise and the camera response (:mod:`holoview.optics.camera`).

Cost (1024 x 1024, 2-core EPYC, ``benchmarks/bench_synthesis.py``): with the default
water setup (R, F, B1..B4: 6 beams) about 6 ms for a uniform level and about 25 ms for
a height map, plus the noise: ``"pooled"`` about 2 ms, ``"gaussian"`` about 12 ms,
``"poisson"`` about 55 ms (numpy's Poisson sampler dominates everything else).
The fields take ``8 * rows * cols`` bytes per beam (48 MB at 1024 x 1024).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from holoview.errors import InputError
from holoview.optics.beams import DEFAULT_THRESHOLD, Beam, field_beams, mean_intensity
from holoview.optics.camera import Camera
from holoview.optics.setup import Setup

#: Rows per matrix product: small products keep OpenBLAS on one thread, whose
#: multi-threaded small products stall (up to 15x) when the other core is busy.
_BLOCK_ROWS = 64

#: Entries of the phase-to-phasor table (phase step 2 pi / 65536 rad).
PHASE_TABLE_SIZE = 1 << 16


def pixel_coordinates(setup: Setup) -> tuple[np.ndarray, np.ndarray]:
    """Return the object-plane coordinates of pixel centres, m.

    Returns
    -------
    x : ndarray, shape (1, cols)
        Along columns, 0 at the frame centre.
    y : ndarray, shape (rows, 1)
        Along rows, 0 at the frame centre.
    """
    rows, cols = setup.shape
    x = (np.arange(cols) - (cols - 1) / 2) * setup.pixel_pitch
    y = (np.arange(rows) - (rows - 1) / 2) * setup.pixel_pitch
    return x[np.newaxis, :], y[:, np.newaxis]


def illumination(setup: Setup, x: np.ndarray, y: np.ndarray) -> np.ndarray | None:
    """Return the field amplitude of the illumination at ``x``, ``y`` (m), or None if uniform.

    A Gaussian beam of 1/e^2 intensity radius ``beam_waist`` has the field amplitude
    ``exp(-r**2 / w**2)``.
    """
    if setup.beam_waist is None:
        return None
    return np.exp(-(x**2 + y**2) / setup.beam_waist**2)


def field_stop(setup: Setup, x: np.ndarray, y: np.ndarray) -> np.ndarray | None:
    """Return the aperture's transmission (0 or 1) at ``x``, ``y`` (m), or None if none."""
    if setup.aperture_radius is None:
        return None
    return ((x**2 + y**2) <= setup.aperture_radius**2).astype(float)


@dataclass(frozen=True)
class _HeightGroup:
    """Beams that share a height term: the same kappa and walk-off centroid."""

    kappa: float
    shift_px: tuple[float, float]  # (rows, cols) pixels: sample h at (row + dy, col + dx)
    members: tuple[int, ...]


def shift_map(
    h: np.ndarray, dy: float, dx: float, padded: np.ndarray | None = None, pad: int = 0
) -> np.ndarray:
    """Return ``h`` sampled at ``(row + dy, col + dx)``, bilinear, edges clamped.

    Parameters
    ----------
    h : ndarray, shape (rows, cols)
        The map.
    dy, dx : float
        Shift in pixels (rows, columns).
    padded, pad : ndarray and int, optional
        ``h`` already edge-padded by ``pad`` pixels on every side (``pad`` at least
        ``ceil(max(|dy|, |dx|)) + 1``), to share one padding between many shifts.

    Returns
    -------
    ndarray, shape (rows, cols), float32
    """
    rows, cols = h.shape
    if padded is None:
        pad = math.ceil(max(abs(dy), abs(dx))) + 1
        padded = np.pad(h.astype(np.float32, copy=False), pad, mode="edge")
    iy, ix = math.floor(dy), math.floor(dx)
    fy, fx = dy - iy, dx - ix
    out = np.zeros((rows, cols), dtype=np.float32)
    for oy, wy in ((iy, 1 - fy), (iy + 1, fy)):
        for ox, wx in ((ix, 1 - fx), (ix + 1, fx)):
            weight = wy * wx
            if weight < 1e-9:
                continue
            view = padded[pad + oy : pad + oy + rows, pad + ox : pad + ox + cols]
            if weight > 1 - 1e-9:
                out += view
            else:
                out += np.float32(weight) * view
    return out


class HologramSynthesizer:
    """Render camera frames of a setup, fast, frame after frame.

    Every beam's field without its height term is separable,
    ``u_b(y) v_b(x)`` (the illumination is a Gaussian, the carrier a plane wave), so a
    uniform-level frame is two small real matrix products, ``(rows, 2 n_beams) @
    (2 n_beams, cols)``, for the real and imaginary parts of the field. A height map
    needs each height group's field in full (cached at the first map, 8 bytes per pixel
    per group) times its phasor map. The field stop (not separable) multiplies the
    intensity.

    Parameters
    ----------
    setup : Setup
        The bench and camera.
    threshold : float
        Beams with a field amplitude under this are left out (the supplement's 5e-4;
        use 1e-12 for every pass, for exact etalon sums).
    noise : str
        Shot-noise model, one of :data:`holoview.optics.camera.NOISE_MODELS`.

    Notes
    -----
    Not thread-safe: one synthesiser per thread. Inputs are never modified; returned
    arrays are new unless a method says otherwise.
    """

    def __init__(
        self, setup: Setup, *, threshold: float = DEFAULT_THRESHOLD, noise: str = "poisson"
    ) -> None:
        if not (math.isfinite(threshold) and threshold > 0):
            raise InputError(f"threshold must be positive, got {threshold!r}")
        self.setup = setup
        self.beams: list[Beam] = field_beams(setup, threshold)
        self.camera = Camera(setup, noise)
        self._scale = np.float32(setup.photons_per_pixel / mean_intensity(self.beams))
        self._k2 = 4 * math.pi / setup.wavelength  # 2 k0, rad/m
        x, y = pixel_coordinates(setup)
        x, y = x[0], y[:, 0]
        columns, rows_ = [], []
        for beam in self.beams:
            u = beam.amplitude * np.exp(1j * (self._k2 * beam.gradient[1] * y + beam.offset))
            v = np.exp(1j * self._k2 * beam.gradient[0] * x)
            if setup.beam_waist is not None:
                u = u * np.exp(-((y + beam.entry[1]) ** 2) / setup.beam_waist**2)
                v = v * np.exp(-((x + beam.entry[0]) ** 2) / setup.beam_waist**2)
            columns.append(u)
            rows_.append(v)
        self._u = np.stack(columns, axis=1)  # (rows, n_beams), complex128
        self._v = np.stack(rows_, axis=0)  # (n_beams, cols), complex128
        self._v_split = np.ascontiguousarray(
            np.concatenate([self._v.real, self._v.imag]), dtype=np.float32
        )
        stop = field_stop(setup, x[np.newaxis, :], y[:, np.newaxis])
        self._stop = None if stop is None else stop.astype(np.float32)
        groups: dict[tuple[float, float, float], list[int]] = {}
        for index, beam in enumerate(self.beams):
            if beam.kappa == 0:
                continue
            shift = (beam.centroid[1] / setup.pixel_pitch, beam.centroid[0] / setup.pixel_pitch)
            groups.setdefault((beam.kappa, *shift), []).append(index)
        self._groups = [
            _HeightGroup(k, (dy, dx), tuple(members)) for (k, dy, dx), members in groups.items()
        ]
        self._reference = tuple(i for i, b in enumerate(self.beams) if b.kappa == 0)
        self._pad = 1 + max(
            (math.ceil(max(abs(g.shift_px[0]), abs(g.shift_px[1]))) for g in self._groups),
            default=0,
        )
        angles = np.arange(PHASE_TABLE_SIZE) * (2 * math.pi / PHASE_TABLE_SIZE)
        self._cos = np.cos(angles).astype(np.float32)
        self._sin = np.sin(angles).astype(np.float32)
        self._group_fields: list[tuple[np.ndarray, np.ndarray]] | None = None
        self._buffers = (
            np.empty(setup.shape, dtype=np.float32),
            np.empty(setup.shape, dtype=np.float32),
        )

    @property
    def shape(self) -> tuple[int, int]:
        """Frame shape ``(rows, cols)``, pixels."""
        return self.setup.shape

    @property
    def dtype(self) -> np.dtype:
        """The raw frames' dtype (uint8 or uint16)."""
        return self.camera.dtype

    def _separable_sum(
        self,
        coefficients: np.ndarray,
        members: tuple[int, ...] | None = None,
        out: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return (real, imag) of ``sum_b c_b u_b v_b`` over ``members`` (default all)."""
        u, v = self._u, self._v_split
        if members is not None:
            index = np.asarray(members)
            u = u[:, index]
            v = np.concatenate([self._v.real[index], self._v.imag[index]]).astype(np.float32)
        uc = u * coefficients
        left_real = np.concatenate([uc.real, -uc.imag], axis=1).astype(np.float32)
        left_imag = np.concatenate([uc.imag, uc.real], axis=1).astype(np.float32)
        if out is None:
            rows = self.shape[0]
            out = (
                np.empty((rows, v.shape[1]), dtype=np.float32),
                np.empty((rows, v.shape[1]), dtype=np.float32),
            )
        for start in range(0, left_real.shape[0], _BLOCK_ROWS):
            stop = start + _BLOCK_ROWS
            np.matmul(left_real[start:stop], v, out=out[0][start:stop])
            np.matmul(left_imag[start:stop], v, out=out[1][start:stop])
        return out

    def _phasor_index(self, values: np.ndarray, kappa: float) -> np.ndarray:
        """Return phase-table indices of ``2 k0 kappa values`` (values in m)."""
        cycles = np.float32(self._k2 * kappa * PHASE_TABLE_SIZE / (2 * math.pi))
        index = np.rint(values * cycles).astype(np.int32)
        np.bitwise_and(index, PHASE_TABLE_SIZE - 1, out=index)
        return index

    def _check_height(self, h: float | np.ndarray) -> float | np.ndarray:
        if np.ndim(h) == 0:
            level = float(h)
            if not math.isfinite(level):
                raise InputError(f"height must be finite, got {h!r} m")
            return level
        heights = np.asarray(h)
        if heights.shape != self.shape:
            raise InputError(f"height map must have shape {self.shape}, got {heights.shape}")
        if heights.dtype.kind not in "iuf":
            raise InputError(f"height map must be real numbers (m), got dtype {heights.dtype}")
        if not math.isfinite(float(heights.sum(dtype=np.float64))):
            raise InputError("height map contains NaN or infinite values")
        return heights

    def field_parts(
        self, h: float | np.ndarray = 0.0, reference_phase: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return the real and imaginary parts of the field sum at the camera.

        Parameters
        ----------
        h : float or ndarray
            Surface height over the rest level, m: one value (uniform level) or a map
            of ``setup.shape``.
        reference_phase : float
            Extra phase of the reference arm, rad (air-path jitter; moves RF and RB_j,
            not FB_j).

        Returns
        -------
        real, imag : ndarray of float32, ``setup.shape``
            The field relative to the incident one, before the field stop: internal
            buffers, overwritten by the next call (copy them to keep them).
        """
        heights = self._check_height(h)
        if not math.isfinite(reference_phase):
            raise InputError(f"reference_phase must be finite, got {reference_phase!r} rad")
        jitter = complex(np.exp(1j * reference_phase))
        coefficients = np.ones(len(self.beams), dtype=complex)
        for index in self._reference:
            coefficients[index] = jitter
        if isinstance(heights, float):
            for group in self._groups:
                phasor = complex(np.exp(1j * self._k2 * group.kappa * heights))
                for index in group.members:
                    coefficients[index] = phasor
            return self._separable_sum(coefficients, out=self._buffers)
        real, imag = self._separable_sum(
            coefficients[list(self._reference)], self._reference, out=self._buffers
        )
        if self._group_fields is None:
            ones = [np.ones(len(g.members), dtype=complex) for g in self._groups]
            self._group_fields = [
                self._separable_sum(c, g.members) for c, g in zip(ones, self._groups, strict=True)
            ]
        padded = np.pad(heights.astype(np.float32, copy=False), self._pad, mode="edge")
        for group, (g_real, g_imag) in zip(self._groups, self._group_fields, strict=True):
            dy, dx = group.shift_px
            index = self._phasor_index(shift_map(heights, dy, dx, padded, self._pad), group.kappa)
            cos, sin = np.take(self._cos, index), np.take(self._sin, index)
            real += g_real * cos
            real -= g_imag * sin
            cos *= g_imag
            sin *= g_real
            imag += cos
            imag += sin
        return real, imag

    def _intensity(self, h: float | np.ndarray, reference_phase: float) -> np.ndarray:
        """Return the expected photons in an internal buffer (see :meth:`intensity`)."""
        real, imag = self.field_parts(h, reference_phase)
        real *= real
        imag *= imag
        real += imag
        real *= self._scale
        if self._stop is not None:
            real *= self._stop
        return real

    def intensity(self, h: float | np.ndarray = 0.0, reference_phase: float = 0.0) -> np.ndarray:
        """Return the expected photon counts per pixel (no noise, no camera), float32.

        See :meth:`field_parts` for the parameters; the mean is ``photons_per_pixel``
        where the illumination is 1, for the incoherent sum of the beams. A new array.
        """
        return self._intensity(h, reference_phase).copy()

    def render(
        self,
        h: float | np.ndarray = 0.0,
        *,
        reference_phase: float = 0.0,
        rng: np.random.Generator | None = None,
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Return one raw camera frame.

        Parameters
        ----------
        h : float or ndarray
            Surface height over the rest level, m (a value or a ``setup.shape`` map).
        reference_phase : float
            Reference-arm phase jitter, rad.
        rng : numpy.random.Generator, optional
            The noise source (required unless the noise model is ``"none"``).
        out : ndarray, optional
            Where to write the frame (``setup.shape``, the camera's dtype), for example
            a ring-buffer slot; by default a new array.

        Returns
        -------
        ndarray of uint8 (bit_depth <= 8) or uint16, ``setup.shape``
            Raw values, ``0 .. 2**bit_depth - 1``, not scaled (``out`` if given).
        """
        return self.camera.expose(self._intensity(h, reference_phase), rng, out=out)
