"""The capillary-gravity dispersion relation with a mean flow, and its fit to an omega-k ridge.

Linear waves on a liquid of depth ``d``, density ``rho`` and surface tension ``sigma``
follow ``omega_0^2 = (g k + sigma k^3 / rho) tanh(k d)``
(:func:`holoview.optics.surfaces.dispersion_omega`); a uniform mean flow ``U`` shifts
a wave travelling along ``k`` to ``omega = omega_0(|k|) + k . U`` (the sign convention
of :mod:`~holoview.processing.waves.omega_k`: power at ``(f, +k)`` travels along ``+k``).

:func:`fit_dispersion` fits ``sigma``, ``d`` and ``U`` (each can be held) to the
ridge frequencies (:func:`~holoview.processing.waves.ridge.find_ridge`) by least
squares, three times: first on the brightest frequency of each cell whose contrast is
within a hundredth of the brightest cells' (a soft-L1 loss, as cells of noise, of a
strong line's leakage or of waves aliased past the Nyquist frequency put their peaks
anywhere), then within 15 % and 8 % of the model, dropping cells more than four robust
standard deviations off. Each fit takes the cells whose line is one wave's (``sharp``:
a blend of neighbouring waves pulls the frequency, :mod:`~holoview.processing.waves.ridge`)
while at least :data:`SHARP_SHARE` of the cells and enough for the fit are; where lines
are broad throughout (damped waves), every cell. The standard errors come from the
residual scatter. The ridge's cells are local maxima, never neighbours, so their
residuals are independent (measured: correlations of -0.06 to +0.10 two cells apart):
over 20 seeds of each of four fields (truth maps: dense and sparse, with 100 nm of
noise), z = error / standard error has an rms of 1.01 (sigma), 1.13 (depth), 1.10 and
1.12 (flow), 91-96 % within two. What the depth's error leaves out is its bias in dense
fields, +0.6 to +1.5 % there (blends of neighbouring lines that sharp cells do not
wholly avoid, :mod:`~holoview.processing.waves.ridge`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from holoview.errors import InputError
from holoview.optics.surfaces import (
    FLUID_MECHANICS,
    GRAVITY,
    WATER_DENSITY,
    WATER_SURFACE_TENSION,
    dispersion_omega,
)
from holoview.processing.waves.omega_k import OmegaKSpectrum
from holoview.processing.waves.ridge import Ridge, find_ridge, noise_contrast

logger = logging.getLogger(__name__)

__all__ = [
    "DEPTH_CHI2",
    "DispersionFit",
    "Fluid",
    "check_fit_settings",
    "fit_dispersion",
    "wave_omega",
]

#: A depth is determined when ten times it fits worse by more than this in chi^2 (in
#: units of the residual variance): three standard errors.
DEPTH_CHI2 = 9.0

#: The first fit takes the cells whose contrast is at least this share of the 90th
#: percentile of the contrasts (but ``min_contrast``).
FIRST_CONTRAST = 0.01

#: The least share of a ridge's cells that must be sharp (one wave's line) for the fit to
#: take only those.
SHARP_SHARE = 0.5

#: The parameters that can be held: surface tension, depth, flow (both components).
PARAMETERS = ("sigma", "depth", "flow")

#: The lowest wavenumber fitted by default, in steps of the field's wave vector: below,
#: a wave spans too few cells of the spectrum for a frequency of its own.
FIRST_STEPS = 4.0

#: Bounds of the fitted depth (m) and surface tension (N/m).
DEPTH_BOUNDS = (1e-5, 10.0)
SIGMA_BOUNDS = (1e-4, 1.0)


@dataclass(frozen=True)
class Fluid:
    """The liquid's mechanics, SI units.

    Attributes
    ----------
    density : float
        kg/m^3.
    surface_tension : float
        N/m (the starting value of a fit).
    gravity : float
        m/s^2.
    name : str
    """

    density: float = WATER_DENSITY
    surface_tension: float = WATER_SURFACE_TENSION
    gravity: float = GRAVITY
    name: str = "water"

    def __post_init__(self) -> None:
        for name in ("density", "gravity"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"the fluid's {name} must be positive, got {value!r}")
        if not (math.isfinite(self.surface_tension) and self.surface_tension >= 0):
            raise InputError(f"the surface tension must be >= 0, got {self.surface_tension!r}")

    @classmethod
    def named(cls, name: str) -> Fluid:
        """Return a fluid of :data:`holoview.optics.surfaces.FLUID_MECHANICS` at 20 degC."""
        if name not in FLUID_MECHANICS:
            raise InputError(
                f"unknown fluid {name!r}; choose one of {', '.join(sorted(FLUID_MECHANICS))}"
            )
        density, sigma = FLUID_MECHANICS[name]
        return cls(density, sigma, GRAVITY, name)


def wave_omega(
    kx: ArrayLike,
    ky: ArrayLike,
    *,
    surface_tension: float,
    depth: float,
    flow: tuple[float, float] = (0.0, 0.0),
    fluid: Fluid | None = None,
) -> NDArray[np.float64]:
    """Return the angular frequency (rad/s) of waves travelling along ``(kx, ky)`` (rad/m).

    ``omega = omega_0(|k|) + kx Ux + ky Uy`` with ``flow = (Ux, Uy)`` in m/s and
    ``omega_0`` the capillary-gravity relation on ``depth`` (m).
    """
    fluid = fluid or Fluid()
    kxx = np.asarray(kx, dtype=np.float64)
    kyy = np.asarray(ky, dtype=np.float64)
    omega0 = np.asarray(
        dispersion_omega(
            np.hypot(kxx, kyy),
            depth,
            g=fluid.gravity,
            sigma=surface_tension,
            rho=fluid.density,
        )
    )
    return omega0 + kxx * flow[0] + kyy * flow[1]


@dataclass(frozen=True)
class DispersionFit:
    """Surface tension, depth and mean flow fitted to the ridge of an omega-k spectrum.

    Attributes
    ----------
    surface_tension, surface_tension_stderr : float
        N/m (the standard error is 0 when held).
    depth, depth_stderr : float
        m.
    flow, flow_stderr : tuple of float
        ``(Ux, Uy)``, m/s (x along columns, y along rows).
    held : tuple of str
        The parameters held at their given values (of ``sigma``, ``depth``, ``flow``).
    fluid : Fluid
        Density and gravity used.
    ridge : Ridge
        The cells fitted.
    rms_residual : float
        RMS of the ridge frequencies about the model, rad/s.
    k_range : tuple of float
        Wavenumbers fitted, rad/m.
    correlation : ndarray, shape (P, P)
        Correlation matrix of the free parameters (order of ``free``).
    free : tuple of str
        The fitted parameters, in the order ``sigma``, ``depth``, ``flow_x``, ``flow_y``.
    """

    surface_tension: float
    surface_tension_stderr: float
    depth: float
    depth_stderr: float
    flow: tuple[float, float]
    flow_stderr: tuple[float, float]
    held: tuple[str, ...]
    fluid: Fluid
    ridge: Ridge
    rms_residual: float
    k_range: tuple[float, float]
    correlation: NDArray[np.float64] = field(repr=False)
    free: tuple[str, ...] = ()

    def omega(self, kx: ArrayLike, ky: ArrayLike) -> NDArray[np.float64]:
        """Return the fitted model's frequency (rad/s) along ``(kx, ky)`` (rad/m)."""
        return wave_omega(
            kx,
            ky,
            surface_tension=self.surface_tension,
            depth=self.depth,
            flow=self.flow,
            fluid=self.fluid,
        )

    def as_dict(self) -> dict[str, Any]:
        """The values with their errors and units, for a JSON summary."""
        return {
            "surface_tension_n_per_m": self.surface_tension,
            "surface_tension_stderr_n_per_m": self.surface_tension_stderr,
            "depth_m": self.depth,
            "depth_stderr_m": self.depth_stderr,
            "flow_m_per_s": list(self.flow),
            "flow_stderr_m_per_s": list(self.flow_stderr),
            "held": list(self.held),
            "density_kg_per_m3": self.fluid.density,
            "gravity_m_per_s2": self.fluid.gravity,
            "cells": int(self.ridge.omega.size),
            "rms_residual_rad_per_s": self.rms_residual,
            "k_range_rad_per_m": list(self.k_range),
            "free": list(self.free),
            "correlation": self.correlation.tolist(),
        }


