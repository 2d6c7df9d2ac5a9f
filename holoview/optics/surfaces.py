"""Fluid surfaces with a known truth: callables ``h(t, x, y)`` in metres.

``t`` is in seconds and ``x``, ``y`` in metres on the object plane (the frame centre at
the origin, ``x`` along columns, ``y`` along rows); ``h`` is the surface height over its
rest level, m, broadcast over ``x`` and ``y``. Every surface here also has
``mean_level(t)`` and ``is_uniform``: a uniform surface lets the synthesiser take its
fast path with a single height.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from holoview.errors import InputError

#: Standard gravity, m/s^2.
GRAVITY = 9.81
#: Surface tension of clean water at 20 degC, N/m.
WATER_SURFACE_TENSION = 0.0728
#: Density of water at 20 degC, kg/m^3.
WATER_DENSITY = 998.2

#: Density (kg/m^3) and surface tension (N/m) of clean liquids at 20 degC, by the names
#: of :data:`holoview.optics.setup.FLUIDS` (CRC Handbook of Chemistry and Physics).
FLUID_MECHANICS: dict[str, tuple[float, float]] = {
    "water": (WATER_DENSITY, WATER_SURFACE_TENSION),
    "ethanol": (789.3, 0.0223),
    "isopropanol": (786.0, 0.0230),
    "glycerol": (1261.0, 0.0634),
}


def dispersion_omega(
    k: float | np.ndarray,
    depth: float,
    g: float = GRAVITY,
    sigma: float = WATER_SURFACE_TENSION,
    rho: float = WATER_DENSITY,
) -> float | np.ndarray:
    """Return the angular frequency of capillary-gravity waves, rad/s.

    ``omega**2 = (g k + sigma k**3 / rho) tanh(k depth)``.

    Parameters
    ----------
    k : float or ndarray
        Wavenumber, rad/m (>= 0).
    depth : float
        Fluid depth, m (> 0).
    g : float
        Gravitational acceleration, m/s^2.
    sigma : float
        Surface tension, N/m.
    rho : float
        Fluid density, kg/m^3.

    Returns
    -------
    float or ndarray
        ``omega``, rad/s, the shape of ``k``.
    """
    for name, value in (("depth", depth), ("g", g), ("rho", rho)):
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be positive and finite, got {value!r}")
    if not (math.isfinite(sigma) and sigma >= 0):
        raise InputError(f"sigma must be non-negative and finite, got {sigma!r}")
    kk = np.asarray(k, dtype=float)
    if np.any(~np.isfinite(kk)) or np.any(kk < 0):
        raise InputError("wavenumber k must be finite and non-negative (rad/m)")
    omega = np.sqrt((g * kk + sigma * kk**3 / rho) * np.tanh(kk * depth))
    return float(omega) if omega.ndim == 0 else omega


def dispersion_k(
    omega: float,
    depth: float,
    g: float = GRAVITY,
    sigma: float = WATER_SURFACE_TENSION,
    rho: float = WATER_DENSITY,
) -> float:
    """Return the wavenumber (rad/m) of capillary-gravity waves of angular frequency ``omega``.

    The inverse of :func:`dispersion_omega` (which increases with ``k``), found by
    bisection to a relative 1e-13.

    Parameters
    ----------
    omega : float
        Angular frequency, rad/s (> 0).
    depth, g, sigma, rho : float
        As in :func:`dispersion_omega`.
    """
    if not (math.isfinite(omega) and omega > 0):
        raise InputError(f"omega must be positive and finite, got {omega!r} rad/s")
    low, high = 0.0, 1.0
    while dispersion_omega(high, depth, g, sigma, rho) < omega:
        low, high = high, 2.0 * high
        if high > 1e12:
            raise InputError(f"no wavenumber has the angular frequency {omega!r} rad/s")
    while high - low > 1e-13 * high:
        middle = 0.5 * (low + high)
        if dispersion_omega(middle, depth, g, sigma, rho) < omega:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


@dataclass(frozen=True)
class Mode:
    """One standing mode ``cos(m pi X / L) cos(n pi Y / L) cos(omega t + phase)``.

    ``m``, ``n`` are non-negative integers (not both 0), ``amplitude`` in metres,
    ``phase`` in rad; ``X = x + L/2``, ``Y = y + L/2`` put the basin's corner at 0.
    """

    m: int
    n: int
    amplitude: float
    phase: float = 0.0


@dataclass(frozen=True)
class StandingWaves:
    """Standing capillary-gravity waves in a square basin (free-slip walls).

    Parameters
    ----------
    modes : sequence of Mode
        The modes summed.
    basin_side : float
        Side of the square basin, m; centred on the frame.
    depth : float
        Fluid depth, m (sets the dispersion).
    sigma, rho, g : float
        Surface tension (N/m), density (kg/m^3), gravity (m/s^2).
    """

    modes: tuple[Mode, ...]
    basin_side: float
    depth: float
    sigma: float = WATER_SURFACE_TENSION
    rho: float = WATER_DENSITY
    g: float = GRAVITY
    omegas: tuple[float, ...] = field(init=False, repr=False)

    is_uniform = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.basin_side) and self.basin_side > 0):
            raise InputError(f"basin_side must be positive, got {self.basin_side!r} m")
        modes = tuple(self.modes)
        for mode in modes:
            if mode.m < 0 or mode.n < 0 or (mode.m == 0 and mode.n == 0):
                raise InputError(f"mode ({mode.m}, {mode.n}): indices must be >= 0, not both 0")
            if not (math.isfinite(mode.amplitude) and math.isfinite(mode.phase)):
                raise InputError(f"mode ({mode.m}, {mode.n}): amplitude and phase must be finite")
        object.__setattr__(self, "modes", modes)
        ks = [math.pi * math.hypot(m.m, m.n) / self.basin_side for m in modes]
        omegas = tuple(
            float(dispersion_omega(k, self.depth, self.g, self.sigma, self.rho)) for k in ks
        )
        object.__setattr__(self, "omegas", omegas)

    def __call__(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the height, m, at time ``t`` (s) and positions ``x``, ``y`` (m)."""
        side = self.basin_side
        xs = np.asarray(x, dtype=float) + side / 2
        ys = np.asarray(y, dtype=float) + side / 2
        total = np.zeros(np.broadcast_shapes(xs.shape, ys.shape))
        for mode, omega in zip(self.modes, self.omegas, strict=True):
            weight = mode.amplitude * math.cos(omega * t + mode.phase)
            total += (
                weight * np.cos(mode.m * math.pi * xs / side) * np.cos(mode.n * math.pi * ys / side)
            )
        return total

    def mean_level(self, t: float) -> float:
        """Return 0: standing modes conserve volume (m)."""
        return 0.0


