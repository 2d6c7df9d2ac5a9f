"""Simulated recordings with a known truth: waves, evaporation, syringe injection.

The wave-analysis scenarios (:mod:`holoview.optics.wave_fields`): ``travelling``
(capillary-gravity waves on a uniform flow), ``partial-waves`` (incoming and outgoing
partial waves around a centre) and ``ringdown`` (a damped mode), their parameters in a
:class:`~holoview.optics.wave_fields.WaveConfig`.

:func:`simulate` yields ``(frame, truth)`` pairs frame after frame, from the fast
synthesiser, for a surface built by :func:`make_surface` and a reference arm that
jitters. The jitter is an Ornstein-Uhlenbeck process on the reference air path
(rms ``vibration_rms`` metres, correlation time ``vibration_time`` seconds): it moves
the RF and RB_j phases by ``2 k0 n1 x(t)`` and leaves FB_j alone, as the paper notes
for air-borne disturbances (supplement I).

Small frames are cheap: a 256 x 256 frame with Poisson noise costs about 3 ms for a
uniform level and 6 ms for waves, so tests can simulate hundreds of frames in seconds.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from holoview.errors import InputError
from holoview.optics.setup import Setup
from holoview.optics.surfaces import (
    WATER_DENSITY,
    WATER_SURFACE_TENSION,
    evaporation,
    injection,
    random_standing_waves,
)
from holoview.optics.synthesis import HologramSynthesizer, pixel_coordinates
from holoview.optics.wave_fields import (
    DampedMode,
    PartialWaves,
    SwitchedOn,
    WaveConfig,
    random_travelling_waves,
)

#: The scenarios :func:`simulate` knows.
SCENARIOS = ("waves", "evaporation", "injection", "travelling", "partial-waves", "ringdown")


@dataclass(frozen=True)
class ScenarioConfig:
    """Physical parameters of the scenarios, SI units.

    Defaults follow the paper: water evaporating at 0.8159 um/min (section 4.2),
    12.3 uL/s injected into a 70.6 cm^2 basin (section 4.2.1), an 84 mm square basin.

    Attributes
    ----------
    evaporation_rate : float
        Level fall, m/s.
    injection_rate : float
        Injected volume rate, m^3/s.
    basin_area : float
        Basin cross-section for the injection, m^2.
    basin_side : float
        Square basin side for the standing waves, m.
    wave_rms : float
        Spatial rms of the wave height, m.
    wave_modes : int
        Number of standing modes.
    wave_max_index : int
        Largest mode index (sets the shortest wavelength, ``2 basin_side / index``).
    sigma, rho : float
        Surface tension (N/m) and density (kg/m^3) of the fluid.
    vibration_rms : float
        Rms of the reference air-path jitter, m (0: none).
    vibration_time : float
        Correlation time of the jitter, s.
    """

    evaporation_rate: float = 0.8159e-6 / 60
    injection_rate: float = 12.3e-9
    basin_area: float = 70.6e-4
    basin_side: float = 84e-3
    wave_rms: float = 30e-9
    wave_modes: int = 6
    wave_max_index: int = 24
    sigma: float = WATER_SURFACE_TENSION
    rho: float = WATER_DENSITY
    vibration_rms: float = 2e-9
    vibration_time: float = 0.05

    def __post_init__(self) -> None:
        for name in (
            "evaporation_rate",
            "injection_rate",
            "basin_area",
            "basin_side",
            "wave_rms",
            "sigma",
            "rho",
            "vibration_rms",
            "vibration_time",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise InputError(f"{name} must be a non-negative finite number, got {value!r}")
        for name in ("basin_area", "basin_side", "rho", "vibration_time"):
            if getattr(self, name) <= 0:
                raise InputError(f"{name} must be positive, got {getattr(self, name)!r}")
        for name in ("wave_modes", "wave_max_index"):
            if getattr(self, name) < 1:
                raise InputError(f"{name} must be >= 1, got {getattr(self, name)!r}")


@dataclass(frozen=True)
class FrameTruth:
    """What was simulated for one frame.

    Attributes
    ----------
    index : int
        Frame number from 0.
    time : float
        Time of the frame, s.
    mean_height : float
        Mean surface height over the frame, m (relative to the rest level).
    reference_path : float
        Reference air-path jitter, m.
    reference_phase : float
        The phase it adds to the reference arm, ``2 k0 n1 reference_path``, rad.
    height : ndarray or None
        The height map, m, ``setup.shape`` (None for a uniform level).
    """

    index: int
    time: float
    mean_height: float
    reference_path: float
    reference_phase: float
    height: np.ndarray | None


def make_surface(
    setup: Setup,
    scenario: str,
    config: ScenarioConfig,
    rng: np.random.Generator,
    waves: WaveConfig | None = None,
) -> Callable[[float, np.ndarray, np.ndarray], np.ndarray]:
    """Return the surface ``h(t, x, y)`` (m) of a scenario.

    Parameters
    ----------
    setup : Setup
        Supplies the depth (dispersion of the waves).
    scenario : str
        One of :data:`SCENARIOS`.
    config : ScenarioConfig
        The physical parameters (``sigma``, ``rho`` and ``wave_rms`` also for the wave
        scenarios).
    rng : numpy.random.Generator
        Draws the wave modes.
    waves : WaveConfig, optional
        The travelling waves, partial waves and damped mode (defaults: WaveConfig()).
    """
    waves = waves or WaveConfig()
    surface = _wave_surface(setup, scenario, config, rng, waves)
    if surface is not None:
        if waves.start > 0 or waves.rise > 0:
            return SwitchedOn(surface, waves.start, waves.rise)
        return surface
    if scenario == "waves":
        return random_standing_waves(
            rng,
            basin_side=config.basin_side,
            depth=setup.depth,
            rms=config.wave_rms,
            n_modes=config.wave_modes,
            max_index=config.wave_max_index,
            sigma=config.sigma,
            rho=config.rho,
        )
    if scenario == "evaporation":
        return evaporation(config.evaporation_rate)
    if scenario == "injection":
        return injection(config.injection_rate, config.basin_area)
    raise InputError(f"unknown scenario {scenario!r}; choose one of {', '.join(SCENARIOS)}")


def _wave_surface(
    setup: Setup,
    scenario: str,
    config: ScenarioConfig,
    rng: np.random.Generator,
    waves: WaveConfig,
) -> Callable[[float, np.ndarray, np.ndarray], np.ndarray] | None:
    """The surface of a wave-analysis scenario (None for the others)."""
    fluid = {"depth": setup.depth, "sigma": config.sigma, "rho": config.rho}
    if scenario == "travelling":
        return random_travelling_waves(
            rng,
            k_range=waves.k_range,
            components=waves.components,
            rms=config.wave_rms,
            flow=waves.flow,
            **fluid,
        )
    if scenario == "partial-waves":
        return PartialWaves(
            waves.partial_waves, centre=waves.centre, core_radius=waves.core_radius, **fluid
        )
    if scenario == "ringdown":
        return DampedMode(
            waves.mode_m,
            waves.mode_frequency,
            waves.mode_decay,
            waves.mode_amplitude,
            centre=waves.centre,
            **fluid,
        )
    return None


def vibration(
    frames: int, fps: float, rms: float, correlation_time: float, rng: np.random.Generator
) -> np.ndarray:
    """Return an Ornstein-Uhlenbeck path jitter sampled at ``fps`` (m), stationary from t=0."""
    if rms == 0:
        return np.zeros(frames)
    a = math.exp(-1 / (fps * correlation_time))
    kicks = rng.standard_normal(frames) * rms * math.sqrt(1 - a * a)
    path = np.empty(frames)
    value = rng.standard_normal() * rms
    for i in range(frames):
        path[i] = value
        value = a * value + kicks[i]
    return path


def simulate(
    setup: Setup,
    scenario: str,
    *,
    frames: int,
    fps: float,
    seed: int | None = None,
    config: ScenarioConfig | None = None,
    noise: str = "poisson",
    surface: Callable[[float, np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> Iterator[tuple[np.ndarray, FrameTruth]]:
    """Yield ``(raw frame, truth)`` for a simulated sequence.

    Parameters
    ----------
    setup : Setup
        The bench and camera.
    scenario : str
        One of :data:`SCENARIOS` (ignored when ``surface`` is given, except in
        messages).
    frames : int
        Number of frames (>= 1).
    fps : float
        Frame rate, frames/s.
    seed : int, optional
        Seed of everything random (modes, jitter, noise): same seed, same frames.
    config : ScenarioConfig, optional
        Physical parameters (defaults: the paper's).
    noise : str
        Shot-noise model (see :mod:`holoview.optics.camera`).
    surface : callable, optional
        Any ``h(t, x, y)`` (m) to use instead of the scenario's; with an ``is_uniform``
        attribute set True it is evaluated once per frame at the frame centre.

    Yields
    ------
    frame : ndarray of uint8 or uint16
        The raw camera frame (a new array each time).
    truth : FrameTruth
    """
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        raise InputError(f"frames must be a positive integer, got {frames!r}")
    if not (isinstance(fps, int | float) and math.isfinite(fps) and fps > 0):
        raise InputError(f"fps must be positive, got {fps!r}")
    config = config or ScenarioConfig()
    rng = np.random.default_rng(seed)
    if surface is None:
        surface = make_surface(setup, scenario, config, rng)
    uniform = bool(getattr(surface, "is_uniform", False))
    synthesizer = HologramSynthesizer(setup, noise=noise)
    jitter = vibration(frames, fps, config.vibration_rms, config.vibration_time, rng)
    k2n1 = 4 * math.pi * setup.n1 / setup.wavelength
    x, y = pixel_coordinates(setup)
    centre = (np.zeros(1), np.zeros(1))
    for index in range(frames):
        t = index / fps
        phase = k2n1 * float(jitter[index])
        if uniform:
            level = float(np.asarray(surface(t, *centre)).ravel()[0])
            frame = synthesizer.render(level, reference_phase=phase, rng=rng)
            truth = FrameTruth(index, t, level, float(jitter[index]), phase, None)
        else:
            height = np.broadcast_to(surface(t, x, y), setup.shape).astype(np.float64)
            frame = synthesizer.render(height, reference_phase=phase, rng=rng)
            truth = FrameTruth(index, t, float(height.mean()), float(jitter[index]), phase, height)
        yield frame, truth
