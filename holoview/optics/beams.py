"""The fields that reach the camera: R, F, B_j and ghost copies, with their walk-off.

The general field sum
---------------------
The supplement (eq. 3) gives the beam amplitudes for a perfect submerged mirror. With
a mirror of power reflectance ``R_m`` (amplitude ``rho = sqrt(R_m)``, its reflection
phase taken as zero: a constant per beam that relative and absolute reconstructions
cancel) and the Fresnel coefficients at normal incidence,

- ``r12 = (n1 - n2) / (n1 + n2) = -R`` (air to fluid, from above),
- ``r21 = +R`` (fluid to air, from below),
- ``t12 t21 = 1 - R**2`` (in and out again, the Stokes relation),

the field amplitudes relative to the incident beam (the common beam-splitter factor
dropped, the same for both arms) are ``a_R = 1``, ``a_F = -R`` and

    ``a_Bj = (1 - R**2) rho**j R**(j - 1)``.

Optical paths (supplement eq. 4, signs fixed so that the phase differences are the
paper's eq. 6 exactly): with ``k0 = 2 pi / wavelength``,

- ``phi_R = 2 k0 n1 (delta_H + m_r . r)``,
- ``phi_F = -2 k0 n1 h``,
- ``phi_Bj = -2 k0 n1 h + 2 k0 j n2 (depth + h + m_b . r)``,

so that each beam is ``E_b = a_b P(r + e_b) exp(i [2 k0 g_b . r + c_b + 2 k0 kappa_b h])``
with phase gradient ``g`` (``n1 m_r``, ``0``, ``j n2 m_b``), height coefficient ``kappa``
(``0``, ``-n1``, ``j n2 - n1``) and constant ``c``. The camera records
``|sum_b E_b|**2``; every pair (A, B) contributes ``2 Re(E_A conj(E_B))``, a hologram
with carrier ``2 (g_A - g_B) pixel_pitch / wavelength`` cycles/pixel and prefactor
``alpha = kappa_A - kappa_B``. Summing the fields rather than the families matters:
with ``rho = 1`` the probe arm ``F + sum_j B_j`` is an all-pass etalon and the terms
landing on FB_j cancel exactly; at FB1 the sum over ``F B1, B2 B1, B3 B2, ...`` is

    ``(1 - R**2) rho R (rho**2 - 1) / (1 - rho**2 R**2)``,

which vanishes for ``rho = 1`` and is what :func:`holoview.optics.families.coherent_amplitude`
returns (times 2 over the mean intensity).

Walk-off
--------
The submerged mirror tilts every B_j ray by ``2 m_b`` per reflection inside the fluid:
a ray leaving the surface at ``r`` after ``j`` mirror reflections entered it at
``r - 2 j**2 d m_b`` (``d`` the depth) and was reflected back down by the surface at
``r - 2 (j**2 - k**2) d m_b``, ``k = 1 .. j - 1``. Its height term is the weighted sum
``(n2 - n1)/2 [h(entry) + h(r)] + n2 sum_k h(s_k)`` (weights adding to ``j n2 - n1``).
The fast synthesis samples it at the weighted centroid of those points (first order in
the walk-off, exact for a uniform level and for planar surfaces); the phase tracing of
:mod:`holoview.optics.tracing` follows every pass. The illumination profile of a B_j
beam is the one at its entry point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from holoview.optics.setup import Setup

#: Field amplitude under which a beam is dropped (the supplement's ray threshold).
DEFAULT_THRESHOLD = 5e-4

#: Hard limit on the number of internal passes followed.
MAX_PASSES = 200


@dataclass(frozen=True)
class Beam:
    """One field reaching the camera (see the module docstring for the symbols).

    Attributes
    ----------
    name : str
        ``"R"``, ``"F"``, ``"B1"``, ``"B2"``, ...; a ghost copy adds ``"~g{i}"`` (``"B1~g0"``).
    arm : str
        ``"reference"`` or ``"probe"``.
    passes : int
        Reflections from the submerged mirror (``j`` of B_j; 0 for R and F).
    amplitude : float
        Signed field amplitude relative to the incident beam.
    gradient : tuple of float
        ``g``: the phase is ``2 k0 g . r``; dimensionless (an index times a tilt).
    kappa : float
        Height coefficient: the phase grows by ``2 k0 kappa h``.
    offset : float
        Constant phase, rad.
    centroid : tuple of float
        Where, relative to the pixel, the height term is sampled, m.
    entry : tuple of float
        Where, relative to the pixel, the beam crossed the object plane on its way in, m.
    ghost : int or None
        Index of the ghost in ``setup.ghosts`` this beam is a copy from, or None.
    """

    name: str
    arm: str
    passes: int
    amplitude: float
    gradient: tuple[float, float]
    kappa: float
    offset: float
    centroid: tuple[float, float]
    entry: tuple[float, float]
    ghost: int | None = None

    @property
    def order_key(self) -> tuple[int, int, int]:
        """Sort key for labels: R, then F, then B_j by decreasing j; ghosts after."""
        rank = 0 if self.name.startswith("R") else 1 if self.name.startswith("F") else 2
        ghost = -1 if self.ghost is None else self.ghost
        return (rank, -self.passes, ghost)


def walkoff_weights(setup: Setup, passes: int) -> tuple[list[float], list[float]]:
    """Return the height-sample positions and weights of a B_j beam.

    Parameters
    ----------
    setup : Setup
        The bench.
    passes : int
        ``j``, the number of submerged-mirror reflections (>= 1).

    Returns
    -------
    positions : list of float
        Multiples ``q`` of the vector ``2 d m_b`` (m) at which ``h`` is sampled,
        relative to the exit pixel: ``-j**2`` (entry), ``-(j**2 - k**2)``, and 0 (exit).
    weights : list of float
        The matching weights (they add up to ``j n2 - n1``).
    """
    j = passes
    n1, n2 = setup.n1, setup.n2
    positions = [float(-(j * j)), 0.0]
    weights = [(n2 - n1) / 2, (n2 - n1) / 2]
    for k in range(1, j):
        positions.append(float(-(j * j - k * k)))
        weights.append(n2)
    return positions, weights


def field_beams(
    setup: Setup, threshold: float = DEFAULT_THRESHOLD, max_passes: int | None = None
) -> list[Beam]:
    """Return every beam whose field amplitude reaches ``threshold``.

    Parameters
    ----------
    setup : Setup
        The bench.
    threshold : float
        Smallest |field amplitude| kept, relative to the incident beam.
    max_passes : int, optional
        Largest ``j`` of B_j kept (default: as many as the threshold allows, at most
        :data:`MAX_PASSES`).

    Returns
    -------
    list of Beam
        R, F, B_1 ... and the ghost copies, in label order.
    """
    k0 = 2 * math.pi / setup.wavelength
    n1, n2, d = setup.n1, setup.n2, setup.depth
    R = setup.surface_reflection
    rho = math.sqrt(setup.mirror_reflectivity)
    walk = (2 * d * setup.m_b[0], 2 * d * setup.m_b[1])
    reference = Beam(
        name="R",
        arm="reference",
        passes=0,
        amplitude=1.0,
        gradient=(n1 * setup.m_r[0], n1 * setup.m_r[1]),
        kappa=0.0,
        offset=2 * k0 * n1 * setup.delta_H,
        centroid=(0.0, 0.0),
        entry=(0.0, 0.0),
    )
    probe = [
        Beam("F", "probe", 0, -R, (0.0, 0.0), -n1, 0.0, (0.0, 0.0), (0.0, 0.0)),
    ]
    limit = MAX_PASSES if max_passes is None else min(max_passes, MAX_PASSES)
    for j in range(1, limit + 1):
        amplitude = (1 - R * R) * rho**j * R ** (j - 1)
        if abs(amplitude) < threshold or amplitude == 0:
            break
        positions, weights = walkoff_weights(setup, j)
        kappa = j * n2 - n1
        q = sum(p * w for p, w in zip(positions, weights, strict=True)) / kappa
        probe.append(
            Beam(
                name=f"B{j}",
                arm="probe",
                passes=j,
                amplitude=amplitude,
                gradient=(j * n2 * setup.m_b[0], j * n2 * setup.m_b[1]),
                kappa=kappa,
                offset=2 * k0 * j * n2 * d,
                centroid=(q * walk[0], q * walk[1]),
                entry=(-j * j * walk[0], -j * j * walk[1]),
            )
        )
    beams = [reference, *probe]
    for index, ghost in enumerate(setup.ghosts):
        originals = [reference] if ghost.arm == "reference" else probe
        for beam in originals:
            amplitude = beam.amplitude * ghost.amplitude
            if abs(amplitude) < threshold:
                continue
            beams.append(
                Beam(
                    name=f"{beam.name}~g{index}",
                    arm=beam.arm,
                    passes=beam.passes,
                    amplitude=amplitude,
                    gradient=(
                        beam.gradient[0] + n1 * ghost.tilt[0],
                        beam.gradient[1] + n1 * ghost.tilt[1],
                    ),
                    kappa=beam.kappa,
                    offset=beam.offset,
                    centroid=beam.centroid,
                    entry=beam.entry,
                    ghost=index,
                )
            )
    return sorted(beams, key=lambda b: b.order_key)


def mean_intensity(beams: list[Beam]) -> float:
    """Return ``sum |a_b|**2``: the intensity of the incoherent sum, relative to the input."""
    return float(sum(b.amplitude**2 for b in beams))