def random_standing_waves(
    rng: np.random.Generator,
    *,
    basin_side: float,
    depth: float,
    rms: float,
    n_modes: int = 6,
    max_index: int = 12,
    sigma: float = WATER_SURFACE_TENSION,
    rho: float = WATER_DENSITY,
) -> StandingWaves:
    """Return standing waves of ``n_modes`` random modes with total rms height ``rms`` (m).

    Mode indices are drawn in ``1 .. max_index``; phases uniformly; amplitudes
    Rayleigh-like, then scaled so the spatial rms over the basin is ``rms`` at t = 0
    with every cosine at its peak (the rms of a product of cosines is 1/2 per mode).
    """
    if n_modes < 1 or max_index < 1:
        raise InputError("n_modes and max_index must be >= 1")
    if not (math.isfinite(rms) and rms >= 0):
        raise InputError(f"rms must be non-negative, got {rms!r} m")
    indices = rng.integers(1, max_index + 1, size=(n_modes, 2))
    raw = rng.rayleigh(1.0, size=n_modes)
    scale = rms / (0.5 * math.sqrt(float(np.sum(raw**2))))
    phases = rng.uniform(0, 2 * math.pi, size=n_modes)
    modes = tuple(
        Mode(int(i), int(j), float(a * scale), float(p))
        for (i, j), a, p in zip(indices, raw, phases, strict=True)
    )
    return StandingWaves(modes, basin_side, depth, sigma=sigma, rho=rho)


