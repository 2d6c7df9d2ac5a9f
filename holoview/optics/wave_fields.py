"""Wave fields with a known truth: travelling waves with a flow, partial waves, a damped mode.

Surfaces ``h(t, x, y)`` in metres (the conventions of :mod:`holoview.optics.surfaces`:
``x`` along columns, ``y`` along rows, the frame centre at the origin), each with
``truth()``: the attributes and datasets that ``holoview simulate`` writes to
``/truth/waves``. Complex amplitudes ``A`` mean ``h = Re(A exp(-i omega t))``; the
azimuth is ``theta = atan2(y - y0, x - x0)``.

- :class:`TravellingWaves`: a sum of plane capillary-gravity waves
  ``a_j cos(k_j . r - omega_j t + phi_j)`` with ``omega_j = omega_0(|k_j|) + k_j . U``
  (a uniform mean flow ``U``), drawn by :func:`random_travelling_waves`.
- :class:`PartialWaves`: around a centre,
  ``Re sum_j [out_j H_m^(1)(k r) + in_j H_m^(2)(k r)] exp(i (m theta - omega t))``,
  outgoing (H^(1)) and incoming (H^(2)) parts of chosen complex amplitudes; ``k`` from
  the dispersion relation. The Hankel functions are singular at the centre: the height
  is zero inside ``core_radius`` and rises smoothly to the full field at
  ``1.5 core_radius`` (a drain's core, which a measurement masks).
- :class:`DampedMode`: ``Re(A exp(-gamma t) J_m(k r) exp(i (m theta - omega t)))``
  from ``t = 0``, a mode ringing down at frequency ``omega / 2 pi`` and rate ``gamma``.
- :class:`SwitchedOn`: any of them at rest until a start time, then rising (a
  wavemaker switched on, a mode excited, after the recording began).

Evaluation on the synthesiser's separable grid (``x`` of shape (1, cols), ``y`` of
shape (rows, 1)) costs one matrix product per frame for the travelling waves, and one
complex sum per partial wave for the others (their radial profiles are computed once).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import special

from holoview.errors import InputError
from holoview.optics.surfaces import (
    GRAVITY,
    WATER_DENSITY,
    WATER_SURFACE_TENSION,
    dispersion_k,
    dispersion_omega,
)

__all__ = [
    "CORE_FULL",
    "DampedMode",
    "PartialWave",
    "PartialWaves",
    "SwitchedOn",
    "TravellingWaves",
    "WaveConfig",
    "random_travelling_waves",
]

#: Partial waves are at full height beyond this many core radii of their centre (zero
#: inside one, a smooth rise between).
CORE_FULL = 1.5

#: Truth: ``(attributes, {name: (array, unit)})`` for ``/truth/waves``.
Truth = tuple[dict[str, Any], dict[str, tuple[np.ndarray, str]]]


def _positive(name: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        raise InputError(f"{name} must be positive and finite, got {value!r}")


def _separable(x: np.ndarray, y: np.ndarray) -> bool:
    """True for the synthesiser's grid: ``x`` one row, ``y`` one column."""
    return x.ndim == 2 and y.ndim == 2 and x.shape[0] == 1 and y.shape[1] == 1


