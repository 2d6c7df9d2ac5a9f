"""Numerical phase tracing (supplement, section II): rays through the real geometry.

A mesh of rays, one per pixel (plus a margin wide enough for the walk-off), starts
on the plane ``z0`` above the fluid going straight down, with phase 0 and amplitude
the illumination's. Vectorised over all live rays, each step moves every ray to its
next surface:

- in air going down: the fluid surface ``z = depth + h(x, y)`` (Newton's method on
  the ray parameter, surface gradient by central differences). The ray splits: the
  reflected copy (Fresnel ``r``, s polarisation, at the local angle) goes back up as
  an F ray; the refracted one (Snell's law, Fresnel ``t``) enters the fluid;
- in the fluid going down: the submerged mirror ``z = -m_b . r``; reflection times
  ``sqrt(mirror_reflectivity)``, and the ray's pass count ``j`` grows by one;
- in the fluid going up: the surface from below; the refracted copy leaves as a B_j
  ray, the reflected one goes down again;
- in air going up: to ``z0``, where it stops.

Every path length ``L`` adds ``k0 n L`` to the phase. A ray whose amplitude falls
under ``threshold`` (5e-4, the supplement's value) is discarded. The reference arm
is the same walk to its mirror ``z = depth - delta_H - m_r . r`` and back, in air.

The camera images the rest surface ``z = depth``: rays are taken back (virtually,
in air) from ``z0`` to that plane, and each family (R, F, B_j) is interpolated from
its exit points to the pixel grid: the exit points of one family are a smooth
deformation of the regular start mesh, so the start coordinates that land on a pixel
are found by a few fixed-point steps of bilinear interpolation
(:func:`scipy.ndimage.map_coordinates`), and the phase (kept unwrapped, float64) and
amplitude are interpolated there. The camera then samples Poisson counts of
``photons_per_pixel |sum of fields|**2`` (normalised like the fast synthesiser) and
applies its response (:mod:`holoview.optics.camera`).

Beam-splitter ghosts are not traced: a ghost copies an arm's traced field with its
extra tilt and amplitude.

Cost: about 6 surface hits per start ray for water (F, then B1..B4 leaving; B5 falls
under the threshold), each hit about 10 evaluations of ``h`` (Newton steps with a
central-difference gradient until within 1e-14 m, usually 2), so the surface
function dominates.
Measured (``benchmarks/bench_synthesis.py``, 2-core EPYC, six-mode standing waves):
about 1.5 s at 256 x 256 (0.9 million rays) and 15-20 s at 1024 x 1024 (12 million
rays), some 300-500x the fast synthesis; a uniform level takes about half as long
(0.8 s at 256 x 256). Memory is about 1 kB per live ray. Use it to check the fast
synthesiser, not to make data.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from holoview.errors import InputError
from holoview.optics.beams import DEFAULT_THRESHOLD, field_beams, mean_intensity
from holoview.optics.camera import Camera
from holoview.optics.setup import Setup
from holoview.optics.synthesis import field_stop, illumination, pixel_coordinates

#: A surface for the tracer: h(x, y) in metres at a fixed time, or a uniform level.
TraceSurface = Callable[[np.ndarray, np.ndarray], np.ndarray] | float

#: Most Newton iterations for a ray-surface intersection.
_NEWTON_STEPS = 6

#: Distance from the surface, m, at which a ray's hit counts as found (1e-6 rad of phase).
_NEWTON_TOLERANCE = 1e-14

#: Fixed-point iterations inverting a family's exit mapping.
_INVERT_STEPS = 4

#: Height of the start plane over the highest surface point, m.
_CLEARANCE = 1e-4


@dataclass(frozen=True)
class TraceResult:
    """What :func:`trace_fields` found.

    Attributes
    ----------
    fields : dict of str to ndarray
        Complex field (relative to the incident one) of each family on the pixel grid,
        keyed ``"R"``, ``"F"``, ``"B1"``, ... and ghost copies (``"R~g0"``, ``"F~g1"``).
    intensity : ndarray of float64
        Expected photons per pixel, ``photons_per_pixel |sum|**2 / sum_b a_b**2``.
    rays : int
        Rays created in all (start rays and their duplicates), both arms.
    passes : int
        Largest number of submerged-mirror reflections of a ray that reached the camera.
    """

    fields: dict[str, np.ndarray]
    intensity: np.ndarray
    rays: int
    passes: int


@dataclass
class _Rays:
    """A batch of rays (structure of arrays), positions and directions in metres."""

    pos: np.ndarray  # (n, 3)
    dir: np.ndarray  # (n, 3), unit
    phase: np.ndarray  # (n,), rad
    amp: np.ndarray  # (n,)
    start: np.ndarray  # (n,), index into the start mesh
    passes: np.ndarray  # (n,), submerged-mirror reflections

    def take(self, mask: np.ndarray) -> _Rays:
        return _Rays(
            self.pos[mask],
            self.dir[mask],
            self.phase[mask],
            self.amp[mask],
            self.start[mask],
            self.passes[mask],
        )

    @staticmethod
    def join(parts: list[_Rays]) -> _Rays:
        return _Rays(
            np.concatenate([p.pos for p in parts]),
            np.concatenate([p.dir for p in parts]),
            np.concatenate([p.phase for p in parts]),
            np.concatenate([p.amp for p in parts]),
            np.concatenate([p.start for p in parts]),
            np.concatenate([p.passes for p in parts]),
        )

    def __len__(self) -> int:
        return len(self.amp)


class _Surface:
    """The fluid surface ``z = depth + h(x, y)`` with its gradient."""

    def __init__(self, surface: TraceSurface, depth: float, step: float) -> None:
        self.depth = depth
        self.step = step
        if callable(surface):
            self.function: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = surface
            self.level = 0.0
        else:
            self.function = None
            self.level = float(surface)
            if not math.isfinite(self.level):
                raise InputError(f"surface level must be finite, got {surface!r} m")

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        if self.function is None:
            return np.full(np.shape(x), self.depth + self.level)
        h = np.asarray(self.function(x, y), dtype=float)
        if h.shape != np.shape(x) or not np.all(np.isfinite(h)):
            raise InputError("the surface returned NaN, infinite or wrongly shaped heights")
        return self.depth + h

    def gradient(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.function is None:
            zero = np.zeros(np.shape(x))
            return zero, zero
        e = self.step
        hx = (self.height(x + e, y) - self.height(x - e, y)) / (2 * e)
        hy = (self.height(x, y + e) - self.height(x, y - e)) / (2 * e)
        return hx, hy

    def intersect(self, rays: _Rays) -> tuple[np.ndarray, np.ndarray]:
        """Return (ray parameter s, upward unit normal at the hit) for every ray.

        Newton's method from the flat-surface guess, until every ray is within
        :data:`_NEWTON_TOLERANCE` of the surface (at most :data:`_NEWTON_STEPS` steps);
        the gradient of the last step is the normal's.
        """
        p, d = rays.pos, rays.dir
        s = (self.height(p[:, 0], p[:, 1]) - p[:, 2]) / d[:, 2]
        for _ in range(_NEWTON_STEPS):
            x, y = p[:, 0] + s * d[:, 0], p[:, 1] + s * d[:, 1]
            hx, hy = self.gradient(x, y)
            if self.function is None:
                break
            f = p[:, 2] + s * d[:, 2] - self.height(x, y)
            if len(f) == 0 or np.max(np.abs(f)) < _NEWTON_TOLERANCE:
                break
            s = s - f / (d[:, 2] - hx * d[:, 0] - hy * d[:, 1])
        normal = np.stack([-hx, -hy, np.ones_like(hx)], axis=1)
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        return s, normal


def _advance(rays: _Rays, s: np.ndarray, k0: float, index: float) -> None:
    """Move rays by ``s`` along their directions in a medium of refractive ``index``."""
    rays.pos = rays.pos + s[:, None] * rays.dir
    rays.phase = rays.phase + k0 * index * s


def _plane_hit(rays: _Rays, z0: float, tilt: tuple[float, float]) -> np.ndarray:
    """Return the ray parameter at the plane ``z = z0 - tilt . r``."""
    p, d = rays.pos, rays.dir
    numerator = z0 - p[:, 2] - tilt[0] * p[:, 0] - tilt[1] * p[:, 1]
    return numerator / (d[:, 2] + tilt[0] * d[:, 0] + tilt[1] * d[:, 1])


def _mirror(rays: _Rays, tilt: tuple[float, float]) -> None:
    """Reflect rays off a plane mirror of normal ``(m_x, m_y, 1)``."""
    normal = np.array([tilt[0], tilt[1], 1.0])
    normal /= np.linalg.norm(normal)
    dot = rays.dir @ normal
    rays.dir = rays.dir - 2 * dot[:, None] * normal[None, :]


def _split(rays: _Rays, normal: np.ndarray, n_from: float, n_to: float) -> tuple[_Rays, _Rays]:
    """Split rays at an interface: return (reflected, refracted) with Fresnel amplitudes.

    ``normal`` is the interface normal on the incident side (pointing against ``dir``).
    s polarisation; total internal reflection gives a zero refracted amplitude.
    """
    d = rays.dir
    cos_i = -np.einsum("ij,ij->i", d, normal)
    eta = n_from / n_to
    radicand = 1 - eta * eta * (1 - cos_i * cos_i)
    total = radicand < 0
    cos_t = np.sqrt(np.where(total, 0.0, radicand))
    denominator = n_from * cos_i + n_to * cos_t
    r = np.where(total, 1.0, (n_from * cos_i - n_to * cos_t) / denominator)
    t = np.where(total, 0.0, 2 * n_from * cos_i / denominator)
    reflected = _Rays(
        rays.pos,
        d + 2 * cos_i[:, None] * normal,
        rays.phase,
        rays.amp * r,
        rays.start,
        rays.passes,
    )
    refracted = _Rays(
        rays.pos.copy(),
        eta * d + (eta * cos_i - cos_t)[:, None] * normal,
        rays.phase.copy(),
        rays.amp * t,
        rays.start,
        rays.passes,
    )
    return reflected, refracted


def _mesh(setup: Setup, margin: int) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """Return start x, y (m, flattened) of a pixel mesh grown by ``margin`` pixels."""
    rows, cols = setup.shape
    p = setup.pixel_pitch
    xs = (np.arange(-margin, cols + margin) - (cols - 1) / 2) * p
    ys = (np.arange(-margin, rows + margin) - (rows - 1) / 2) * p
    x, y = np.meshgrid(xs, ys)
    return x.ravel(), y.ravel(), (len(ys), len(xs))


def _start_rays(x: np.ndarray, y: np.ndarray, z0: float, setup: Setup) -> _Rays:
    n = len(x)
    profile = illumination(setup, x, y)
    amp = np.ones(n) if profile is None else profile.astype(float)
    direction = np.zeros((n, 3))
    direction[:, 2] = -1.0
    return _Rays(
        np.stack([x, y, np.full(n, z0)], axis=1),
        direction,
        np.zeros(n),
        amp,
        np.arange(n),
        np.zeros(n, dtype=np.int64),
    )


def _to_grid(
    setup: Setup,
    done: _Rays,
    mesh_shape: tuple[int, int],
    margin: int,
) -> np.ndarray:
    """Interpolate one family's exit rays (at the image plane) to the pixel grid."""
    size = mesh_shape[0] * mesh_shape[1]
    p = setup.pixel_pitch
    mesh_x, mesh_y, _ = _mesh(setup, margin)
    shift_x = np.median(done.pos[:, 0] - mesh_x[done.start])
    shift_y = np.median(done.pos[:, 1] - mesh_y[done.start])
    exit_x = mesh_x + shift_x
    exit_y = mesh_y + shift_y
    phase = np.zeros(size)
    amp = np.zeros(size)
    exit_x[done.start] = done.pos[:, 0]
    exit_y[done.start] = done.pos[:, 1]
    phase[done.start] = done.phase
    amp[done.start] = done.amp
    if len(done) < size:
        missing = np.ones(size, dtype=bool)
        missing[done.start] = False
        nearest = ndimage.distance_transform_edt(
            missing.reshape(mesh_shape), return_distances=False, return_indices=True
        )
        flat = np.ravel_multi_index(tuple(nearest), mesh_shape).ravel()
        phase[missing] = phase[flat[missing]]
    grids = [a.reshape(mesh_shape) for a in (exit_x, exit_y, phase, amp)]
    px, py = pixel_coordinates(setup)
    target_x = np.broadcast_to(px, setup.shape)
    target_y = np.broadcast_to(py, setup.shape)
    rows, cols = setup.shape
    col = np.broadcast_to(np.arange(cols, dtype=float)[None, :] + margin, setup.shape)
    row = np.broadcast_to(np.arange(rows, dtype=float)[:, None] + margin, setup.shape)
    col = col - shift_x / p
    row = row - shift_y / p
    for _ in range(_INVERT_STEPS):
        coords = np.array([row, col])
        ex = ndimage.map_coordinates(grids[0], coords, order=1, mode="nearest")
        ey = ndimage.map_coordinates(grids[1], coords, order=1, mode="nearest")
        col = col + (target_x - ex) / p
        row = row + (target_y - ey) / p
    coords = np.array([row, col])
    phase_px = ndimage.map_coordinates(grids[2], coords, order=1, mode="nearest")
    amp_px = ndimage.map_coordinates(grids[3], coords, order=1, mode="nearest")
    return amp_px * np.exp(1j * phase_px)


