"""A simulated recording named by the lattice and demodulated: the joint estimate's input.

The operator's procedure at the bench: peaks found in the first frame, RB1 and FB1
labelled where they are (or nothing labelled: the lattice finds its basis), every peak
the lattice gives an alpha demodulated on its stored twin (synthetic reference) and its
carrier value kept per frame, beside the simulator's truth (mean height and the
reference arm's phase per frame). Shared by ``tests/identify/test_joint.py`` and
``benchmarks/bench_lattice.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from holoview.optics.families import predict_families
from holoview.optics.scenarios import ScenarioConfig, simulate
from holoview.optics.setup import Setup
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.naming.lattice import LatticeIdentification, identify_lattice
from holoview.processing.naming.lattice_geometry import LatticeKind
from holoview.processing.peaks.detection import Peak, find_peaks

#: Kinds demodulated: everything on the lattice with a height.
USED_KINDS = (LatticeKind.FIRST_ORDER, LatticeKind.SECOND_ORDER, LatticeKind.INTERMODULATION)


@dataclass(frozen=True)
class LatticeRecording:
    """Carrier values of the named peaks and the truth.

    ``labels``, ``alphas``, ``couplings``: of the demodulated peaks, in ``values``'
    column order; ``heights`` and ``reference_phases`` the simulator's per frame (m,
    rad); ``rate`` the slope of the true heights (m/s).
    """

    ident: LatticeIdentification
    labels: tuple[str, ...]
    alphas: np.ndarray
    couplings: np.ndarray
    times: np.ndarray
    values: np.ndarray
    heights: np.ndarray
    reference_phases: np.ndarray
    rate: float


def record(
    setup: Setup,
    scenario: str,
    config: ScenarioConfig,
    *,
    fps: float,
    frames: int,
    seed: int,
    labelled: bool = True,
) -> LatticeRecording:
    """Simulate, name (RB1 and FB1 labelled from the truth, or automatically), demodulate."""
    stream = simulate(setup, scenario, frames=frames, fps=fps, seed=seed, config=config)
    first, first_truth = next(stream)
    detected = find_peaks(first)
    labels = None
    if labelled:
        truth = {f.label: f for f in predict_families(setup, max_order=2)}
        labels = {k: truth[k].observed_carrier for k in ("RB1", "FB1")}
    ident = identify_lattice(
        [p.carrier for p in detected],
        setup.shape,
        setup.n1,
        setup.n2,
        labels=labels,
        amplitudes=[p.amplitude for p in detected],
    )
    chosen = [p for p in ident.peaks if p.kind in USED_KINDS and p.alpha]
    peaks = [
        Peak(p.carrier, detected[p.index].amplitude, detected[p.index].snr).relabelled(
            p.label, p.alpha
        )
        for p in chosen
    ]
    demodulator = Demodulator(setup.shape, peaks, reference="synthetic", unwrap="never", threads=1)
    values = np.empty((frames, len(peaks)), dtype=np.complex128)
    times, heights, phases = np.empty(frames), np.empty(frames), np.empty(frames)
    frame, frame_truth = first, first_truth
    for i in range(frames):
        if i > 0:
            frame, frame_truth = next(stream)
        values[i] = [r.carrier_value for r in demodulator.process(frame).peaks]
        times[i], heights[i] = frame_truth.time, frame_truth.mean_height
        phases[i] = frame_truth.reference_phase
    return LatticeRecording(
        ident=ident,
        labels=tuple(p.label for p in chosen),
        alphas=np.array([p.alpha for p in chosen]),
        couplings=np.array([p.coupling for p in chosen]),
        times=times,
        values=values,
        heights=heights,
        reference_phases=phases,
        rate=float(np.polyfit(times, heights, 1)[0]),
    )


def injection_setup() -> tuple[Setup, ScenarioConfig]:
    """512 x 512, a mirror reflecting 70 % (bright FB_j), 20000 photons a pixel, and an
    injection whose level rises 51 nm a frame at 25 frames/s: RB2 steps 2.0 rad a
    frame, FB2 3.2, RB3 3.6 and FB3 4.8 (water)."""
    setup = Setup(
        shape=(512, 512),
        mirror_reflectivity=0.7,
        photons_per_pixel=20000.0,
        saturation=80000.0,
        bit_depth=16,
    )
    rise = 51e-9 * 25  # m/s
    area = 70.6e-4
    config = ScenarioConfig(injection_rate=rise * area, basin_area=area, vibration_rms=3e-9)
    return setup, config