def _k(wavenumber: float) -> str:
    """A wavenumber in rad/m for a message: whole numbers from 100 up (``24890``, not
    ``2.489e+04``)."""
    return f"{wavenumber:.0f}" if abs(wavenumber) >= 100 else f"{wavenumber:.3g}"


def _parse_hold(hold: Iterable[str]) -> tuple[str, ...]:
    names = tuple(dict.fromkeys(h.strip().lower() for h in hold if h.strip()))
    aliases = {"d": "depth", "u": "flow", "surface_tension": "sigma"}
    names = tuple(aliases.get(n, n) for n in names)
    unknown = [n for n in names if n not in PARAMETERS]
    if unknown:
        raise InputError(
            f"cannot hold {', '.join(unknown)}: the parameters are {', '.join(PARAMETERS)}"
        )
    if len(set(names)) == len(PARAMETERS):
        raise InputError("every parameter is held: nothing to fit")
    return names


def check_fit_settings(hold: Iterable[str], depth: float, fluid: Fluid) -> tuple[str, ...]:
    """Check a dispersion fit's settings before any spectrum is made; return the held names.

    Raises
    ------
    InputError
        An unknown or every parameter held, a depth that is not positive, or no starting
        surface tension where it is fitted.
    """
    held = _parse_hold(hold)
    if not (math.isfinite(depth) and depth > 0):
        raise InputError(f"the depth must be positive, got {depth!r} m")
    if fluid.surface_tension <= 0 and "sigma" not in held:
        raise InputError("the surface tension's starting value must be positive")
    return held