@dataclass(frozen=True)
class UniformLevel:
    """A flat surface moving at a constant rate: ``h = level0 + rate t`` (m).

    Use :func:`evaporation` and :func:`injection` to build one from physical rates.
    """

    rate: float
    level0: float = 0.0

    is_uniform = True

    def __post_init__(self) -> None:
        for name in ("rate", "level0"):
            if not math.isfinite(getattr(self, name)):
                raise InputError(f"{name} must be finite, got {getattr(self, name)!r}")

    def __call__(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the height, m, broadcast over ``x`` and ``y`` (m)."""
        shape = np.broadcast_shapes(np.shape(x), np.shape(y))
        return np.full(shape, self.mean_level(t))

    def mean_level(self, t: float) -> float:
        """Return the level at time ``t`` (s), m."""
        return self.level0 + self.rate * t


def evaporation(rate: float, level0: float = 0.0) -> UniformLevel:
    """Return a level falling at ``rate`` m/s (positive: evaporating)."""
    if not (math.isfinite(rate) and rate >= 0):
        raise InputError(f"evaporation rate must be non-negative, got {rate!r} m/s")
    return UniformLevel(-rate, level0)


def injection(volume_rate: float, area: float, level0: float = 0.0) -> UniformLevel:
    """Return a level rising as ``volume_rate`` m^3/s flows into a basin of ``area`` m^2."""
    if not (math.isfinite(area) and area > 0):
        raise InputError(f"basin area must be positive, got {area!r} m^2")
    if not math.isfinite(volume_rate):
        raise InputError(f"volume rate must be finite, got {volume_rate!r} m^3/s")
    return UniformLevel(volume_rate / area, level0)


@dataclass(frozen=True)
class UserSurface:
    """Any function ``h(t, x, y)`` (m), checked for shape and finiteness on each call."""

    function: Callable[[float, np.ndarray, np.ndarray], np.ndarray]
    name: str = "user"

    is_uniform = False

    def __call__(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return ``function(t, x, y)`` broadcast to the positions' shape, m."""
        shape = np.broadcast_shapes(np.shape(x), np.shape(y))
        try:
            value = np.broadcast_to(np.asarray(self.function(t, x, y), dtype=float), shape)
        except ValueError as exc:
            raise InputError(f"surface {self.name!r} returned a wrong shape: {exc}") from exc
        if not np.all(np.isfinite(value)):
            raise InputError(f"surface {self.name!r} returned NaN or infinite heights")
        return value

    def mean_level(self, t: float) -> float:
        """Return NaN: the mean of an arbitrary function is not known in closed form."""
        return math.nan


@dataclass(frozen=True)
class SurfaceSum:
    """The sum of several surfaces (for example waves on an evaporating layer)."""

    parts: Sequence[Callable[[float, np.ndarray, np.ndarray], np.ndarray]]

    @property
    def is_uniform(self) -> bool:
        """True when every part is uniform."""
        return all(getattr(p, "is_uniform", False) for p in self.parts)

    def __call__(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the summed height, m."""
        shape = np.broadcast_shapes(np.shape(x), np.shape(y))
        total = np.zeros(shape)
        for part in self.parts:
            total = total + part(t, x, y)
        return total

    def mean_level(self, t: float) -> float:
        """Return the sum of the parts' mean levels, m (NaN if one is unknown)."""
        return float(sum(getattr(p, "mean_level", lambda _t: math.nan)(t) for p in self.parts))
