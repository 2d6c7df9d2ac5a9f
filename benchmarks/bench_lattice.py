"""Issue 13 figures: identification by the lattice and the joint per-frame estimate.

Run from the repository root::

    .venv/bin/python benchmarks/bench_lattice.py                  # 100 benches, 3 seeds
    .venv/bin/python benchmarks/bench_lattice.py --setups 20 --seeds 1   # quick

Prints, with the machine and its load first:

1. **Random benches** (``tests/identify/random_setups.py``: fluid, mirror reflectivity
   0.7 to 1, tilts, camera response, up to two ghosts), one frame each at 512 x 512 and
   256 x 256: every first-order family up to j = 3 present in the spectrum (detected,
   clear of other families) named right with the right alpha and one global twin, by the
   automatic basis (carriers and brightness) and from RB1 and RF labelled; ghost copies
   of RB1 named; the time to identify (median, worst).
2. **Injection** at 25 frames/s, 51 nm a frame (RB2, FB2, RB3, FB3 stepping 2 to 5 rad),
   512 x 512 simulated frames: the joint estimate's fused and per-peak rate errors and
   flagged frames, beside the per-peak rule (``track_depth``: which peaks it leaves out,
   its fused error).
3. **Evaporation with 15 nm rms reference vibration**, 256 x 256: the fused depth's rms
   error against the truth beside FB1's alone and the per-peak rule's fused depth; the
   correlation of the vibration estimate with the simulator's.
4. The joint estimator's time per frame (8 peaks).
5. The issue's targets, each marked met or missed.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests" / "identify"))

from lattice_recording import injection_setup, record  # noqa: E402
from machine import machine  # noqa: E402
from random_setups import judge, random_setup, render  # noqa: E402

from holoview.errors import InputError  # noqa: E402
from holoview.optics.families import predict_families  # noqa: E402
from holoview.optics.scenarios import ScenarioConfig  # noqa: E402
from holoview.optics.setup import Setup  # noqa: E402
from holoview.processing.naming.lattice import identify_lattice  # noqa: E402
from holoview.processing.naming.lattice_geometry import LatticeKind  # noqa: E402
from holoview.processing.series.depth_series import track_depth  # noqa: E402
from holoview.processing.series.joint_estimation import JointEstimator  # noqa: E402
from holoview.processing.series.joint_series import estimate_joint  # noqa: E402
from holoview.processing.series.phase_series import unwrap_in_time  # noqa: E402


def _apart(a, b, shape) -> float:
    d = (np.subtract(a, b) + 0.5) % 1.0 - 0.5
    return float(min(np.hypot(d[0] * shape[1], d[1] * shape[0]),
                     np.hypot(*(((np.add(a, b) + 0.5) % 1.0 - 0.5) * shape[::-1]))))  # fmt: skip


def benches(count: int, size: int) -> dict[str, object]:
    """Identify ``count`` random benches automatically and from labels."""
    results = {"auto": [], "labels": []}
    times, present, ghost_named, ghost_present = [], 0, 0, 0
    for seed in range(count):
        setup = random_setup(np.random.default_rng(seed), size)
        peaks = render(setup, seed)
        carriers = [p.carrier for p in peaks]
        amplitudes = [p.amplitude for p in peaks]
        truth = {f.label: f for f in predict_families(setup, max_order=3)}
        for mode in ("auto", "labels"):
            labels = None
            if mode == "labels":
                labels = {k: truth[k].observed_carrier for k in ("RB1", "RF")}
            start = time.perf_counter()
            try:
                ident = identify_lattice(
                    carriers, setup.shape, setup.n1, setup.n2, labels=labels, amplitudes=amplitudes
                )
            except InputError as exc:
                print(f"  {size}^2 seed {seed} {mode}: {exc}")
                results[mode].append(False)
                continue
            if mode == "auto":
                times.append(time.perf_counter() - start)
            verdict = judge(setup, peaks, ident)
            results[mode].append(verdict.all_right)
            if mode == "auto":
                present += len(verdict.present)
                if not verdict.all_right:
                    print(f"  {size}^2 seed {seed} auto: {verdict}")
                for g in range(len(setup.ghosts)):
                    copy = next(
                        (f for k, f in truth.items() if k in (f"R~g{g}B1", f"RB1~g{g}")), None
                    )
                    if copy is None:
                        continue
                    ghost_present += 1
                    named = [p for p in ident.peaks if p.kind is LatticeKind.GHOST
                             and p.label and p.label.startswith("RB1~")]  # fmt: skip
                    if any(_apart(peaks[p.index].carrier, copy.observed_carrier, setup.shape) < 1
                           for p in named):  # fmt: skip
                        ghost_named += 1
    return {
        "auto right": sum(results["auto"]),
        "labels right": sum(results["labels"]),
        "count": count,
        "families present": present,
        "ghost RB1 copies named": f"{ghost_named} of {ghost_present}",
        "ms median": 1e3 * statistics.median(times),
        "ms worst": 1e3 * max(times),
    }


def injection(seed: int) -> dict[str, object]:
    setup, config = injection_setup()
    rec = record(setup, "injection", config, fps=25.0, frames=250, seed=seed)
    joint = estimate_joint(rec.values, rec.times, rec.alphas, rec.couplings, setup.wavelength)
    old = track_depth(rec.values, rec.times, rec.alphas, setup.wavelength)
    per_frame = 4 * np.pi * rec.alphas * rec.rate / 25 / setup.wavelength
    return {
        "peaks": dict(zip(rec.labels, np.round(per_frame, 2).tolist(), strict=True)),
        "fused error": joint.fit.relative_error(rec.rate),
        "worst peak error": max(f.relative_error(rec.rate) for f in joint.peak_fits),
        "flagged frames": int(joint.flagged.sum()),
        "min margin": float(np.min(joint.margins[1:])),
        "old: left out": [k for k, a in zip(rec.labels, old.aliasing.aliased, strict=True) if a],
        "old: fused error": old.fit.relative_error(rec.rate),
    }


def evaporation(seed: int) -> dict[str, object]:
    setup = Setup(shape=(256, 256))
    config = ScenarioConfig(vibration_rms=15e-9, vibration_time=0.05)
    rec = record(setup, "evaporation", config, fps=10.0, frames=300, seed=seed)
    joint = estimate_joint(rec.values, rec.times, rec.alphas, rec.couplings, setup.wavelength)
    old = track_depth(rec.values, rec.times, rec.alphas, setup.wavelength)
    truth = rec.heights - rec.heights[0]
    fb1 = list(rec.labels).index("FB1")
    alone = unwrap_in_time(rec.values[:, fb1])[:, 0] * setup.wavelength / (4 * np.pi * setup.n2)
    psi = rec.reference_phases - rec.reference_phases[0]

    def rms(x: np.ndarray) -> float:
        return float(np.std(x - truth)) * 1e9

    return {
        "fused rms nm": rms(joint.fused),
        "FB1 alone rms nm": rms(alone),
        "old fused rms nm": rms(old.fused.depth),
        "vibration correlation": float(np.corrcoef(joint.vibration, psi)[0, 1]),
        "fused rate error": joint.fit.relative_error(rec.rate),
        "flagged frames": int(joint.flagged.sum()),
    }


def joint_speed() -> float:
    """Median ms per frame of the incremental estimator with 8 peaks."""
    alphas = np.array([0.333, 1.0, 1.333, 1.666, 2.666, 3.0, 4.0, 4.333])
    couplings = np.array([-1, 1, 0, -1, 0, -1, 0, -1])
    rng = np.random.default_rng(0)
    t = np.arange(400)
    phases = np.outer(1.2 * t, alphas) + rng.normal(0, 0.01, (t.size, alphas.size))
    estimator = JointEstimator(alphas, couplings, 532e-9)
    costs = []
    for row in np.exp(1j * phases):
        start = time.perf_counter()
        estimator.update(row)
        costs.append(time.perf_counter() - start)
    return 1e3 * statistics.median(costs[10:])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--setups", type=int, default=100, help="random benches per size")
    parser.add_argument("--seeds", type=int, default=3, help="recordings per scenario")
    args = parser.parse_args()
    print(machine())
    met: dict[str, bool] = {}
    for size in (512, 256):
        figures = benches(args.setups, size)
        print(f"\nrandom benches at {size} x {size}:")
        for key, value in figures.items():
            print(f"  {key:24s} {value if not isinstance(value, float) else f'{value:.1f}'}")
        met[f"{size}^2: every present family named right ({args.setups} benches, auto)"] = (
            figures["auto right"] == args.setups
        )
    inj = [injection(2 + 10 * k) for k in range(args.seeds)]
    print("\ninjection, 25 frames/s, 51 nm a frame (steps in rad a frame):")
    for run in inj:
        print("  " + "; ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                               for k, v in run.items()))  # fmt: skip
    met["injection: fused rate within 0.3 %"] = all(r["fused error"] < 0.003 for r in inj)
    met["injection: each peak's rate within 1 %"] = all(r["worst peak error"] < 0.01 for r in inj)
    met["injection: RB2, FB2, RB3, FB3 named and used"] = all(
        {"RB2", "FB2", "RB3", "FB3"} <= set(r["peaks"]) for r in inj
    )
    evap = [evaporation(4 + 10 * k) for k in range(args.seeds)]
    print("\nevaporation with 15 nm rms reference vibration:")
    for run in evap:
        print("  " + "; ".join(f"{k} {v:.3g}" for k, v in run.items()))
    met["evaporation: fused noise below FB1's alone"] = all(
        r["fused rms nm"] < r["FB1 alone rms nm"] for r in evap
    )
    met["evaporation: vibration correlation > 0.9"] = all(
        r["vibration correlation"] > 0.9 for r in evap
    )
    print(f"\njoint estimator, 8 peaks: {joint_speed():.2f} ms a frame (median)")
    print("\ntargets:")
    for target, ok in met.items():
        print(f"  {'met   ' if ok else 'MISSED'} {target}")


if __name__ == "__main__":
    main()
