"""Fast hologram synthesis: ``|sum of fields|**2``, shot noise, camera response.

:class:`HologramSynthesizer` precomputes, once per setup, each beam's field on the
pixel grid without its height term (amplitude, illumination at the beam's entry point,
carrier ramp, constant phase; see :mod:`holoview.optics.beams` for the model). These
are separable (a Gaussian beam times a plane wave), so for a uniform level the field
sum is two thin products ``(rows, 2 n_beams) @ (2 n_beams, cols)`` with each beam's
height phasor ``exp(2 i k0 kappa h)`` as a scalar. For a height map, each group of
beams sharing a height term adds its field times ``exp(2 i k0 kappa h(r + c))``:
the map sampled at the group's walk-off centroid ``c`` (bilinear) and exponentiated
through a 65536-entry phase table (1e-4 rad steps; the map's mean enters exactly).
Then ``|E|**2``, the field stop, the noise and the camera response
(:mod:`holoview.optics.camera`).

Cost (``benchmarks/bench_synthesis.py``; 2-core EPYC, load average about 2; medians;
default water bench, 6 beams R, F, B1..B4, 5 height groups), one 1024 x 1024 frame:

- uniform level: 7.5 ms without noise, 8.5 ms with ``"pooled"`` noise, 28 ms with
  ``"gaussian"``, 59 ms with ``"poisson"``;
- height map: 50, 52, 79 and 132 ms.

A uniform level is the field sum (about 3 ms, by numpy's own einsum loops: BLAS
threads on such thin products stall when the other core is busy), ``|E|**2`` (under
1 ms) and the camera (4 ms). A height map adds, per height group, the bilinear taps
(about 25 % of the frame), two phase-table gathers (about 35 %) and the
accumulation. numpy's Poisson sampler (about 50 ms) is the most expensive single step.
At 256 x 256 a frame costs 0.5-4 ms (uniform) or 3-10 ms (map). Each height group's
field takes 8 bytes per pixel (40 MB at 1024 x 1024).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from holoview.errors import InputError
from holoview.optics.beams import DEFAULT_THRESHOLD, Beam, field_beams, mean_intensity
from holoview.optics.camera import Camera
from holoview.optics.setup import Setup

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


def bilinear_taps(dy: float, dx: float) -> list[tuple[int, int, float]]:
    """Return the taps ``(row offset, col offset, weight)`` of a bilinear sample.

    Sampling a map at ``(row + dy, col + dx)`` is the weighted sum of the map at the
    integer offsets returned; taps of zero weight are left out.
    """
    iy, ix = math.floor(dy), math.floor(dx)
    fy, fx = dy - iy, dx - ix
    taps = []
    for oy, wy in ((iy, 1 - fy), (iy + 1, fy)):
        for ox, wx in ((ix, 1 - fx), (ix + 1, fx)):
            if wy * wx > 1e-9:
                taps.append((oy, ox, wy * wx))
    return taps


def pad_edge(
    h: np.ndarray, pad: int, out: np.ndarray | None = None, offset: float = 0.0
) -> np.ndarray:
    """Return ``h - offset`` edge-padded by ``pad`` pixels on every side, float32.

    ``out`` (shape ``(rows + 2 pad, cols + 2 pad)``, float32) is filled when given.
    """
    rows, cols = h.shape
    if out is None:
        out = np.empty((rows + 2 * pad, cols + 2 * pad), dtype=np.float32)
    inner = out[pad : pad + rows, pad : pad + cols]
    np.subtract(h, offset, out=inner, casting="unsafe")
    if pad:
        out[:pad, pad : pad + cols] = inner[:1]
        out[pad + rows :, pad : pad + cols] = inner[-1:]
        out[:, :pad] = out[:, pad : pad + 1]
        out[:, pad + cols :] = out[:, pad + cols - 1 : pad + cols]
    return out


@dataclass(frozen=True)
class _HeightGroup:
    """Beams that share a height term: the same kappa and walk-off centroid.

    ``taps`` are the bilinear taps of the walk-off shift with the weights multiplied by
    the phase-table cycles per metre, ``2 k0 kappa N / (2 pi)``.
    """

    kappa: float
    shift_px: tuple[float, float]  # (rows, cols) pixels: sample h at (row + dy, col + dx)
    members: tuple[int, ...]
    taps: tuple[tuple[int, int, np.float32], ...]
    cycles: float


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
        self._groups = []
        for (kappa, dy, dx), members in groups.items():
            cycles = self._k2 * kappa * PHASE_TABLE_SIZE / (2 * math.pi)
            taps = tuple((oy, ox, np.float32(w * cycles)) for oy, ox, w in bilinear_taps(dy, dx))
            self._groups.append(_HeightGroup(kappa, (dy, dx), tuple(members), taps, cycles))
        self._reference = tuple(i for i, b in enumerate(self.beams) if b.kappa == 0)
        self._pad = 1 + max(
            (math.ceil(max(abs(g.shift_px[0]), abs(g.shift_px[1]))) for g in self._groups),
            default=0,
        )
        angles = np.arange(PHASE_TABLE_SIZE) * (2 * math.pi / PHASE_TABLE_SIZE)
        self._cos = np.cos(angles).astype(np.float32)
        self._sin = np.sin(angles).astype(np.float32)
        self._group_fields: list[tuple[np.ndarray, np.ndarray]] | None = None  # |g|, arg index
        self._buffers = (
            np.empty(setup.shape, dtype=np.float32),
            np.empty(setup.shape, dtype=np.float32),
        )
        self._work: dict[str, np.ndarray] = {}

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
        # einsum's own loops, not BLAS: OpenBLAS threads on such thin products spin and
        # stall (up to 100x) when the other core is busy, as it is in the live app
        np.einsum("ik,kj->ij", left_real, v, out=out[0])
        np.einsum("ik,kj->ij", left_imag, v, out=out[1])
        return out

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
        self._add_height_groups(heights, real, imag)
        return real, imag

    def _buffer(self, name: str, shape: tuple[int, int], dtype: type) -> np.ndarray:
        """Return a reusable work array (allocating it once: page faults cost here)."""
        array = self._work.get(name)
        if array is None:
            array = self._work[name] = np.empty(shape, dtype=dtype)
        return array

    def _add_height_groups(self, heights: np.ndarray, real: np.ndarray, imag: np.ndarray) -> None:
        """Add every height group's field times its phasor map to ``real``, ``imag``.

        The map's mean goes into the phase exactly (float64), the rest through float32
        and the phase table, so the table's precision does not depend on the level.
        """
        rows, cols = self.shape
        pad = self._pad
        level = float(heights.mean(dtype=np.float64))
        padded = pad_edge(
            heights,
            pad,
            self._buffer("padded", (rows + 2 * pad, cols + 2 * pad), np.float32),
            level,
        )
        phase = self._buffer("phase", self.shape, np.float32)
        tmp = self._buffer("tmp", self.shape, np.float32)
        index = self._buffer("index", self.shape, np.int32)
        cos = self._buffer("cos", self.shape, np.float32)
        sin = self._buffer("sin", self.shape, np.float32)
        if self._group_fields is None:
            self._group_fields = []
            for group in self._groups:
                ones = np.ones(len(group.members), dtype=complex)
                g_real, g_imag = self._separable_sum(ones, group.members)
                magnitude = np.hypot(g_real, g_imag)
                angle = np.rint(np.arctan2(g_imag, g_real) * (PHASE_TABLE_SIZE / (2 * math.pi)))
                self._group_fields.append((magnitude, angle.astype(np.int32)))
        for group, (magnitude, angle) in zip(self._groups, self._group_fields, strict=True):
            for n, (oy, ox, weight) in enumerate(group.taps):
                view = padded[pad + oy : pad + oy + rows, pad + ox : pad + ox + cols]
                if n == 0:
                    np.multiply(view, weight, out=phase)
                else:
                    np.multiply(view, weight, out=tmp)
                    phase += tmp
            phase += np.float32((level * group.cycles) % PHASE_TABLE_SIZE)
            np.rint(phase, out=phase)
            np.copyto(index, phase, casting="unsafe")
            index += angle
            self._cos.take(index, out=cos, mode="wrap")
            self._sin.take(index, out=sin, mode="wrap")
            cos *= magnitude
            sin *= magnitude
            real += cos
            imag += sin

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
