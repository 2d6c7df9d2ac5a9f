"""The optical bench: a validated, immutable description of a multiplexed DH setup.

A Michelson interferometer (paper, section 2 and supplement I): a reference arm R
reflected by the mirror M_r, and a probe arm that meets a fluid surface z = h above a
submerged mirror M_b. All quantities are SI (metres, radians); tilts are the small
angles of the mirror normals, ``m = (m_x, m_y)`` with ``x`` along camera columns and
``y`` along camera rows, both on the object plane.

Geometry and sign conventions used throughout :mod:`holoview.optics`:

- the submerged mirror is the plane ``z = -m_b . r``; the fluid surface at rest is
  ``z = depth``, perturbed by ``h(r)`` (so the fluid thickness is
  ``depth + h + m_b . r``);
- the reference mirror sits ``delta_H`` further from the beam splitter than the rest
  surface (the paper's arm-length difference ``H_R - H``), tilted by ``m_r``;
- the camera images the plane of the rest surface, with ``pixel_pitch`` metres per
  pixel on that plane; pixel ``(row, col)`` sits at
  ``x = (col - (cols - 1) / 2) * pixel_pitch``, ``y = (row - (rows - 1) / 2) * pixel_pitch``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

from holoview.errors import InputError, finite_number

#: Refractive indices near 532-589 nm, room temperature. Water and isopropanol are the
#: paper's values (section 4.2); air is 1.000293 (standard air at 589 nm); ethanol
#: 1.361 and glycerol 1.473 are handbook values at 589 nm, 20 degC.
FLUIDS: dict[str, float] = {
    "vacuum": 1.0,
    "air": 1.000293,
    "water": 1.333,
    "ethanol": 1.361,
    "isopropanol": 1.377,
    "glycerol": 1.473,
}

#: Largest mirror tilt, rad, for which the small-angle model of the paper holds well.
MAX_TILT = 0.05

#: Most photons per pixel and frame a simulated camera takes (full wells hold about 1e5;
#: numpy's Poisson sampler fails near 1e19).
MAX_PHOTONS = 1e12

#: Beam-splitter ghosts copy one of these arms.
GHOST_ARMS = ("reference", "probe")


#: Plausible ranges of the physical parameters, SI: a laser from the deep UV to the far
#: infrared; an object-side pixel from a microscope's to a demagnifying telescope's;
#: refractive indices of gases and liquids.
PLAUSIBLE_RANGES: dict[str, tuple[float, float]] = {
    "wavelength_m": (100e-9, 20e-6),
    "pixel_pitch_m": (10e-9, 10e-3),
    "n1": (1.0, 3.0),
    "n2": (1.0, 3.0),
}

_WHAT = {
    "wavelength_m": "laser wavelength (100 nm to 20 um)",
    "pixel_pitch_m": "object-side pixel pitch (10 nm to 10 mm)",
}
_UNIT_WORDS = {1.0: "metres", 1e-3: "millimetres", 1e-6: "micrometres", 1e-9: "nanometres"}
#: Typical values (m): a misplaced length is taken for the unit that comes closest to them.
_TYPICAL = {"wavelength_m": 600e-9, "pixel_pitch_m": 10e-6}


def _unit_hint(name: str, typed: float, factor: float, label: str) -> str:
    """``"; 532 looks like nanometres: ..."``: the unit bringing ``typed`` nearest to usual."""
    low, high = PLAUSIBLE_RANGES[name]
    fits = [unit for unit in _UNIT_WORDS if unit != factor and low <= typed * unit <= high]
    if not fits:
        return ""
    unit = min(fits, key=lambda u: abs(math.log10(typed * u / _TYPICAL[name])))
    return (
        f"; {typed:g} looks like {_UNIT_WORDS[unit]}: {label} takes "
        f"{_UNIT_WORDS.get(factor, 'its own unit')}, so give {typed * unit / factor:.4g}"
    )


def check_optics(
    *,
    wavelength_m: float | None = None,
    pixel_pitch_m: float | None = None,
    n1: float | None = None,
    n2: float | None = None,
    names: Mapping[str, tuple[str, float]] | None = None,
) -> None:
    """Refuse a physical parameter that is not plausible, with a hint about units.

    The one check of the setup's physical parameters: the simulator's :class:`Setup`,
    ``holoview record``, ``holoview simulate`` and ``holoview process`` (and the
    experiment settings) all call it. None means "not given" and is not checked.

    Parameters
    ----------
    wavelength_m : float, optional
        Laser wavelength in vacuum, m.
    pixel_pitch_m : float, optional
        Object-side pixel pitch, m.
    n1, n2 : float, optional
        Refractive indices above the surface and of the fluid; ``n2 > n1``.
    names : mapping, optional
        For messages: per parameter (``"wavelength_m"``, ...), the name the user gave
        it under and the factor from its unit to SI, e.g.
        ``{"wavelength_m": ("--wavelength-nm", 1e-9)}`` (default: the parameter's own
        name, in SI).

    Raises
    ------
    InputError
        One line naming the parameter: not a number, not finite, not positive, out of
        :data:`PLAUSIBLE_RANGES` (saying which unit the value looks like), or
        ``n2 <= n1``.

    Examples
    --------
    >>> try:
    ...     check_optics(wavelength_m=532, names={"wavelength_m": ("--wavelength", 1.0)})
    ... except InputError as error:
    ...     print(error)  # doctest: +NORMALIZE_WHITESPACE
    --wavelength 532: 532 m is not a plausible laser wavelength (100 nm to 20 um);
    532 looks like nanometres: --wavelength takes metres, so give 5.32e-07
    """
    given = {"wavelength_m": wavelength_m, "pixel_pitch_m": pixel_pitch_m, "n1": n1, "n2": n2}
    labels = dict(names or {})
    label = {name: labels.get(name, (name, 1.0))[0] for name in given}
    values: dict[str, float] = {}
    for name, raw in given.items():
        if raw is None:
            continue
        factor = labels.get(name, (name, 1.0))[1]
        value = finite_number(label[name], raw)
        values[name] = value
        if name in _WHAT:
            typed = value / factor
            if value <= 0:
                raise InputError(f"{label[name]} must be positive, got {typed:g}")
            low, high = PLAUSIBLE_RANGES[name]
            if not low <= value <= high:
                raise InputError(
                    f"{label[name]} {typed:g}: {value:.3g} m is not a plausible {_WHAT[name]}"
                    + _unit_hint(name, typed, factor, label[name])
                )
    if "n1" in values and "n2" in values and not values["n2"] > values["n1"]:
        raise InputError(
            f"{label['n2']} = {values['n2']:g} must be above n1 = {values['n1']:g}: "
            "the model needs a fluid denser than the medium above it"
        )
    for name in ("n1", "n2"):
        low, high = PLAUSIBLE_RANGES[name]
        if name in values and values[name] < low:
            raise InputError(f"{label[name]} {values[name]:g}: a refractive index is at least 1")
        if name in values and values[name] > high:
            raise InputError(
                f"{label[name]} {values[name]:g} is not a plausible refractive index (1 to 3)"
            )


def _positive(name: str, value: float, unit: str = "") -> float:
    number = finite_number(name, value)
    if number <= 0:
        raise InputError(f"{name} must be positive, got {number:g}{unit}")
    return number


def _tilt(name: str, value: Any) -> tuple[float, float]:
    """Return a tilt as a 2-tuple of finite floats, rad, within the small-angle range."""
    try:
        mx, my = value
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a pair (m_x, m_y) in rad, got {value!r}") from exc
    tilt = (finite_number(f"{name}[0]", mx), finite_number(f"{name}[1]", my))
    if max(abs(tilt[0]), abs(tilt[1])) > MAX_TILT:
        raise InputError(
            f"{name} = ({tilt[0]:.3g}, {tilt[1]:.3g}) rad is beyond the small-angle model "
            f"(|m| <= {MAX_TILT} rad)"
        )
    return tilt


@dataclass(frozen=True)
class Ghost:
    """A beam-splitter ghost: a weak, tilted copy of one arm's field.

    Parameters
    ----------
    arm : {"reference", "probe"}
        The arm whose field is copied (the probe copy holds F and every B_j).
    tilt : tuple of float
        Extra tilt of the copy, rad, as an equivalent mirror tilt: a reference ghost
        behaves as if M_r were tilted by ``m_r + tilt``.
    amplitude : float
        Field amplitude of the copy relative to the arm's own field, in (0, 1).
    """

    arm: str = "reference"
    tilt: tuple[float, float] = (0.0, 0.0)
    amplitude: float = 0.05

    def __post_init__(self) -> None:
        if self.arm not in GHOST_ARMS:
            raise InputError(f"ghost arm must be one of {GHOST_ARMS}, got {self.arm!r}")
        object.__setattr__(self, "tilt", _tilt("ghost tilt", self.tilt))
        amplitude = finite_number("ghost amplitude", self.amplitude)
        if not 0 < amplitude < 1:
            raise InputError(f"ghost amplitude must be in (0, 1), got {amplitude:g}")
        object.__setattr__(self, "amplitude", amplitude)


@dataclass(frozen=True)
class Setup:
    """Everything the forward model needs to know about the bench and the camera.

    Parameters
    ----------
    wavelength : float
        Vacuum wavelength of the laser, m.
    n1, n2 : float
        Refractive indices above the surface (air) and of the fluid; ``n2 > n1``.
    m_r, m_b : tuple of float
        Tilts of the reference and the submerged mirror, rad.
    delta_H : float
        Arm-length difference ``H_R - H``, m.
    depth : float
        Fluid depth over the submerged mirror at rest, m.
    mirror_reflectivity : float
        Power reflectance of the submerged mirror, in [0, 1] (1: lossless).
    ghosts : tuple of Ghost
        Beam-splitter ghost reflections.
    pixel_pitch : float
        Object-side pixel pitch (camera pitch divided by the magnification), m.
    shape : tuple of int
        Frame size ``(rows, cols)``, pixels.
    beam_waist : float or None
        1/e^2 intensity radius of the Gaussian illumination on the object plane, m
        (``None``: uniform illumination).
    aperture_radius : float or None
        Radius of a circular field stop on the object plane, m (``None``: none).
    photons_per_pixel : float
        Mean photon count per pixel and frame at the beam centre, photons.
    bit_depth : int
        Camera bits per pixel, 1 to 16.
    gamma : float
        Camera response exponent: value ~ (photons / saturation) ** gamma.
    saturation : float
        Photon count mapped to the camera's top value (full well), photons.

    Raises
    ------
    InputError
        A parameter is not finite or out of range (the message names it), ``n2`` does
        not exceed ``n1``, or a tilt puts RF, RB1 or FB1 past Nyquist.
    """

    wavelength: float = 532e-9
    n1: float = FLUIDS["air"]
    n2: float = FLUIDS["water"]
    m_r: tuple[float, float] = (2.0e-3, 1.2e-3)
    m_b: tuple[float, float] = (-0.5e-3, 1.5e-3)
    delta_H: float = 0.0
    depth: float = 5e-3
    mirror_reflectivity: float = 0.85
    ghosts: tuple[Ghost, ...] = ()
    pixel_pitch: float = 20e-6
    shape: tuple[int, int] = (1024, 1024)
    beam_waist: float | None = None
    aperture_radius: float | None = None
    photons_per_pixel: float = 800.0
    bit_depth: int = 12
    gamma: float = 1.0
    saturation: float = 4000.0

    def __post_init__(self) -> None:
        put = object.__setattr__
        put(self, "wavelength", _positive("wavelength", self.wavelength, " m"))
        put(self, "n1", _positive("n1", self.n1))
        put(self, "n2", _positive("n2", self.n2))
        put(self, "pixel_pitch", _positive("pixel_pitch", self.pixel_pitch, " m"))
        check_optics(
            wavelength_m=self.wavelength,
            pixel_pitch_m=self.pixel_pitch,
            n1=self.n1,
            n2=self.n2,
            names={"wavelength_m": ("wavelength", 1.0), "pixel_pitch_m": ("pixel_pitch", 1.0)},
        )
        put(self, "m_r", _tilt("m_r", self.m_r))
        put(self, "m_b", _tilt("m_b", self.m_b))
        put(self, "delta_H", finite_number("delta_H", self.delta_H))
        put(self, "depth", _positive("depth", self.depth, " m"))
        reflectivity = finite_number("mirror_reflectivity", self.mirror_reflectivity)
        if not 0 <= reflectivity <= 1:
            raise InputError(f"mirror_reflectivity must be in [0, 1], got {reflectivity:g}")
        put(self, "mirror_reflectivity", reflectivity)
        ghosts = tuple(self.ghosts)
        for ghost in ghosts:
            if not isinstance(ghost, Ghost):
                raise InputError(f"ghosts must be Ghost instances, got {ghost!r}")
        put(self, "ghosts", ghosts)
        try:
            rows, cols = (int(n) for n in self.shape)
        except (TypeError, ValueError) as exc:
            raise InputError(f"shape must be (rows, cols), got {self.shape!r}") from exc
        if rows < 2 or cols < 2:
            raise InputError(f"shape must be at least (2, 2) pixels, got ({rows}, {cols})")
        put(self, "shape", (rows, cols))
        for name in ("beam_waist", "aperture_radius"):
            value = getattr(self, name)
            if value is not None:
                put(self, name, _positive(name, value, " m"))
        for name in ("photons_per_pixel", "saturation"):
            photons = _positive(name, getattr(self, name), " photons")
            if photons > MAX_PHOTONS:
                raise InputError(
                    f"{name} = {photons:g} photons is beyond any camera (at most {MAX_PHOTONS:g})"
                )
            put(self, name, photons)
        bits = self.bit_depth
        if isinstance(bits, bool) or not isinstance(bits, int) or not 1 <= bits <= 16:
            raise InputError(f"bit_depth must be an integer from 1 to 16, got {bits!r}")
        put(self, "gamma", _positive("gamma", self.gamma))
        self._check_nyquist()

    def _check_nyquist(self) -> None:
        """Raise InputError when RF, RB1 or FB1 (or a ghost copy of RF) aliases."""
        scale = 2 * self.pixel_pitch / self.wavelength
        rf = tuple(scale * self.n1 * m for m in self.m_r)
        fb1 = tuple(scale * self.n2 * m for m in self.m_b)
        rb1 = (fb1[0] - rf[0], fb1[1] - rf[1])
        for label, carrier, culprit in (
            ("RF", rf, "m_r"),
            ("FB1", fb1, "m_b"),
            ("RB1", rb1, "m_r and m_b"),
        ):
            if max(abs(carrier[0]), abs(carrier[1])) >= 0.5:
                raise InputError(
                    f"{culprit}: the {label} carrier ({carrier[0]:+.3f}, {carrier[1]:+.3f}) "
                    "cycles/pixel is past Nyquist (|f| < 0.5 per axis); reduce the tilt or "
                    "the pixel pitch"
                )

    @property
    def surface_reflection(self) -> float:
        """Fresnel amplitude reflection coefficient ``R = (n2 - n1) / (n2 + n1)``."""
        return (self.n2 - self.n1) / (self.n2 + self.n1)

    @property
    def max_value(self) -> int:
        """The camera's top raw value, ``2 ** bit_depth - 1``."""
        return (1 << self.bit_depth) - 1

    def replace(self, **changes: Any) -> Setup:
        """Return a copy with ``changes`` applied (validated again)."""
        values = {f.name: getattr(self, f.name) for f in fields(self) if f.init}
        values.update(changes)
        return Setup(**values)

    def as_attributes(self) -> dict[str, object]:
        """Return the setup as flat attributes for a recording, names carrying units.

        Lengths end in ``_m``; tilts in ``_rad`` (a ``(value, "rad")`` pair); ghosts are
        flattened as ``ghost{i}_arm``, ``ghost{i}_tilt_rad``, ``ghost{i}_amplitude``.
        """
        attrs: dict[str, object] = {
            "wavelength_m": self.wavelength,
            "n1": self.n1,
            "n2": self.n2,
            "m_r_rad": (list(self.m_r), "rad"),
            "m_b_rad": (list(self.m_b), "rad"),
            "delta_H_m": self.delta_H,
            "depth_m": self.depth,
            "mirror_reflectivity": self.mirror_reflectivity,
            "pixel_pitch_m": self.pixel_pitch,
            "shape_px": list(self.shape),
            "beam_waist_m": self.beam_waist,
            "aperture_radius_m": self.aperture_radius,
            "photons_per_pixel": (self.photons_per_pixel, "photons"),
            "bit_depth": self.bit_depth,
            "gamma": self.gamma,
            "saturation": (self.saturation, "photons"),
        }
        for i, ghost in enumerate(self.ghosts):
            attrs[f"ghost{i}_arm"] = ghost.arm
            attrs[f"ghost{i}_tilt_rad"] = (list(ghost.tilt), "rad")
            attrs[f"ghost{i}_amplitude"] = ghost.amplitude
        return attrs

    def to_dict(self) -> dict[str, Any]:
        """Return the constructor arguments as plain Python values (ghosts as dicts)."""
        values = {f.name: getattr(self, f.name) for f in fields(self) if f.init}
        values["ghosts"] = [asdict(g) for g in self.ghosts]
        return values

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> Setup:
        """Build a setup from :meth:`to_dict` output (unknown keys are an InputError)."""
        known = {f.name for f in fields(cls) if f.init}
        unknown = sorted(set(values) - known)
        if unknown:
            raise InputError(f"unknown setup parameter(s): {', '.join(unknown)}")
        args = dict(values)
        if "ghosts" in args:
            args["ghosts"] = tuple(
                g if isinstance(g, Ghost) else Ghost(**g) for g in args["ghosts"] or ()
            )
        for name in ("m_r", "m_b", "shape"):
            if name in args:
                args[name] = tuple(args[name])
        return cls(**args)