@dataclass(frozen=True)
class TravellingWaves:
    """Plane capillary-gravity waves on a uniform flow.

    Parameters
    ----------
    wavevectors : ndarray, shape (M, 2)
        ``(kx, ky)`` of each wave, rad/m: the direction it travels.
    amplitudes : ndarray, shape (M,)
        Height amplitude of each wave, m.
    phases : ndarray, shape (M,)
        Phase at ``t = 0`` and the origin, rad.
    depth : float
        Fluid depth, m.
    flow : (float, float)
        Uniform mean flow ``(Ux, Uy)``, m/s.
    sigma, rho, g : float
        Surface tension (N/m), density (kg/m^3), gravity (m/s^2).
    """

    wavevectors: np.ndarray
    amplitudes: np.ndarray
    phases: np.ndarray
    depth: float
    flow: tuple[float, float] = (0.0, 0.0)
    sigma: float = WATER_SURFACE_TENSION
    rho: float = WATER_DENSITY
    g: float = GRAVITY
    omegas: np.ndarray = field(init=False, repr=False)

    is_uniform = False

    def __post_init__(self) -> None:
        k = np.asarray(self.wavevectors, dtype=np.float64).reshape(-1, 2)
        a = np.asarray(self.amplitudes, dtype=np.float64).ravel()
        p = np.asarray(self.phases, dtype=np.float64).ravel()
        if not (k.shape[0] == a.size == p.size) or a.size == 0:
            raise InputError("travelling waves need as many wave vectors, amplitudes and phases")
        if not (np.all(np.isfinite(k)) and np.all(np.isfinite(a)) and np.all(np.isfinite(p))):
            raise InputError("travelling waves: wave vectors, amplitudes and phases must be finite")
        if not all(math.isfinite(u) for u in self.flow):
            raise InputError(f"the flow must be finite, got {self.flow!r}")
        omega0 = np.asarray(
            dispersion_omega(np.hypot(k[:, 0], k[:, 1]), self.depth, self.g, self.sigma, self.rho)
        )
        omegas = omega0 + k[:, 0] * self.flow[0] + k[:, 1] * self.flow[1]
        if np.any(omegas <= 0):
            raise InputError(
                "the flow sweeps some waves backwards (k . U < -omega_0): lower the flow or "
                "raise the smallest wavenumber"
            )
        for name, value in (("wavevectors", k), ("amplitudes", a), ("phases", p)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "omegas", omegas)

    def __call__(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the height, m, at time ``t`` (s) and positions ``x``, ``y`` (m)."""
        xs = np.asarray(x, dtype=np.float64)
        ys = np.asarray(y, dtype=np.float64)
        weights = self.amplitudes * np.exp(1j * (self.phases - self.omegas * t))
        if _separable(xs, ys):
            along_x = np.exp(1j * np.outer(self.wavevectors[:, 0], xs[0])).astype(np.complex64)
            along_y = np.exp(1j * np.outer(self.wavevectors[:, 1], ys[:, 0])).astype(np.complex64)
            product = (along_y * weights[:, np.newaxis].astype(np.complex64)).T @ along_x
            return product.real.astype(np.float64)
        total = np.zeros(np.broadcast_shapes(xs.shape, ys.shape))
        for (kx, ky), w in zip(self.wavevectors, weights, strict=True):
            total += (w * np.exp(1j * (kx * xs + ky * ys))).real
        return total

    def mean_level(self, t: float) -> float:
        """Return 0: the waves carry no mean level (m)."""
        return 0.0

    def truth(self) -> Truth:
        """The flow, fluid and every wave, SI units."""
        attrs = {
            "kind": "travelling",
            "flow_m_per_s": list(self.flow),
            "depth_m": self.depth,
            "sigma_n_per_m": self.sigma,
            "rho_kg_per_m3": self.rho,
            "g_m_per_s2": self.g,
            "convention": "h = sum a cos(k.r - omega t + phase), omega = omega_0(|k|) + k.U",
        }
        data = {
            "wavevector_rad_per_m": (self.wavevectors, "rad/m"),
            "amplitude_m": (self.amplitudes, "m"),
            "phase_rad": (self.phases, "rad"),
            "omega_rad_per_s": (self.omegas, "rad/s"),
        }
        return attrs, data


def random_travelling_waves(
    rng: np.random.Generator,
    *,
    k_range: tuple[float, float],
    components: int,
    rms: float,
    depth: float,
    flow: tuple[float, float] = (0.0, 0.0),
    sigma: float = WATER_SURFACE_TENSION,
    rho: float = WATER_DENSITY,
) -> TravellingWaves:
    """Return ``components`` plane waves, wavenumbers uniform in ``k_range`` (rad/m).

    Directions and phases are uniform; amplitudes Rayleigh-distributed, scaled so the
    field's rms height is ``rms`` (m).
    """
    k_low, k_high = k_range
    _positive("the smallest wavenumber", k_low)
    if not (math.isfinite(k_high) and k_high > k_low):
        raise InputError(f"the wavenumber range must increase, got {k_range!r} rad/m")
    if components < 1:
        raise InputError(f"components must be >= 1, got {components}")
    if not (math.isfinite(rms) and rms >= 0):
        raise InputError(f"rms must be non-negative, got {rms!r} m")
    k = rng.uniform(k_low, k_high, components)
    angle = rng.uniform(0.0, 2.0 * math.pi, components)
    raw = rng.rayleigh(1.0, components)
    amplitudes = raw * rms / math.sqrt(0.5 * float(np.sum(raw**2)))
    return TravellingWaves(
        np.column_stack([k * np.cos(angle), k * np.sin(angle)]),
        amplitudes,
        rng.uniform(0.0, 2.0 * math.pi, components),
        depth,
        flow=(float(flow[0]), float(flow[1])),
        sigma=sigma,
        rho=rho,
    )


@dataclass(frozen=True)
class PartialWave:
    """One azimuthal number ``m`` at one frequency, its incoming and outgoing amplitudes.

    ``incoming`` and ``outgoing`` are complex, m: the coefficients of ``H_m^(2)(k r)``
    and ``H_m^(1)(k r)`` in ``h = Re(sum (...) exp(i (m theta - omega t)))``.
    """

    m: int
    frequency: float
    incoming: complex
    outgoing: complex


class _RadialCache:
    """The complex profiles of a centred field on the last grid it was evaluated on."""

    def __init__(self) -> None:
        self.key: tuple[Any, ...] | None = None
        self.maps: list[np.ndarray] = []


def _polar(x: np.ndarray, y: np.ndarray, centre: tuple[float, float]) -> tuple[np.ndarray, ...]:
    dx = np.asarray(x, dtype=np.float64) - centre[0]
    dy = np.asarray(y, dtype=np.float64) - centre[1]
    return np.hypot(dx, dy), np.arctan2(dy, dx)


def _core_ramp(r: np.ndarray, core: float) -> np.ndarray:
    """0 inside ``core``, 1 beyond :data:`CORE_FULL` ``core``, a smooth (sin^2) rise between."""
    if core <= 0:
        return np.ones_like(r)
    s = np.clip((r - core) / ((CORE_FULL - 1.0) * core), 0.0, 1.0)
    return np.sin(0.5 * math.pi * s) ** 2


def _grid_key(x: np.ndarray, y: np.ndarray) -> tuple[Any, ...]:
    xs, ys = np.asarray(x), np.asarray(y)
    return (xs.shape, ys.shape, hash(xs.tobytes()), hash(ys.tobytes()))


@dataclass(frozen=True)
class PartialWaves:
    """Incoming and outgoing partial waves around a centre (module docstring).

    Parameters
    ----------
    waves : sequence of PartialWave
    centre : (float, float)
        ``(x0, y0)``, m, on the object plane.
    core_radius : float
        Height zero inside, full beyond 1.5 times, m (0: no core; only a regular
        field, ``incoming == outgoing``, is finite at the centre).
    depth, sigma, rho, g : float
        As :class:`TravellingWaves` (the wavenumber of each frequency).
    """

    waves: tuple[PartialWave, ...]
    centre: tuple[float, float] = (0.0, 0.0)
    core_radius: float = 3e-3
    depth: float = 5e-3
    sigma: float = WATER_SURFACE_TENSION
    rho: float = WATER_DENSITY
    g: float = GRAVITY
    wavenumbers: tuple[float, ...] = field(init=False, repr=False)
    _cache: _RadialCache = field(init=False, repr=False, compare=False)

    is_uniform = False

    def __post_init__(self) -> None:
        waves = tuple(self.waves)
        if not waves:
            raise InputError("partial waves: give at least one (m, f, incoming, outgoing)")
        for wave in waves:
            _positive(f"the frequency of partial wave m={wave.m}", wave.frequency)
            if not (np.isfinite(complex(wave.incoming)) and np.isfinite(complex(wave.outgoing))):
                raise InputError(f"partial wave m={wave.m}: amplitudes must be finite")
        if not (math.isfinite(self.core_radius) and self.core_radius >= 0):
            raise InputError(f"core_radius must be >= 0, got {self.core_radius!r} m")
        ks = tuple(
            dispersion_k(2 * math.pi * w.frequency, self.depth, self.g, self.sigma, self.rho)
            for w in waves
        )
        object.__setattr__(self, "waves", waves)
        object.__setattr__(self, "wavenumbers", ks)
        object.__setattr__(self, "_cache", _RadialCache())

    def _maps(self, x: np.ndarray, y: np.ndarray) -> list[np.ndarray]:
        key = _grid_key(x, y)
        if self._cache.key != key:
            r, theta = _polar(x, y, self.centre)
            ramp = _core_ramp(r, self.core_radius)
            safe = np.maximum(r, 1e-12)
            maps = []
            for wave, k in zip(self.waves, self.wavenumbers, strict=True):
                radial = complex(wave.outgoing) * special.hankel1(wave.m, k * safe) + complex(
                    wave.incoming
                ) * special.hankel2(wave.m, k * safe)
                radial = np.where(ramp > 0, radial * ramp, 0.0)
                maps.append((radial * np.exp(1j * wave.m * theta)).astype(np.complex128))
            self._cache.key, self._cache.maps = key, maps
        return self._cache.maps

    def __call__(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the height, m, at time ``t`` (s) and positions ``x``, ``y`` (m)."""
        total = np.zeros(np.broadcast_shapes(np.shape(x), np.shape(y)))
        for wave, profile in zip(self.waves, self._maps(x, y), strict=True):
            total += (profile * np.exp(-2j * math.pi * wave.frequency * t)).real
        return total

    def mean_level(self, t: float) -> float:
        """Return NaN: the field's mean over a frame is not known in closed form."""
        return math.nan

    def truth(self) -> Truth:
        """Centre, core, fluid and every partial wave, SI units."""
        attrs = {
            "kind": "partial-waves",
            "centre_m": list(self.centre),
            "core_radius_m": self.core_radius,
            "depth_m": self.depth,
            "sigma_n_per_m": self.sigma,
            "rho_kg_per_m3": self.rho,
            "g_m_per_s2": self.g,
            "convention": "h = Re sum [outgoing H_m^(1)(k r) + incoming H_m^(2)(k r)] "
            "exp(i (m theta - omega t)), theta = atan2(y - y0, x - x0)",
        }
        w = self.waves
        data = {
            "m": (np.array([p.m for p in w], np.int64), "1"),
            "frequency_hz": (np.array([p.frequency for p in w]), "Hz"),
            "wavenumber_rad_per_m": (np.array(self.wavenumbers), "rad/m"),
            "incoming_m": (np.array([complex(p.incoming) for p in w]), "m"),
            "outgoing_m": (np.array([complex(p.outgoing) for p in w]), "m"),
        }
        return attrs, data


@dataclass(frozen=True)
class DampedMode:
    """A mode ringing down: ``Re(A exp(-gamma t) J_m(k r) exp(i (m theta - omega t)))``.

    Parameters
    ----------
    m : int
        Azimuthal number.
    frequency : float
        ``omega / 2 pi``, Hz.
    decay : float
        ``gamma``, 1/s (>= 0).
    amplitude : complex
        ``A``, m.
    centre : (float, float)
        ``(x0, y0)``, m.
    depth, sigma, rho, g : float
        As :class:`TravellingWaves` (``k`` from the frequency).
    """

    m: int
    frequency: float
    decay: float
    amplitude: complex
    centre: tuple[float, float] = (0.0, 0.0)
    depth: float = 5e-3
    sigma: float = WATER_SURFACE_TENSION
    rho: float = WATER_DENSITY
    g: float = GRAVITY
    wavenumber: float = field(init=False, repr=False)
    _cache: _RadialCache = field(init=False, repr=False, compare=False)

    is_uniform = False

    def __post_init__(self) -> None:
        _positive("the mode's frequency", self.frequency)
        if not (math.isfinite(self.decay) and self.decay >= 0):
            raise InputError(f"the decay rate must be >= 0, got {self.decay!r} 1/s")
        if not np.isfinite(complex(self.amplitude)):
            raise InputError("the mode's amplitude must be finite")
        k = dispersion_k(2 * math.pi * self.frequency, self.depth, self.g, self.sigma, self.rho)
        object.__setattr__(self, "wavenumber", k)
        object.__setattr__(self, "_cache", _RadialCache())

    def __call__(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the height, m, at time ``t`` (s) and positions ``x``, ``y`` (m)."""
        key = _grid_key(x, y)
        if self._cache.key != key:
            r, theta = _polar(x, y, self.centre)
            profile = special.jv(self.m, self.wavenumber * r) * np.exp(1j * self.m * theta)
            self._cache.key, self._cache.maps = key, [complex(self.amplitude) * profile]
        decay = math.exp(-self.decay * t) if t >= 0 else 0.0
        rotate = np.exp(-2j * math.pi * self.frequency * t)
        shape = np.broadcast_shapes(np.shape(x), np.shape(y))
        return np.broadcast_to((self._cache.maps[0] * (decay * rotate)).real, shape)

    def mean_level(self, t: float) -> float:
        """Return NaN: the mean over a frame is not known in closed form."""
        return math.nan

    def truth(self) -> Truth:
        """The mode, its centre and fluid, SI units."""
        attrs = {
            "kind": "ringdown",
            "m": self.m,
            "frequency_hz": self.frequency,
            "decay_per_s": self.decay,
            "amplitude_m": [complex(self.amplitude).real, complex(self.amplitude).imag],
            "wavenumber_rad_per_m": self.wavenumber,
            "centre_m": list(self.centre),
            "depth_m": self.depth,
            "sigma_n_per_m": self.sigma,
            "rho_kg_per_m3": self.rho,
            "g_m_per_s2": self.g,
            "convention": "h = Re(A exp(-decay t) J_m(k r) exp(i (m theta - omega t)))",
        }
        return attrs, {}


@dataclass(frozen=True)
class SwitchedOn:
    """A surface at rest until ``start`` (s), rising to full height over ``rise`` (s).

    ``h(t) = envelope(t) surface(t)``, the envelope 0 before ``start``, a sine-squared
    rise, 1 after ``start + rise``: a wavemaker switched on after the recording began
    (so the first frame shows the bare carriers), or a mode excited at ``start``
    (``rise`` 0; then ``surface`` is evaluated at ``t - start``).
    """

    surface: Any
    start: float = 0.0
    rise: float = 0.0

    is_uniform = False

    def __post_init__(self) -> None:
        for name in ("start", "rise"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise InputError(f"the waves' {name} must be >= 0, got {value!r} s")

    def envelope(self, t: float) -> float:
        """Return the envelope at ``t`` (s), 0 to 1."""
        if t < self.start:
            return 0.0
        if self.rise <= 0 or t >= self.start + self.rise:
            return 1.0
        return math.sin(0.5 * math.pi * (t - self.start) / self.rise) ** 2

    def __call__(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the height, m, at time ``t`` (s) and positions ``x``, ``y`` (m)."""
        level = self.envelope(t)
        shape = np.broadcast_shapes(np.shape(x), np.shape(y))
        if level == 0.0:
            return np.zeros(shape)
        delay = self.start if isinstance(self.surface, DampedMode) else 0.0
        return level * np.broadcast_to(self.surface(t - delay, x, y), shape)

    def mean_level(self, t: float) -> float:
        """Return the surface's mean level times the envelope, m."""
        return self.envelope(t) * float(self.surface.mean_level(t))

    def truth(self) -> Truth:
        """The surface's truth with ``start_s`` and ``rise_s``."""
        attrs, data = self.surface.truth()
        return {**attrs, "start_s": self.start, "rise_s": self.rise}, data


@dataclass(frozen=True)
class WaveConfig:
    """What the wave scenarios of :func:`holoview.optics.scenarios.make_surface` draw.

    Attributes
    ----------
    flow : (float, float)
        Uniform mean flow of the travelling waves, m/s.
    k_range : (float, float)
        Wavenumbers of the travelling waves, rad/m.
    components : int
        Number of travelling plane waves.
    partial_waves : tuple of PartialWave
        The partial waves (``partial-waves`` scenario).
    centre : (float, float)
        Centre of the partial waves and the damped mode on the object plane, m.
    core_radius : float
        Masked core of the partial waves, m.
    mode_m, mode_frequency, mode_decay, mode_amplitude
        The damped mode (``ringdown``): azimuthal number, Hz, 1/s, m.
    start, rise : float
        The waves start at ``start`` (s) and reach full height ``rise`` (s) later
        (:class:`SwitchedOn`); a damped mode starts at full height at ``start``.
    """

    flow: tuple[float, float] = (0.02, 0.01)
    k_range: tuple[float, float] = (300.0, 1800.0)
    components: int = 300
    partial_waves: tuple[PartialWave, ...] = (
        PartialWave(0, 14.0, 20e-9, 12e-9),
        PartialWave(2, 22.0, 8e-9 + 6e-9j, 15e-9),
        PartialWave(-1, 30.0, 10e-9, 5e-9j),
    )
    centre: tuple[float, float] = (0.0, 0.0)
    core_radius: float = 4e-3
    mode_m: int = 2
    mode_frequency: float = 12.0
    mode_decay: float = 0.8
    mode_amplitude: float = 60e-9
    start: float = 0.0
    rise: float = 0.0

    def __post_init__(self) -> None:
        if not all(math.isfinite(u) for u in (*self.flow, *self.centre)):
            raise InputError(f"flow and centre must be finite, got {self.flow}, {self.centre}")
        if self.components < 1:
            raise InputError(f"components must be >= 1, got {self.components}")
        if not (math.isfinite(self.mode_amplitude) and self.mode_amplitude >= 0):
            raise InputError(f"the mode's amplitude must be >= 0, got {self.mode_amplitude!r}")
