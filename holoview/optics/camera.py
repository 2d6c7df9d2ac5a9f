"""The camera: photon shot noise, response (gamma, saturation) and quantisation.

Expected photon counts ``lam`` per pixel become raw integer values:

1. photons: ``n ~ Poisson(lam)`` (``"poisson"``, exact); ``lam + sqrt(lam) z`` with fresh
   standard normals ``z`` rounded to whole photons (``"gaussian"``, the large-count
   limit, 4-5x faster); the same with ``z`` read at a random offset from a pool of
   normals drawn once (``"pooled"``, about 40x faster, for live display: two frames'
   noise fields are shifted copies of one pool, so do not use it to measure noise);
   or ``lam`` rounded (``"none"``);
2. response: ``value = round(max_value * min(n / saturation, 1) ** gamma)`` through a
   lookup table indexed by the photon count (one gather per pixel);
3. the result in ``uint8`` for ``bit_depth <= 8``, else ``uint16``, raw (unscaled).
"""

from __future__ import annotations

import numpy as np

from holoview.errors import InputError
from holoview.optics.setup import Setup

#: The shot-noise models :class:`Camera` offers.
NOISE_MODELS = ("poisson", "gaussian", "pooled", "none")

#: Largest saturation (photons) served by a lookup table; above it, arithmetic.
_MAX_TABLE = 1 << 21


class Camera:
    """Turn expected photon counts into raw camera values.

    Parameters
    ----------
    setup : Setup
        Supplies ``shape``, ``bit_depth``, ``gamma`` and ``saturation`` (photons).
    noise : str
        One of :data:`NOISE_MODELS`.
    seed : int, optional
        Seed of the pool of normals for ``noise="pooled"``.
    """

    def __init__(self, setup: Setup, noise: str = "poisson", seed: int | None = None) -> None:
        if noise not in NOISE_MODELS:
            raise InputError(f"noise must be one of {NOISE_MODELS}, got {noise!r}")
        self.noise = noise
        self.shape = setup.shape
        self.dtype = np.dtype(np.uint8 if setup.bit_depth <= 8 else np.uint16)
        self.max_value = setup.max_value
        self.gamma = setup.gamma
        self.saturation = setup.saturation
        self._top = int(np.ceil(setup.saturation))
        self._table: np.ndarray | None = None
        if self._top <= _MAX_TABLE:
            counts = np.arange(self._top + 1, dtype=np.float64)
            self._table = self._respond(counts).astype(self.dtype)
        self._counts = np.empty(self.shape, dtype=np.float32)
        self._index = np.empty(self.shape, dtype=np.int32)
        self._pool: np.ndarray | None = None
        if noise == "pooled":
            rows, cols = self.shape
            pool_rng = np.random.default_rng(seed)
            self._pool = pool_rng.standard_normal((2 * rows, 2 * cols), dtype=np.float32)

    def _respond(self, photons: np.ndarray) -> np.ndarray:
        """Return the response to photon counts, as rounded float values."""
        fraction = np.clip(photons / self.saturation, 0.0, 1.0)
        if self.gamma != 1.0:
            fraction = fraction**self.gamma
        return np.floor(fraction * self.max_value + 0.5)

    def photons(self, lam: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        """Return detected photon counts for expectations ``lam`` (photons), float32.

        ``rng`` is required except for ``noise="none"``. The result is an internal
        buffer, overwritten by the next call.
        """
        counts = self._counts
        if self.noise == "none":
            np.add(lam, np.float32(0.5), out=counts)
            return np.floor(counts, out=counts)
        if rng is None:
            raise InputError(f"noise={self.noise!r} needs a numpy Generator (rng)")
        if self.noise == "poisson":
            np.copyto(counts, rng.poisson(lam), casting="unsafe")
            return counts
        if self.noise == "gaussian":
            z = rng.standard_normal(lam.shape, dtype=np.float32)
        else:
            assert self._pool is not None
            rows, cols = lam.shape
            oy, ox = rng.integers(0, rows), rng.integers(0, cols)
            z = self._pool[oy : oy + rows, ox : ox + cols]
        np.sqrt(lam, out=counts)
        counts *= z
        counts += lam
        counts += np.float32(0.5)
        return np.floor(counts, out=counts)

    def expose(
        self, lam: np.ndarray, rng: np.random.Generator | None, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Return raw camera values for expected photon counts ``lam`` (photons).

        Parameters
        ----------
        lam : ndarray of float32
            Expected photons per pixel, ``setup.shape``.
        rng : numpy.random.Generator or None
            Noise source (not needed for ``noise="none"``).
        out : ndarray, optional
            Destination (``setup.shape``, :attr:`dtype`); by default a new array.

        Returns
        -------
        ndarray of uint8 or uint16
            Raw values in ``0 .. 2**bit_depth - 1``.
        """
        if lam.shape != self.shape:
            raise InputError(f"expected photons of shape {self.shape}, got {lam.shape}")
        if out is not None and (out.shape != self.shape or out.dtype != self.dtype):
            raise InputError(
                f"out must be {self.dtype} of shape {self.shape}, got {out.dtype} {out.shape}"
            )
        counts = self.photons(lam, rng)
        if self._table is None:
            values = self._respond(counts).astype(self.dtype)
            if out is None:
                return values
            out[...] = values
            return out
        np.minimum(counts, np.float32(self._top), out=counts)
        np.copyto(self._index, counts, casting="unsafe")
        # mode="clip" clamps negative counts to the table's first entry, and checks nothing
        if out is None:
            return self._table.take(self._index, mode="clip")
        return self._table.take(self._index, out=out, mode="clip")