def trace_fields(
    setup: Setup,
    surface: TraceSurface = 0.0,
    *,
    threshold: float = DEFAULT_THRESHOLD,
    reference_phase: float = 0.0,
    max_passes: int = 200,
) -> TraceResult:
    """Trace the probe and reference arms and return every family's field on the pixels.

    Parameters
    ----------
    setup : Setup
        The bench (ghosts are applied as tilted copies of the traced arms).
    surface : callable or float
        ``h(x, y)`` over the rest level, m, for ``x``, ``y`` in m on the object plane
        (fix the time of a :mod:`holoview.optics.surfaces` surface with a lambda), or
        a uniform level, m.
    threshold : float
        Rays whose |amplitude| falls under this are discarded.
    reference_phase : float
        Extra phase of the reference arm, rad.
    max_passes : int
        Safety limit on submerged-mirror reflections.

    Returns
    -------
    TraceResult
    """
    if not (math.isfinite(threshold) and threshold > 0):
        raise InputError(f"threshold must be positive, got {threshold!r}")
    if not math.isfinite(reference_phase):
        raise InputError(f"reference_phase must be finite, got {reference_phase!r} rad")
    k0 = 2 * math.pi / setup.wavelength
    n1, n2 = setup.n1, setup.n2
    # start rays far enough out that every family's exit points cover the frame: the
    # B_j walk-off, and the reference's 2 m_r tilt over its extra arm length
    walk = max(max(abs(b.entry[0]), abs(b.entry[1])) for b in field_beams(setup, threshold))
    walk = max(walk, 2 * max(map(abs, setup.m_r)) * (abs(setup.delta_H) + _CLEARANCE))
    margin = math.ceil(walk / setup.pixel_pitch) + 3
    mesh_x, mesh_y, mesh_shape = _mesh(setup, margin)
    shape = _Surface(surface, setup.depth, setup.pixel_pitch * 1e-2)
    top = float(np.max(shape.height(mesh_x, mesh_y)))
    z0 = max(top, setup.depth) + _CLEARANCE
    rho = math.sqrt(setup.mirror_reflectivity)
    rays_created = len(mesh_x)

    finished: list[_Rays] = []
    down_air = _start_rays(mesh_x, mesh_y, z0, setup)
    s, normal = shape.intersect(down_air)
    _advance(down_air, s, k0, n1)
    f_rays, down_fluid = _split(down_air, normal, n1, n2)
    up_air = [f_rays]
    rays_created += len(f_rays)
    for _ in range(max_passes):
        down_fluid = down_fluid.take(np.abs(down_fluid.amp) >= threshold)
        if len(down_fluid) == 0:
            break
        _advance(down_fluid, _plane_hit(down_fluid, 0.0, setup.m_b), k0, n2)
        _mirror(down_fluid, setup.m_b)
        down_fluid.amp = down_fluid.amp * rho
        down_fluid.passes = down_fluid.passes + 1
        up_fluid = down_fluid.take(np.abs(down_fluid.amp) >= threshold)
        s, normal = shape.intersect(up_fluid)
        _advance(up_fluid, s, k0, n2)
        down_fluid, leaving = _split(up_fluid, -normal, n2, n1)
        up_air.append(leaving)
        rays_created += len(leaving) + len(down_fluid)
    exiting = _Rays.join(up_air)
    exiting = exiting.take(np.abs(exiting.amp) >= threshold)
    _advance(exiting, _plane_hit(exiting, z0, (0.0, 0.0)), k0, n1)
    finished.append(exiting)

    reference = _start_rays(mesh_x, mesh_y, z0, setup)
    _advance(reference, _plane_hit(reference, setup.depth - setup.delta_H, setup.m_r), k0, n1)
    _mirror(reference, setup.m_r)
    _advance(reference, _plane_hit(reference, z0, (0.0, 0.0)), k0, n1)
    reference.phase = reference.phase + reference_phase
    rays_created += len(reference)

    fields: dict[str, np.ndarray] = {}
    image_plane = setup.depth
    for name, batch in [("R", reference), *_families(exiting)]:
        back = _plane_hit(batch, image_plane, (0.0, 0.0))
        _advance(batch, back, k0, n1)
        fields[name] = _to_grid(setup, batch, mesh_shape, margin)
    fields.update(_ghost_fields(setup, fields))

    total = sum(fields.values())
    norm = mean_intensity(field_beams(setup, threshold))
    intensity = setup.photons_per_pixel * np.abs(total) ** 2 / norm
    px, py = pixel_coordinates(setup)
    stop = field_stop(setup, px, py)
    if stop is not None:
        intensity = intensity * stop
    passes = int(exiting.passes.max()) if len(exiting) else 0
    return TraceResult(fields, intensity, rays_created, passes)


