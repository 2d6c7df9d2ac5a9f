"""Random benches for the lattice identification, and the check of its names against truth.

Shared by ``tests/identify/test_lattice.py`` (a small sample) and
``benchmarks/bench_lattice.py`` (100 setups and more). A setup draws a fluid, a
submerged-mirror reflectivity in [0.7, 1], the two mirror tilts (through the carriers of
RF and FB1, 0.05 to 0.32 cycles/pixel in any direction, RB1 inside the spectrum), a
camera response exponent near 1 (second orders and products) and up to two
beam-splitter ghosts of either arm (offset 0.04 to 0.2 cycles/pixel, field 5 to 30 %).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from holoview.errors import InputError
from holoview.optics.families import Family, alpha_of, predict_families
from holoview.optics.setup import FLUIDS, Ghost, Setup
from holoview.optics.synthesis import HologramSynthesizer
from holoview.processing.naming.lattice import LatticeIdentification
from holoview.processing.peaks.detection import Peak, find_peaks

#: The first-order families the target names (j up to 3).
TARGET_FAMILIES = ("RF", "RB1", "FB1", "RB2", "FB2", "RB3", "FB3")

#: A family counts as present when a detected peak lies this close (FFT bins) ...
PRESENT_BINS = 1.0

#: ... and no other family with a different name lies this close to it (bins).
CLEAR_BINS = 3.0

#: Families weaker than this (relative modulation) are not counted as neighbours.
NEIGHBOUR_AMPLITUDE = 2e-4

FLUID_NAMES = ("water", "ethanol", "isopropanol", "glycerol")


def _polar(rng: np.random.Generator, low: float, high: float) -> np.ndarray:
    angle = rng.uniform(0, 2 * np.pi)
    return rng.uniform(low, high) * np.array([np.cos(angle), np.sin(angle)])


def random_setup(rng: np.random.Generator, size: int) -> Setup:
    """A random bench (module documentation) of ``size`` x ``size`` pixels."""
    n2 = FLUIDS[str(rng.choice(FLUID_NAMES))]
    base = Setup(shape=(size, size), n2=n2)
    scale = 2 * base.pixel_pitch / base.wavelength
    while True:
        rf, fb1 = _polar(rng, 0.05, 0.32), _polar(rng, 0.05, 0.32)
        rb1 = fb1 - rf
        if np.max(np.abs(rb1)) < 0.45 and np.hypot(*rb1) > 0.05:
            break
    ghosts = []
    for _ in range(int(rng.integers(0, 3))):
        offset = _polar(rng, 0.04, 0.2) / (scale * base.n1)
        arm = "reference" if rng.uniform() < 0.5 else "probe"
        ghosts.append(Ghost(arm, (float(offset[0]), float(offset[1])), rng.uniform(0.05, 0.3)))
    return base.replace(
        m_r=tuple(rf / (scale * base.n1)),
        m_b=tuple(fb1 / (scale * n2)),
        mirror_reflectivity=float(rng.uniform(0.7, 1.0)),
        gamma=float(rng.choice([1.0, rng.uniform(0.85, 1.15)])),
        ghosts=tuple(ghosts),
    )


def render(setup: Setup, seed: int) -> list[Peak]:
    """One frame of a uniform level with shot noise, and the peaks found in it."""
    frame = HologramSynthesizer(setup).render(0.0, rng=np.random.default_rng(seed))
    return find_peaks(frame)


def _bins(a: np.ndarray, b: np.ndarray, shape: tuple[int, int]) -> float:
    d = (np.subtract(a, b) + 0.5) % 1.0 - 0.5
    return float(np.hypot(d[0] * shape[1], d[1] * shape[0]))


def _apart(a: tuple[float, float], b: tuple[float, float], shape: tuple[int, int]) -> float:
    """Distance in bins between two carriers on either twin."""
    return min(_bins(a, b, shape), _bins(a, np.negative(b), shape))


def _same_point(a: Family, b: Family, n1: float, n2: float) -> bool:
    """Whether two families land on one lattice point with one alpha (FB1 and B2B1)."""
    if "~" in a.label or "~" in b.label:
        return False
    try:
        return abs(alpha_of(a.label, n1, n2) - alpha_of(b.label, n1, n2)) < 1e-9 and (
            a.kind != "second-order" or b.kind != "second-order" or a.label == b.label
        )
    except InputError:
        return False


@dataclass(frozen=True)
class Verdict:
    """How one identification did on one setup.

    ``present``: target families detected and clear of other families; ``right``: those
    named right with the right alpha; ``twin_direct`` / ``twin_flipped``: those whose
    stored twin is the true one, or its negative; ``wrong``: peaks given a target name
    that is not theirs.
    """

    present: tuple[str, ...]
    right: tuple[str, ...]
    twin_direct: tuple[str, ...]
    twin_flipped: tuple[str, ...]
    wrong: tuple[str, ...]

    @property
    def all_right(self) -> bool:
        """Every present family named right, on one consistent global twin, none wrong."""
        twins_ok = set(self.twin_direct) == set(self.present) or set(self.twin_flipped) == set(
            self.present
        )
        return set(self.right) == set(self.present) and twins_ok and not self.wrong


def judge(setup: Setup, peaks: list[Peak], ident: LatticeIdentification) -> Verdict:
    """Compare an identification of ``peaks`` with the families the simulator placed."""
    shape = setup.shape
    families = [f for f in predict_families(setup, max_order=5) if f.amplitude > 0]
    neighbours = [f for f in families if f.amplitude >= NEIGHBOUR_AMPLITUDE]
    present, right, direct, flipped, wrong = [], [], [], [], []
    for family in families:
        if family.label not in TARGET_FAMILIES:
            continue
        carrier = family.observed_carrier
        distances = [_apart(p.carrier, carrier, shape) for p in peaks]
        if not distances or min(distances) > PRESENT_BINS:
            continue
        crowded = any(
            _apart(o.observed_carrier, carrier, shape) < CLEAR_BINS
            for o in neighbours
            if o.label != family.label and not _same_point(o, family, setup.n1, setup.n2)
        )
        if crowded:
            continue
        index = int(np.argmin(distances))
        named = ident.peaks[index]
        present.append(family.label)
        alpha = alpha_of(family.label, setup.n1, setup.n2)
        if (
            named.label == family.label
            and named.alpha is not None
            and abs(named.alpha - alpha) < 1e-9
        ):
            right.append(family.label)
        if _bins(named.carrier, carrier, shape) <= PRESENT_BINS:
            direct.append(family.label)
        elif _bins(named.carrier, np.negative(carrier), shape) <= PRESENT_BINS:
            flipped.append(family.label)
    for p in ident.peaks:
        if p.label in TARGET_FAMILIES and p.label not in present:
            truth = next((f for f in families if f.label == p.label), None)
            if truth is None or _apart(peaks[p.index].carrier, truth.observed_carrier, shape) > 1.5:
                wrong.append(p.label)
    return Verdict(tuple(present), tuple(right), tuple(direct), tuple(flipped), tuple(wrong))
