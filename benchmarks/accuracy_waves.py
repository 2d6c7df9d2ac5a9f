"""The wave analyses against the simulator's truth, from maps of simulated holograms.

Run from the repository root::

    .venv/bin/python benchmarks/accuracy_waves.py                      # seeds 1 2 3
    .venv/bin/python benchmarks/accuracy_waves.py --seeds 4 5 --keep /tmp/acc

For each seed and scenario the commands are run as a user would (printed), in a child
process each:

1. ``holoview simulate``: 512 frames of 1050 x 1050 holograms at 250 frames/s (80 um
   pixels, six peaks), the surface at rest in the first frames (``--wave-start-s``);
2. ``holoview process --maps --reference absolute``: 256 x 256 height maps per peak and
   fused (0.328 mm pixels), in ``results.h5``;
3. ``holoview waves`` on the fused maps: the dispersion fit (travelling waves), the
   partial waves with the centre found (partial waves), the ringdown fit (a damped mode).

Then each value in ``waves.json`` is compared with ``/truth/waves`` of the recording:
the relative error and the error in standard errors. Targets (issue 24): sigma within
3 %, depth within 5 %, flow within 3 % (or two standard errors); each partial wave's
amplitudes and incoming/outgoing ratio within 3 %; the ringdown's frequency within
0.5 % and decay rate within 5 %. The rings reach 37 mm: around the true centre
(3, -2) mm from the middle, the matched windows' maps (180 pixels of 0.467 mm) leave
37.6 mm of room, and rings to 38 mm held the centre found at the edge of where they
fit, a pixel off (2 to 3 % of the partial waves' amplitudes lost); the centre search
now refuses such a radius. Recordings (1.1 GB each) are deleted at the end
unless ``--keep`` names a folder (then they are reused).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
from machine import machine

OPTICS = (
    "--size 1050 --frames 512 --fps 250 --pixel-pitch-um 80 --m-r-mrad 0.8 0.05 "
    "--m-b-mrad 0.05 0.6 --reflectivity 0.1 --depth-mm 3 --no-truth-maps"
)
SCENARIOS = {
    "travelling": (
        "--scenario travelling --wave-k 300 1800 --flow-mm-per-s 20 10 --sigma 0.065 "
        "--wave-start-s 0.002 --wave-rise-s 0.01",
        "--time 0.02:",
    ),
    "partial-waves": (
        "--scenario partial-waves --centre-mm 3 -2 --core-mm 4 "
        "--wave-start-s 0.002 --wave-rise-s 0.01",
        "--time 0.02: --no-fit --depth-mm 3 --centre auto --r-range-mm 5:37 --m-max 4 --n-modes 3",
    ),
    "ringdown": (
        "--scenario ringdown --centre-mm 3 -2 --mode 2 12 0.8 60 --wave-start-s 0.05",
        "--no-fit --depth-mm 3 --centre auto --r-range-mm 5:37 --m-max 4 "
        "--ringdown 2,10:14 --ringdown-start 0.06",
    ),
}


def holoview(arguments: str) -> float:
    """Run ``holoview -q ARGUMENTS`` in a child (printed); return its wall time, s."""
    print(f"  $ holoview -q {arguments}", flush=True)
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "holoview", "-q", *arguments.split()],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        raise SystemExit(f"failed ({done.returncode}): {done.stderr.strip()}")
    return time.perf_counter() - started


def row(name: str, value: float, stderr: float, truth: float, target: float) -> bool:
    """Print one compared value; return whether it meets its target."""
    relative = (value - truth) / truth
    sigmas = abs(value - truth) / stderr if stderr > 0 else float("inf")
    met = abs(relative) <= target or sigmas <= 2.0
    print(
        f"    {name:28s} {value:12.6g} ± {stderr:9.2g}   truth {truth:10.6g}   "
        f"error {relative * 100:+7.3f} % ({sigmas:5.1f} se)   target {target * 100:g} %"
        f"{'' if met else '   MISSED'}"
    )
    return met


def compare(scenario: str, summary: dict, truth: h5py.Group) -> list[bool]:
    """The values of ``waves.json`` against the truth; one bool per target."""
    t = truth.attrs
    if scenario == "travelling":
        fit = summary["dispersion"]
        met = [
            row(
                "sigma (N/m)",
                fit["surface_tension_n_per_m"],
                fit["surface_tension_stderr_n_per_m"],
                float(t["sigma_n_per_m"]),
                0.03,
            ),
            row("depth (m)", fit["depth_m"], fit["depth_stderr_m"], float(t["depth_m"]), 0.05),
        ]
        for axis, name in enumerate(("Ux (m/s)", "Uy (m/s)")):
            met.append(
                row(
                    name,
                    fit["flow_m_per_s"][axis],
                    fit["flow_stderr_m_per_s"][axis],
                    float(t["flow_m_per_s"][axis]),
                    0.03,
                )
            )
        return met
    if scenario == "partial-waves":
        fits = {p["m"]: p for p in summary["partial_waves"]}
        met = []
        incoming = truth["incoming_m"][()] @ np.array([1, 1j])
        outgoing = truth["outgoing_m"][()] @ np.array([1, 1j])
        for m, f, wave_in, wave_out in zip(
            truth["m"][()], truth["frequency_hz"][()], incoming, outgoing, strict=True
        ):
            fit = fits.get(int(m))
            if fit is None or abs(fit["frequency_hz"] - f) > 0.1:
                print(f"    (m, f) = ({m}, {f:g} Hz): not found   MISSED")
                met.append(False)
                continue
            label = f"m={m:+d} {f:g} Hz"
            met.append(
                row(
                    f"{label} incoming (m)",
                    fit["incoming_amplitude_m"],
                    fit["incoming_stderr_m"],
                    abs(wave_in),
                    0.03,
                )
            )
            met.append(
                row(
                    f"{label} outgoing (m)",
                    fit["outgoing_amplitude_m"],
                    fit["outgoing_stderr_m"],
                    abs(wave_out),
                    0.03,
                )
            )
            met.append(
                row(
                    f"{label} in/out",
                    fit["incoming_over_outgoing"],
                    fit["incoming_over_outgoing_stderr"],
                    abs(wave_in) / abs(wave_out),
                    0.03,
                )
            )
        return met
    fit = summary["ringdown"]
    return [
        row(
            "frequency (Hz)",
            fit["frequency_hz"],
            fit["frequency_stderr_hz"],
            float(t["frequency_hz"]),
            0.005,
        ),
        row(
            "decay (1/s)",
            fit["decay_per_s"],
            fit["decay_stderr_per_s"],
            float(t["decay_per_s"]),
            0.05,
        ),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--scenarios", nargs="+", choices=list(SCENARIOS), default=list(SCENARIOS))
    parser.add_argument("--keep", type=Path, help="keep (and reuse) the recordings here")
    args = parser.parse_args()
    print(machine())
    folder = args.keep or Path(tempfile.mkdtemp(prefix="accuracy_waves_"))
    folder.mkdir(parents=True, exist_ok=True)
    met: list[bool] = []
    try:
        for scenario in args.scenarios:
            simulated, analysis = SCENARIOS[scenario]
            for seed in args.seeds:
                print(f"{scenario}, seed {seed}:")
                recording = folder / f"{scenario}-{seed}.h5"
                out = folder / f"{scenario}-{seed}"
                if not recording.exists():
                    holoview(f"simulate {recording} {OPTICS} --seed {seed} {simulated}")
                took = holoview(
                    f"process {recording} --out {out} --maps --reference absolute --overwrite"
                )
                took_waves = holoview(
                    f"waves {out / 'results.h5'} --out {out / 'waves'} --overwrite {analysis}"
                )
                print(f"    (process {took:.0f} s, waves {took_waves:.1f} s)")
                summary = json.loads((out / "waves" / "waves.json").read_text())
                with h5py.File(recording, "r") as f:
                    met += compare(scenario, summary, f["truth/waves"])
    finally:
        if args.keep is None:
            shutil.rmtree(folder, ignore_errors=True)
    print(f"{sum(met)} of {len(met)} values within their targets")


if __name__ == "__main__":
    main()
