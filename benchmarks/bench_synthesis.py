"""Synthesis speed: what a simulated frame costs, and where the time goes.

Run from the repository root::

    .venv/bin/python benchmarks/bench_synthesis.py            # 256, 512, 1024; about 1 minute
    .venv/bin/python benchmarks/bench_synthesis.py --quick    # 1024 x 1024 only
    .venv/bin/python benchmarks/bench_synthesis.py --trace    # also the phase tracing at 1024

Prints, with the machine (CPU model, cores, load average), medians over frames:

1. per frame size, the fast synthesiser's full ``render`` (field sum, camera, noise) for
   a uniform level and for a standing-wave height map, with each noise model;
2. the breakdown at the largest size: the field sum (``field_parts``), ``|E|**2``, and
   the camera (noise + response + quantisation), uniform level and height map;
3. the budget of the live simulated camera (60 frames/s, 1024 x 1024: 16.7 ms) and
   the issue's target (well under 15 ms), marked met or missed for the fastest path;
4. the numerical phase tracing at 256 x 256 (and 1024 x 1024 with ``--trace``), and
   its ratio to the fast synthesis of the same surface.

Timings on a shared machine are noisy: read the load average printed with them.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from machine import machine

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from holoview.optics.camera import NOISE_MODELS  # noqa: E402
from holoview.optics.scenarios import ScenarioConfig, make_surface  # noqa: E402
from holoview.optics.setup import Setup  # noqa: E402
from holoview.optics.synthesis import HologramSynthesizer, pixel_coordinates  # noqa: E402
from holoview.optics.tracing import trace_fields  # noqa: E402


def median_ms(function: Callable[[], object], repeats: int) -> float:
    """Return the median wall time of ``function`` in milliseconds (after one warm-up)."""
    function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def waves(setup: Setup) -> np.ndarray:
    """Return a standing-wave height map of the setup's frame, m."""
    surface = make_surface(setup, "waves", ScenarioConfig(), np.random.default_rng(0))
    x, y = pixel_coordinates(setup)
    return np.broadcast_to(surface(0.1, x, y), setup.shape).copy()


def bench_render(sizes: list[int], repeats: int) -> dict[tuple[int, str, str], float]:
    """Print and return render times per (size, surface, noise)."""
    results: dict[tuple[int, str, str], float] = {}
    print("render: median ms per frame (uniform level | height map)")
    print(f"{'size':>6} " + " ".join(f"{noise:>17}" for noise in NOISE_MODELS))
    for size in sizes:
        setup = Setup(shape=(size, size))
        heights = waves(setup)
        row = []
        for noise in NOISE_MODELS:
            synthesizer = HologramSynthesizer(setup, noise=noise)
            rng = np.random.default_rng(1)
            level = median_ms(lambda s=synthesizer, r=rng: s.render(2e-8, rng=r), repeats)
            mapped = median_ms(lambda s=synthesizer, r=rng, h=heights: s.render(h, rng=r), repeats)
            results[(size, "level", noise)] = level
            results[(size, "map", noise)] = mapped
            row.append(f"{level:7.2f} | {mapped:7.2f}")
        print(f"{size:>6} " + " ".join(f"{cell:>17}" for cell in row))
    return results


def bench_breakdown(size: int, repeats: int) -> None:
    """Print where the time of one frame goes."""
    setup = Setup(shape=(size, size))
    heights = waves(setup)
    synthesizer = HologramSynthesizer(setup, noise="pooled")
    rng = np.random.default_rng(2)
    print(
        f"\nbreakdown at {size} x {size}, {len(synthesizer.beams)} beams "
        f"({', '.join(b.name for b in synthesizer.beams)}): median ms"
    )
    for name, h in (("uniform level", 2e-8), ("height map", heights)):
        field = median_ms(lambda h=h: synthesizer.field_parts(h), repeats)
        intensity = median_ms(lambda h=h: synthesizer._intensity(h, 0.0), repeats)
        print(f"  {name:>13}: field sum {field:6.2f}, + |E|^2 {intensity - field:5.2f}")
    lam = synthesizer.intensity(2e-8)
    for noise in NOISE_MODELS:
        camera = HologramSynthesizer(setup, noise=noise).camera
        cost = median_ms(lambda c=camera: c.expose(lam, rng), repeats)
        print(f"  camera ({noise:>8}): {cost:6.2f}")


def bench_trace(sizes: list[int]) -> None:
    """Print the phase tracing's cost beside the fast synthesis of the same surface."""
    print("\nphase tracing (one frame, standing waves), seconds")
    for size in sizes:
        setup = Setup(shape=(size, size))
        surface = make_surface(setup, "waves", ScenarioConfig(), np.random.default_rng(0))
        start = time.perf_counter()
        result = trace_fields(setup, lambda x, y, s=surface: s(0.1, x, y))
        traced = time.perf_counter() - start
        synthesizer = HologramSynthesizer(setup, noise="none")
        heights = waves(setup)
        fast = median_ms(lambda s=synthesizer, h=heights: s.intensity(h), 5) / 1e3
        print(
            f"  {size} x {size}: {traced:6.2f} s, {result.rays} rays, {result.passes} passes; "
            f"fast synthesis {1e3 * fast:.1f} ms: {traced / fast:.0f}x"
        )


def main() -> int:
    """Run the benchmark; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1024 x 1024 only")
    parser.add_argument("--trace", action="store_true", help="also trace at 1024 x 1024")
    parser.add_argument("--repeats", type=int, default=15, help="frames per median")
    args = parser.parse_args()
    print(f"machine: {machine()}")
    print(f"numpy {np.__version__}, python {platform.python_version()}\n")
    sizes = [1024] if args.quick else [256, 512, 1024]
    results = bench_render(sizes, args.repeats)
    bench_breakdown(1024, args.repeats)
    fastest = min(results[(1024, "level", noise)] for noise in ("pooled", "none"))
    budget = 1e3 / 60
    print(f"\nlive camera budget at 60 frames/s: {budget:.1f} ms per frame")
    print(
        f"uniform level, pooled noise, 1024 x 1024: {results[(1024, 'level', 'pooled')]:.2f} ms "
        f"({'met' if results[(1024, 'level', 'pooled')] < 15 else 'missed'}: target < 15 ms)"
    )
    print(
        f"height map, pooled noise, 1024 x 1024: {results[(1024, 'map', 'pooled')]:.2f} ms "
        f"({'met' if results[(1024, 'map', 'pooled')] < budget else 'missed'}: 60 frames/s)"
    )
    print(
        f"fastest 1024 x 1024 path: {fastest:.2f} ms; well under a second: "
        f"{'met' if max(results.values()) < 1000 else 'missed'}"
    )
    bench_trace([256, 1024] if args.trace else [256])
    print(f"\nload average after: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