def _fit_once(
    ridge: Ridge,
    start: dict[str, float],
    held: tuple[str, ...],
    fluid: Fluid,
    robust: float = 0.0,
) -> tuple[dict[str, float], np.ndarray, tuple[str, ...], np.ndarray]:
    """One least-squares fit; return the values, covariance (free), free names, residuals.

    ``robust`` > 0: a soft-L1 loss of that scale (rad/s), for a first fit among outliers.
    """
    free = tuple(
        n
        for n in ("sigma", "depth", "flow_x", "flow_y")
        if (n if not n.startswith("flow") else "flow") not in held
    )
    values = dict(start)

    def unpack(x: np.ndarray) -> dict[str, float]:
        out = dict(values)
        for name, v in zip(free, x, strict=True):
            out[name] = math.exp(v) if name in ("sigma", "depth") else float(v)
        return out

    def residuals(x: np.ndarray) -> np.ndarray:
        p = unpack(x)
        model = wave_omega(
            ridge.kx,
            ridge.ky,
            surface_tension=p["sigma"],
            depth=p["depth"],
            flow=(p["flow_x"], p["flow_y"]),
            fluid=fluid,
        )
        return np.asarray(ridge.omega - model)

    if not free:
        return values, np.zeros((0, 0)), free, residuals(np.zeros(0))
    x0 = np.array(
        [math.log(values[n]) if n in ("sigma", "depth") else values[n] for n in free], float
    )
    bounds_low = [
        {"sigma": math.log(SIGMA_BOUNDS[0]), "depth": math.log(DEPTH_BOUNDS[0])}.get(n, -np.inf)
        for n in free
    ]
    bounds_high = [
        {"sigma": math.log(SIGMA_BOUNDS[1]), "depth": math.log(DEPTH_BOUNDS[1])}.get(n, np.inf)
        for n in free
    ]
    x0 = np.clip(x0, np.array(bounds_low) + 1e-9, np.array(bounds_high) - 1e-9)
    result = least_squares(
        residuals,
        x0,
        bounds=(bounds_low, bounds_high),
        x_scale="jac",
        loss="soft_l1" if robust > 0 else "linear",
        f_scale=robust if robust > 0 else 1.0,
    )
    if not result.success:
        raise InputError(f"the dispersion fit did not converge ({result.message})")
    for name, v, lo, hi in zip(free, result.x, bounds_low, bounds_high, strict=True):
        if v - lo < 1e-6 or hi - v < 1e-6:
            hint = (
                "the waves do not feel the bottom (k d > 3 for every k fitted): hold it"
                if name == "depth"
                else "check the fluid and the maps"
            )
            raise InputError(
                f"the dispersion fit did not converge: the {name} ran to its bound; {hint}"
            )
    return unpack(result.x), _covariance(result.jac, result.fun), free, result.fun