def _families(exiting: _Rays) -> list[tuple[str, _Rays]]:
    """Split exiting probe rays into F (no mirror reflection) and B_j."""
    result = []
    for j in np.unique(exiting.passes):
        name = "F" if j == 0 else f"B{int(j)}"
        result.append((name, exiting.take(exiting.passes == j)))
    return result


def _ghost_fields(setup: Setup, fields: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Return the ghost copies: an arm's fields times amplitude and an extra tilt ramp."""
    k2 = 4 * math.pi / setup.wavelength
    px, py = pixel_coordinates(setup)
    copies: dict[str, np.ndarray] = {}
    for index, ghost in enumerate(setup.ghosts):
        ramp = ghost.amplitude * np.exp(
            1j * k2 * setup.n1 * (ghost.tilt[0] * px + ghost.tilt[1] * py)
        )
        names = ["R"] if ghost.arm == "reference" else [n for n in fields if n[0] in "FB"]
        for name in names:
            if "~" not in name:
                copies[f"{name}~g{index}"] = fields[name] * ramp
    return copies


def trace_frame(
    setup: Setup,
    surface: TraceSurface,
    rng: np.random.Generator | None,
    *,
    noise: str = "poisson",
    threshold: float = DEFAULT_THRESHOLD,
    reference_phase: float = 0.0,
) -> np.ndarray:
    """Return a raw camera frame from the phase tracing (Poisson sampling, camera response).

    Parameters are those of :func:`trace_fields`, plus the noise source ``rng`` and
    model ``noise`` (see :mod:`holoview.optics.camera`).
    """
    result = trace_fields(setup, surface, threshold=threshold, reference_phase=reference_phase)
    camera = Camera(setup, noise)
    return camera.expose(result.intensity.astype(np.float32), rng)
