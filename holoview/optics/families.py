"""Hologram families: carriers, amplitudes, prefactors and displacements, from the model.

Every pair of beams (A, B) of :mod:`holoview.optics.beams` makes an off-axis hologram.
A family is stored on the twin whose phase grows with the surface height (docs/design.md):
A is the beam with the larger height coefficient, so ``alpha = kappa_A - kappa_B > 0``
and the carrier is ``2 (g_A - g_B) pixel_pitch / wavelength`` cycles/pixel (``fx``
along columns, ``fy`` along rows, numpy's FFT sign). This gives the paper's eq. 6:

==========  ============================  ==================================
label       carrier (x 2 pitch / lambda)  alpha
==========  ============================  ==================================
``RF``      ``n1 m_r``                    ``n1``
``RBj``     ``j n2 m_b - n1 m_r``         ``j n2 - n1``
``FBj``     ``j n2 m_b``                  ``j n2``
``BlBj``    ``(l - j) n2 m_b``            ``(l - j) n2`` (on top of FB_(l-j))
``2X``      twice X's                     twice X's (second order, camera response)
==========  ============================  ==================================

Labels
------
A label is the two beam names, R first, then F, then B_j by decreasing j (``"RB1"``,
``"FB2"``, ``"B2B1"``). A beam-splitter ghost copy carries ``~g{i}`` (``i`` its index in
``Setup.ghosts``) right after the beam it copies: ``"R~g0F"`` is the reference ghost
against F (a copy of RF), ``"RB1~g1"`` the reference against a probe ghost's B1, and
``"RR~g0"`` the reference against its own ghost (alpha 0: it carries no height). A
leading integer marks a second-order peak: ``"2RB1"``.

Amplitudes are modulation depths relative to the local mean camera value at the
beam centre. In intensity a pair has ``A = 2 |a_A a_B| / sum_b a_b**2``; through the
camera response ``I**gamma`` a family alone would give the Fourier coefficients of
``(1 + A cos theta)**gamma``: its first harmonic (the family's amplitude) and its
second (the second-order peak ``"2X"``), both relative to the mean. Cross terms
between families (for example RB2 against RF, which lands on 2RB1) and saturation
add a few per cent that this leaves out; with ``gamma == 1`` first orders are exact
and second orders are 0.

A family's amplitude is its pair's own. What the spectrum shows at a carrier is the
coherent sum of every pair there (:func:`coherent_amplitude`): at FB_j the pairs
F B_j, B_(j+1) B_1, ... nearly cancel (exactly, for a lossless mirror), and so do the
copies of FB_j that a probe-arm ghost makes against the probe (``"FB1~g0"``,
``"F~g0B1"``, ``"B2B1~g0"``, ...), the probe and its ghost both being all-pass.

Displacement ``delta_AB`` (m): the family's phase samples ``h(r + delta_AB)`` to first
order, ``delta_AB = (kappa_A c_A - kappa_B c_B) / alpha`` with ``c`` the beams' walk-off
centroids; RF has none, RB1 about ``-d m_b`` and FB1 about ``-(n2 - n1)/n2 d m_b``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from holoview.errors import InputError
from holoview.optics.beams import Beam, field_beams, mean_intensity
from holoview.optics.setup import Setup

#: Family kinds.
KINDS = ("RF", "RB", "FB", "BB", "ghost", "second-order")

#: Beam threshold for the "all passes" sums (mean intensity, coherent amplitudes).
_ALL_PASSES = 1e-12

_BEAM = re.compile(r"(R|F|B(\d+))(?:~g(\d+))?")
_LABEL = re.compile(r"(\d*)((?:R|F|B\d+)(?:~g\d+)?)((?:R|F|B\d+)(?:~g\d+)?)")


@dataclass(frozen=True)
class Family:
    """One hologram family, on the twin where its phase grows with the height.

    Attributes
    ----------
    label : str
        See the module docstring (``"RF"``, ``"RB1"``, ``"B2B1"``, ``"2RB1"``, ``"R~g0F"``).
    carrier : tuple of float
        ``(fx, fy)``, cycles/pixel, unfolded (may lie past Nyquist: see ``aliased``).
    amplitude : float
        Modulation depth relative to the mean camera value at the beam centre.
    alpha : float
        Prefactor: ``delta_phi = 4 pi alpha delta_h / wavelength``.
    displacement : tuple of float
        ``(dx, dy)``, m: the family images ``h(r + displacement)``.
    kind : str
        One of :data:`KINDS`.
    """

    label: str
    carrier: tuple[float, float]
    amplitude: float
    alpha: float
    displacement: tuple[float, float]
    kind: str

    @property
    def aliased(self) -> bool:
        """True when the carrier lies at or past Nyquist (0.5 cycles/pixel) on an axis."""
        return max(abs(self.carrier[0]), abs(self.carrier[1])) >= 0.5

    @property
    def observed_carrier(self) -> tuple[float, float]:
        """Where the camera sees the carrier: folded into [-0.5, 0.5) cycles/pixel."""
        fx, fy = ((c + 0.5) % 1.0 - 0.5 for c in self.carrier)
        return (fx, fy)


def response_harmonics(modulation: float, gamma: float) -> tuple[float, float]:
    """Return the first and second harmonic of ``(1 + m cos t)**gamma`` over its mean.

    Parameters
    ----------
    modulation : float
        Modulation depth ``m`` of the intensity, in [0, 1].
    gamma : float
        Response exponent.

    Returns
    -------
    tuple of float
        ``(2 |c1| / c0, 2 |c2| / c0)``, the modulation depths of the fundamental and of
        the second harmonic in the response.
    """
    if gamma == 1.0:
        return modulation, 0.0
    theta = np.linspace(0.0, 2 * math.pi, 256, endpoint=False)
    base = np.maximum(1 + min(modulation, 1.0) * np.cos(theta), 0.0)
    coefficients = np.fft.rfft(base**gamma) / theta.size
    mean = coefficients[0].real
    return 2 * abs(coefficients[1]) / mean, 2 * abs(coefficients[2]) / mean


def _kind(a: Beam, b: Beam) -> str:
    if a.ghost is not None or b.ghost is not None:
        return "ghost"
    names = {a.name[0], b.name[0]}
    if names == {"R", "F"}:
        return "RF"
    if "R" in names:
        return "RB"
    if "F" in names:
        return "FB"
    return "BB"


def _pair(setup: Setup, a: Beam, b: Beam, norm: float) -> tuple[Family, complex]:
    """Return the family of beams ``a`` and ``b`` and its complex stored-twin coefficient."""
    first, second = sorted((a, b), key=lambda x: x.order_key)
    label = first.name + second.name
    if a.kappa == b.kappa:
        high, low = first, second
    else:
        high, low = (a, b) if a.kappa > b.kappa else (b, a)
    alpha = high.kappa - low.kappa
    scale = 2 * setup.pixel_pitch / setup.wavelength
    carrier = (
        scale * (high.gradient[0] - low.gradient[0]),
        scale * (high.gradient[1] - low.gradient[1]),
    )
    if alpha > 0:
        displacement = (
            (high.kappa * high.centroid[0] - low.kappa * low.centroid[0]) / alpha,
            (high.kappa * high.centroid[1] - low.kappa * low.centroid[1]) / alpha,
        )
    else:
        displacement = (0.0, 0.0)
    coefficient = high.amplitude * low.amplitude * complex(np.exp(1j * (high.offset - low.offset)))
    amplitude, _ = response_harmonics(2 * abs(coefficient) / norm, setup.gamma)
    family = Family(label, carrier, amplitude, alpha, displacement, _kind(a, b))
    return family, coefficient


def predict_families(
    setup: Setup, max_order: int = 2, *, second_order: bool = True
) -> list[Family]:
    """Predict every hologram family the camera sees, up to ``max_order`` mirror passes.

    Parameters
    ----------
    setup : Setup
        The bench.
    max_order : int
        Largest ``j`` of B_j included (RB_j, FB_j, B_l B_j with ``l <= max_order``).
    second_order : bool
        Add the second-order peak ``"2X"`` of every RF, RB_j and FB_j.

    Returns
    -------
    list of Family
        Sorted by decreasing amplitude. Families with a field amplitude under the
        supplement's 5e-4 ray threshold are left out; ``alpha == 0`` families
        (a ghost against its own original) are included.
    """
    if isinstance(max_order, bool) or not isinstance(max_order, int) or max_order < 1:
        raise InputError(f"max_order must be a positive integer, got {max_order!r}")
    norm = mean_intensity(field_beams(setup, _ALL_PASSES))
    beams = field_beams(setup, max_passes=max_order)
    families: list[Family] = []
    for i, a in enumerate(beams):
        for b in beams[i + 1 :]:
            family, _ = _pair(setup, a, b, norm)
            families.append(family)
    if second_order:
        for i, a in enumerate(beams):
            for b in beams[i + 1 :]:
                family, coefficient = _pair(setup, a, b, norm)
                if family.kind not in ("RF", "RB", "FB"):
                    continue
                _, second = response_harmonics(2 * abs(coefficient) / norm, setup.gamma)
                families.append(
                    Family(
                        label=f"2{family.label}",
                        carrier=(2 * family.carrier[0], 2 * family.carrier[1]),
                        amplitude=second,
                        alpha=2 * family.alpha,
                        displacement=family.displacement,
                        kind="second-order",
                    )
                )
    families.sort(key=lambda f: (-f.amplitude, f.label))
    return families


def _coherent(setup: Setup, label: str) -> tuple[complex, tuple[complex, complex], float]:
    """Return (sum of coefficients, (sum c_i dx_i, sum c_i dy_i), mean intensity).

    Sums run over every beam pair (all passes) whose carrier is the family's, or its
    twin's (conjugated).
    """
    beams = field_beams(setup, _ALL_PASSES)
    norm = mean_intensity(beams)
    pairs = [_pair(setup, a, b, norm) for i, a in enumerate(beams) for b in beams[i + 1 :]]
    target = next((f for f, _ in pairs if f.label == label), None)
    if target is None:
        raise InputError(f"no first-order family {label!r} in this setup")
    total = 0j
    moment = [0j, 0j]
    for family, coefficient in pairs:
        offsets = [c - t for c, t in zip(family.carrier, target.carrier, strict=True)]
        sums = [c + t for c, t in zip(family.carrier, target.carrier, strict=True)]
        if max(map(abs, offsets)) < 1e-9:
            value = coefficient
        elif max(map(abs, sums)) < 1e-9:
            value = coefficient.conjugate()
        else:
            continue
        total += value
        moment[0] += value * family.displacement[0]
        moment[1] += value * family.displacement[1]
    return total, (moment[0], moment[1]), norm


def predict_carriers(setup: Setup, max_order: int = 2) -> dict[str, tuple[float, float]]:
    """Return every family's stored-twin carrier, cycles/pixel (unfolded), by label.

    A shortcut for ``{f.label: f.carrier for f in predict_families(setup, max_order)}``.
    """
    return {f.label: f.carrier for f in predict_families(setup, max_order)}


def coherent_amplitude(setup: Setup, label: str) -> float:
    """Return the amplitude of the spectral peak at ``label``'s carrier from the field sum.

    Every beam pair whose carrier coincides with the family's (or with its twin, taken
    conjugate) adds coherently: at FB1 that is F B1, B2 B1, B3 B2, ... (all passes), so
    a lossless submerged mirror gives 0 there.

    Parameters
    ----------
    setup : Setup
        The bench.
    label : str
        A first-order family label (for example ``"FB1"``).

    Returns
    -------
    float
        Modulation depth relative to the mean camera value, like
        :attr:`Family.amplitude`.
    """
    total, _, norm = _coherent(setup, label)
    first, _ = response_harmonics(2 * abs(total) / norm, setup.gamma)
    return first


def coherent_displacement(setup: Setup, label: str) -> tuple[float, float]:
    """Return the displacement, m, of the spectral peak at ``label``'s carrier.

    Where several pairs share the carrier (FB1 with B2B1, B3B2, ...), the peak's phase
    images ``h`` around ``Re(sum_i c_i delta_i / sum_i c_i)`` to first order, ``c_i``
    the pairs' complex coefficients. Near the etalon's cancellation (``R_m -> 1``) the
    weights nearly cancel and this displacement grows well beyond each pair's: the FB
    peaks of a good mirror image a blurred, shifted surface.

    Parameters
    ----------
    setup : Setup
        The bench.
    label : str
        A first-order family label.

    Returns
    -------
    tuple of float
        ``(dx, dy)``, m (``(0, 0)`` when the peak vanishes).
    """
    total, moment, _ = _coherent(setup, label)
    if abs(total) < 1e-15:
        return (0.0, 0.0)
    return ((moment[0] / total).real, (moment[1] / total).real)


def _beam_terms(name: str, n1: float, n2: float) -> tuple[float, tuple[int, int], bool]:
    """Return (kappa, (u, v) carrier coefficients, is_ghost) of a beam name."""
    match = _BEAM.fullmatch(name)
    if match is None:
        raise InputError(f"{name!r} is not a beam name (R, F, B1, B2, ...)")
    ghost = match.group(3) is not None
    if match.group(1) == "R":
        return 0.0, (1, 0), ghost
    if match.group(1) == "F":
        return -n1, (0, 0), ghost
    j = int(match.group(2))
    if j < 1:
        raise InputError(f"{name!r} is not a beam name: B_j needs j >= 1")
    return j * n2 - n1, (0, j), ghost


def _parse(label: str, n1: float, n2: float) -> tuple[float, tuple[int, int], bool]:
    """Return (alpha, (u, v) coefficients of the stored carrier, is_ghost) of a label.

    The carrier of the stored twin is ``u f_RF + v f_FB1``.
    """
    if not isinstance(label, str):
        raise InputError(f"a family label must be a string, got {label!r}")
    match = _LABEL.fullmatch(label.strip())
    if match is None:
        raise InputError(f"{label!r} is not a family label (RF, RB1, FB1, B2B1, 2RB1, R~g0F, ...)")
    harmonic = int(match.group(1)) if match.group(1) else 1
    if harmonic < 1:
        raise InputError(f"{label!r}: the order prefix must be >= 1")
    ka, ca, ga = _beam_terms(match.group(2), n1, n2)
    kb, cb, gb = _beam_terms(match.group(3), n1, n2)
    if ka < kb:
        ka, ca, kb, cb = kb, cb, ka, ca
    coefficients = (harmonic * (ca[0] - cb[0]), harmonic * (ca[1] - cb[1]))
    return harmonic * (ka - kb), coefficients, ga or gb


def _check_indices(n1: float, n2: float) -> None:
    for name, value in (("n1", n1), ("n2", n2)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive finite number, got {value!r}")
    if n2 <= n1:
        raise InputError(f"n2 = {n2:g} must exceed n1 = {n1:g}")


def alpha_of(label: str, n1: float, n2: float) -> float:
    """Return the prefactor alpha of a family label (positive on the stored twin).

    Parameters
    ----------
    label : str
        ``"RF"`` (n1), ``"RBj"`` (j n2 - n1), ``"FBj"`` (j n2), ``"BlBj"`` ((l - j) n2),
        a leading order ``"2RB1"`` (times 2), ghost copies (``"R~g0F"``: as the original).
    n1, n2 : float
        Refractive indices above and below the surface (``n2 > n1``).

    Returns
    -------
    float
        alpha, dimensionless; ``delta_h = delta_phi * wavelength / (4 pi alpha)``.
    """
    _check_indices(n1, n2)
    alpha, _, _ = _parse(label, n1, n2)
    return alpha


def infer_carriers(
    labelled: Mapping[str, tuple[float, float]], n1: float, n2: float, max_order: int = 2
) -> dict[str, tuple[float, float]]:
    """Infer every family's carrier from labelled ones (two suffice, e.g. RB1 and FB1).

    The model fixes every carrier as ``u f_RF + v f_FB1`` with integer ``(u, v)``; two
    labelled peaks with independent ``(u, v)`` fix ``f_RF`` and ``f_FB1`` (more are
    fitted by least squares).

    Parameters
    ----------
    labelled : mapping of str to (fx, fy)
        Stored-twin carriers of labelled peaks, cycles/pixel (for example
        ``{"RB1": (-0.2, 0.06), "FB1": (-0.05, 0.15)}``). Unfolded carriers are best;
        folded ones give folded predictions only where the model is linear modulo 1.
    n1, n2 : float
        Refractive indices (they order each pair's twin).
    max_order : int
        Largest ``j`` of the families returned.

    Returns
    -------
    dict of str to (fx, fy)
        ``RF``, ``RBj``, ``FBj``, ``BlBj`` (``l <= max_order``) and the second-order
        ``2RF``, ``2RBj``, ``2FBj``, cycles/pixel, unfolded.

    Raises
    ------
    InputError
        Fewer than two independent labels, a ghost label (its tilt is unknown), or a
        carrier that is not a finite pair.
    """
    _check_indices(n1, n2)
    if isinstance(max_order, bool) or not isinstance(max_order, int) or max_order < 1:
        raise InputError(f"max_order must be a positive integer, got {max_order!r}")
    rows: list[tuple[int, int]] = []
    values: list[tuple[float, float]] = []
    for label, carrier in labelled.items():
        _, coefficients, ghost = _parse(label, n1, n2)
        if ghost:
            raise InputError(f"{label!r}: a ghost copy's carrier depends on its unknown tilt")
        try:
            fx, fy = (float(c) for c in carrier)
        except (TypeError, ValueError) as exc:
            raise InputError(f"carrier of {label!r} must be (fx, fy), got {carrier!r}") from exc
        if not (math.isfinite(fx) and math.isfinite(fy)):
            raise InputError(f"carrier of {label!r} must be finite, got ({fx}, {fy})")
        rows.append(coefficients)
        values.append((fx, fy))
    matrix = np.array(rows, dtype=float).reshape(-1, 2)
    if len(rows) < 2 or np.linalg.matrix_rank(matrix) < 2:
        raise InputError(
            "need two labelled peaks that fix both RF and FB1 (for example RB1 and FB1, "
            f"or RF and RB1); got {sorted(labelled)}"
        )
    solution, *_ = np.linalg.lstsq(matrix, np.array(values, dtype=float), rcond=None)
    rf, fb1 = solution[0], solution[1]

    def combine(u: int, v: int) -> tuple[float, float]:
        f = u * rf + v * fb1
        return (float(f[0]), float(f[1]))

    result: dict[str, tuple[float, float]] = {"RF": combine(1, 0)}
    for j in range(1, max_order + 1):
        result[f"RB{j}"] = combine(-1, j)
        result[f"FB{j}"] = combine(0, j)
    for l_ in range(2, max_order + 1):
        for j in range(1, l_):
            result[f"B{l_}B{j}"] = combine(0, l_ - j)
    for label in [k for k in result if not k.startswith("B")]:
        fx, fy = result[label]
        result[f"2{label}"] = (2 * fx, 2 * fy)
    return result