def _covariance(jac: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """The parameters' covariance, the residual variance times ``(J' J)^-1``."""
    n, p = jac.shape
    try:
        return np.asarray(np.linalg.inv(jac.T @ jac) * float(np.sum(residual**2)) / max(n - p, 1))
    except np.linalg.LinAlgError:
        return np.full((p, p), np.nan)


def _depth_bounded(
    ridge: Ridge,
    values: dict[str, float],
    held: tuple[str, ...],
    fluid: Fluid,
    residual: np.ndarray,
) -> bool:
    """True when ten times the fitted depth fits worse by :data:`DEPTH_CHI2` in chi^2."""
    deeper = dict(values, depth=min(10.0 * values["depth"], DEPTH_BOUNDS[1] * 0.99))
    try:
        _, _, _, other = _fit_once(ridge, deeper, (*held, "depth"), fluid)
    except InputError:
        return True
    rss, n = float(np.sum(residual**2)), residual.size
    variance = rss / max(n - 4, 1)
    return float(np.sum(other**2)) - rss > DEPTH_CHI2 * variance


def _sharp_cells(ridge: Ridge, least: int) -> Ridge:
    """The ridge's sharp cells, if they are :data:`SHARP_SHARE` of them and ``least``."""
    sharp = int(np.count_nonzero(ridge.sharp))
    if sharp >= least and sharp >= SHARP_SHARE * ridge.omega.size:
        return ridge.select(ridge.sharp)
    return ridge


def fit_dispersion(
    spectrum: OmegaKSpectrum,
    fluid: Fluid | None = None,
    *,
    depth: float = 5e-3,
    flow: tuple[float, float] = (0.0, 0.0),
    hold: Iterable[str] = (),
    k_min: float | None = None,
    k_max: float | None = None,
    min_contrast: float = 10.0,
) -> DispersionFit:
    """Fit surface tension, depth and a uniform flow to the ridge of an omega-k spectrum.

    Parameters
    ----------
    spectrum : OmegaKSpectrum
    fluid : Fluid, optional
        Density, gravity and the starting (or held) surface tension; water by default.
    depth : float
        Starting (or held) depth, m.
    flow : (float, float)
        Starting (or held) flow ``(Ux, Uy)``, m/s.
    hold : iterable of str
        Parameters held at their given values: ``sigma``, ``depth``, ``flow``.
    k_min, k_max : float, optional
        Wavenumbers fitted, rad/m (defaults: :data:`FIRST_STEPS` wave-vector steps, and
        the cut-off).
    min_contrast : float
        Least ratio of a cell's peak power to its median power (raised to what noise
        alone reaches with few segments, :func:`~holoview.processing.waves.ridge.noise_contrast`).

    Returns
    -------
    DispersionFit

    Raises
    ------
    InputError
        Too few cells with a clear ridge, a parameter that runs to its bound or
        cannot be determined (infinite error), or a fit that does not converge.
    """
    fluid = fluid or Fluid()
    held = check_fit_settings(hold, depth, fluid)
    low = FIRST_STEPS * max(spectrum.dk) if k_min is None else float(k_min)
    high = spectrum.k_cut if k_max is None else min(float(k_max), spectrum.k_cut)
    if not 0 <= low < high:
        why = ""
        if k_min is None and high <= low:  # the field is too small for the window's band
            why = (
                f": the maps' cut-off {_k(spectrum.k_cut)} rad/m is not above the first "
                f"wavenumber fitted, {FIRST_STEPS:g} steps of the field's "
                f"{_k(max(spectrum.dk))} rad/m"
            )
        raise InputError(f"no wavenumbers to fit between {_k(low)} and {_k(high)} rad/m{why}")
    values = {
        "sigma": fluid.surface_tension,
        "depth": float(depth),
        "flow_x": float(flow[0]),
        "flow_y": float(flow[1]),
    }
    kyy, kxx = np.meshgrid(spectrum.ky, spectrum.kx, indexing="ij")
    step = 2.0 * np.pi * spectrum.df
    chance = noise_contrast(spectrum, low, high)
    contrast = max(min_contrast, chance)
    model = None
    n_free = 4 - ("sigma" in held) - ("depth" in held) - 2 * ("flow" in held)
    for search in (None, 0.15, 0.08):
        if search is not None:
            model = wave_omega(
                kxx,
                kyy,
                surface_tension=values["sigma"],
                depth=values["depth"],
                flow=(values["flow_x"], values["flow_y"]),
                fluid=fluid,
            )
        found = find_ridge(
            spectrum,
            model,
            k_min=low,
            k_max=high,
            search=search or 0.0,
            min_contrast=contrast,
        )
        ridge = _sharp_cells(found, max(3 * n_free, 8))
        if search is None and ridge.omega.size:
            # first fit on the clear waves: leakage of strong lines shows as weak peaks
            bright = max(contrast, FIRST_CONTRAST * float(np.percentile(ridge.contrast, 90)))
            if np.count_nonzero(ridge.contrast >= bright) >= max(3 * n_free, 8):
                ridge = ridge.select(ridge.contrast >= bright)
        if ridge.omega.size < max(3 * n_free, 8):
            seldom = ""
            if chance > min_contrast:
                n = spectrum.segments
                seldom = f", which noise alone seldom reaches in {n} segment{'s' * (n != 1)}"
            raise InputError(
                f"the dispersion fit has {ridge.omega.size} cell{'s' * (ridge.omega.size != 1)} "
                "with a clear wave between "
                f"{_k(low)} and {_k(high)} rad/m ({contrast:.3g} times over the median "
                f"power{seldom}); too few: the maps show no waves there"
            )
        robust = 2.0 * step if search is None else 0.0
        values, covariance, free, residual = _fit_once(ridge, values, held, fluid, robust)
        spread = 1.4826 * float(np.median(np.abs(residual - np.median(residual))))
        outliers = np.abs(residual) > 4.0 * max(spread, 1e-12)
        if np.any(outliers) and np.count_nonzero(~outliers) >= max(3 * n_free, 8):
            ridge = ridge.select(~outliers)
            values, covariance, free, residual = _fit_once(ridge, values, held, fluid)
    errors = np.sqrt(np.diag(covariance))
    stderr = dict(zip(free, errors, strict=True))
    if "depth" in stderr and not (
        math.isfinite(stderr["depth"]) and _depth_bounded(ridge, values, held, fluid, residual)
    ):
        first = float(np.min(np.hypot(ridge.kx, ridge.ky)))
        blended = np.hypot(found.kx, found.ky)[~found.sharp]
        longer = ""
        # the blends were left out (every cell fitted is sharp), longer waves among them
        if np.all(ridge.sharp) and np.min(blended, initial=first) < first:
            longer = (
                f"; the lines of longer ones, from {_k(float(np.min(blended)))} rad/m, blend "
                "with their neighbours' and are left out"
            )
        raise InputError(
            "the dispersion fit did not converge: the depth is not determined by these waves "
            f"(ten times deeper fits as well: the longest waves fitted, {_k(first)} rad/m, "
            f"feel a bottom deeper than {1e3 / first:.2g} mm little{longer}); hold it at a "
            "known depth, or fit longer waves (--k-range, a wider field)"
        )
    if not np.all(np.isfinite(errors)):
        raise InputError(
            "the dispersion fit did not converge: the parameters "
            f"({', '.join(free)}) are not all determined by these waves; hold some"
        )
    for name in ("sigma", "depth"):
        if stderr.get(name, 0.0) > 1.0:  # errors of logarithms: relative errors
            hint = (
                "the waves do not feel the bottom (k d > 3): hold it with a known depth"
                if name == "depth"
                else "hold it"
            )
            raise InputError(
                f"the dispersion fit did not converge: the {name} is not determined by these "
                f"waves (its error exceeds its value); {hint}"
            )
    sigma_err = values["sigma"] * stderr.get("sigma", 0.0)
    depth_err = values["depth"] * stderr.get("depth", 0.0)
    outer = np.outer(errors, errors)
    correlation = covariance / np.where(outer > 0, outer, 1.0)
    fit = DispersionFit(
        surface_tension=values["sigma"],
        surface_tension_stderr=sigma_err,
        depth=values["depth"],
        depth_stderr=depth_err,
        flow=(values["flow_x"], values["flow_y"]),
        flow_stderr=(stderr.get("flow_x", 0.0), stderr.get("flow_y", 0.0)),
        held=held,
        fluid=fluid,
        ridge=ridge,
        rms_residual=float(np.sqrt(np.mean(residual**2))),
        k_range=(low, high),
        correlation=correlation,
        free=free,
    )
    logger.info(
        "dispersion fit over %d cells: sigma %.4g +- %.2g N/m, depth %.4g +- %.2g m, "
        "U (%.4g, %.4g) +- (%.2g, %.2g) m/s",
        ridge.omega.size,
        fit.surface_tension,
        fit.surface_tension_stderr,
        fit.depth,
        fit.depth_stderr,
        *fit.flow,
        *fit.flow_stderr,
    )
    return fit
