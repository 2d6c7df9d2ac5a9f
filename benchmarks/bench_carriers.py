"""Carrier values per frame: the separable-DFT probe against one FFT and the whole demodulation.

Run from the repository root::

    .venv/bin/python benchmarks/bench_carriers.py            # about 4 minutes
    .venv/bin/python benchmarks/bench_carriers.py --quick    # 1024^2 only, 100 frames

Prints, after the machine (CPU model, vector extensions, cores, load average):

1. per-frame time at 1024^2 and 2048^2 with 5 and 6 peaks (uint16 frames), medians,
   90th percentiles and best over rounds that interleave the candidates (so that the
   load of a shared machine falls on all alike): the probe
   (:class:`~holoview.processing.series.carrier_probe.CarrierProbe`, with and without its
   noise estimate), one single-threaded real FFT (pyFFTW, the frame copied into its
   float32 buffer first, as the demodulator does), and the whole
   ``Demodulator.process`` (one FFTW thread, relative reference, no unwrapping), with
   the ratios;
2. what was tried on the probe: input dtypes, one whole-frame matrix product (BLAS
   threads as OpenBLAS likes) against the probe's row blocks, the column count of the
   product, the rebuild when the carriers change, an aperture;
3. leakage: on noise-free simulated frames of a uniform level swept over 5 um (every
   relative phase turns), the worst phase error of each setup's peaks against the level,
   for the automatic taper, no taper, a Hann window and the map path's carrier value,
   beside the weakest peak's mean-phase shot noise;
4. equality with the map path on ``holoview simulate`` recordings (evaporation at
   60 um/min and waves, 1024^2, 60 frames/s): per peak the rms difference of the two
   unwrapped mean-phase series (rad and nm) against each series' own noise, the fitted
   rates with their standard errors, and the per-frame cost of each path in that loop;
5. the targets, met or missed.

Timings on a shared machine are noisy: read the load average printed with them.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
from machine import machine

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from holoview.acquire.recording_reader import RecordingReader  # noqa: E402
from holoview.cli import main as holoview_main  # noqa: E402
from holoview.optics.families import predict_families  # noqa: E402
from holoview.optics.setup import Ghost, Setup  # noqa: E402
from holoview.optics.synthesis import HologramSynthesizer  # noqa: E402
from holoview.processing.fourier.fftplans import rfft2_plan  # noqa: E402
from holoview.processing.maps.demodulate import Demodulator  # noqa: E402
from holoview.processing.peaks.detection import Peak  # noqa: E402
from holoview.processing.series.carrier_probe import CarrierProbe  # noqa: E402
from holoview.processing.series.phase_series import unwrap_in_time  # noqa: E402
from holoview.processing.series.rate_fits import fit_rate  # noqa: E402

#: The issue's figures on a 2-core AVX2 machine, ms: separable DFT at 5 carriers of 1024^2.
ISSUE_PROBE_MS = 1.7
#: One single-threaded rfft2 and the whole demodulation, 1024^2, ms (issue 17).
ISSUE_RFFT_MS, ISSUE_DEMOD_MS = 4.7, 9.0
EVAPORATION_UM_PER_MIN = 60.0


def interleaved(tests: dict[str, Callable[[], object]], rounds: int) -> dict[str, np.ndarray]:
    """Time each callable once per round, in turn; return the times in ms per name."""
    for fn in tests.values():
        fn()
    times: dict[str, list[float]] = {name: [] for name in tests}
    for _ in range(rounds):
        for name, fn in tests.items():
            start = time.perf_counter()
            fn()
            times[name].append(1e3 * (time.perf_counter() - start))
    return {name: np.array(t) for name, t in times.items()}


def summary(ms: np.ndarray) -> str:
    return f"median {np.median(ms):7.3f}  p90 {np.percentile(ms, 90):7.3f}  best {ms.min():7.3f} ms"


def simulator_peaks(setup: Setup, count: int) -> list[Peak]:
    """The brightest families with distinct carriers (second orders last), as peaks."""
    families = predict_families(setup)
    families.sort(key=lambda f: (f.kind == "second-order", -f.amplitude))
    peaks: list[Peak] = []
    for family in families:
        c = family.observed_carrier
        if family.alpha <= 0 or any(math.dist(c, p.carrier) < 1e-6 for p in peaks):
            continue
        peaks.append(
            Peak(c, max(family.amplitude, 1e-3), 100.0, label=family.label, alpha=family.alpha)
        )
        if len(peaks) == count:
            break
    return peaks


def speed(sizes: list[int], counts: list[int], rounds: int) -> dict[tuple[int, int], dict]:
    """Section 1: probe, one rfft2, the whole demodulation."""
    print("\n1. Per-frame time, uint16 frames (12-bit values), rounds interleaved")
    out = {}
    rng = np.random.default_rng(0)
    for n in sizes:
        frame = rng.integers(0, 4096, (n, n), dtype=np.uint16)
        plan = rfft2_plan((n, n), threads=1)

        def fft(plan=plan, frame=frame) -> None:
            np.copyto(plan.input_array, frame, casting="unsafe")
            plan.execute()

        for count in counts:
            peaks = simulator_peaks(Setup(shape=(n, n)), count)
            probe = CarrierProbe((n, n), peaks)
            quiet = CarrierProbe((n, n), peaks, noise=False)
            demod = Demodulator((n, n), peaks, reference="relative", unwrap="never", threads=1)
            times = interleaved(
                {
                    "probe, noise estimate": lambda p=probe, f=frame: p.measure(f),
                    "probe, values only": lambda p=quiet, f=frame: p.measure(f),
                    "rfft2, 1 thread (copy + FFT)": fft,
                    "Demodulator.process, 1 thread": lambda d=demod, f=frame: d.process(f),
                },
                rounds if n <= 1024 else max(10, rounds // 3),
            )
            print(
                f"  {n}^2, {count} peaks (taper {probe.taper[0]:.3f}, "
                f"noise x{probe.noise_gain:.3f}):"
            )
            for name, ms in times.items():
                print(f"    {name:32s} {summary(ms)}")
            p = float(np.median(times["probe, noise estimate"]))
            f = float(np.median(times["rfft2, 1 thread (copy + FFT)"]))
            d = float(np.median(times["Demodulator.process, 1 thread"]))
            print(
                f"    ratios (medians): rfft2 / probe {f / p:.2f}, demodulation / probe {d / p:.2f}"
            )
            out[(n, count)] = {"probe": p, "rfft": f, "demod": d}
    return out


def variants(n: int, rounds: int) -> None:
    """Section 2: what was tried on the probe."""
    print(f"\n2. What was tried, {n}^2, 5 peaks")
    rng = np.random.default_rng(1)
    u16 = rng.integers(0, 4096, (n, n), dtype=np.uint16)
    peaks = simulator_peaks(Setup(shape=(n, n)), 5)
    probe = CarrierProbe((n, n), peaks, noise=False)
    y, x = np.mgrid[:n, :n]
    aperture = np.hypot(y - n / 2, x - n / 2) < 0.45 * n
    with_aperture = CarrierProbe((n, n), peaks, noise=False, aperture=aperture)
    columns = {w: rng.standard_normal((n, w)).astype(np.float32) for w in (8, 10, 11, 12, 16)}
    f32 = u16.astype(np.float32)

    def blocked(width: int) -> Callable[[], None]:
        step = max(1, 262144 // (n * width))
        block = np.empty((step, n), dtype=np.float32)
        out = np.empty((n, width), dtype=np.float32)

        def run() -> None:
            for start in range(0, n, step):
                stop = min(start + step, n)
                np.copyto(block[: stop - start], u16[start:stop], casting="unsafe")
                np.matmul(block[: stop - start], columns[width], out=out[start:stop])

        return run

    whole = np.empty((n, 16), dtype=np.float32)
    tests: dict[str, Callable[[], object]] = {
        "probe, uint16": lambda: probe.measure(u16),
        "probe, uint8": lambda: probe.measure((u16 >> 4).astype(np.uint8)),
        "probe, float32": lambda: probe.measure(f32),
        "probe, float64": lambda: probe.measure(u16.astype(np.float64)),
        "probe, uint16 strided view": lambda: probe.measure(u16[:, ::-1]),
        "probe, uint16, aperture": lambda: with_aperture.measure(u16),
        "rebuild: with_carriers": lambda: probe.with_carriers(peaks[::-1]),
        "uint16 -> float32, whole frame": lambda: f32.__setitem__(Ellipsis, u16),
        "one whole-frame product, 16 columns": lambda: np.matmul(f32, columns[16], out=whole),
    }
    for width in columns:
        tests[f"row blocks, {width:2d} columns"] = blocked(width)
    times = interleaved(tests, rounds)
    print(
        f"    (uint8 and float64 include making the converted copy; OPENBLAS_NUM_THREADS="
        f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')})"
    )
    for name, ms in times.items():
        print(f"    {name:38s} {summary(ms)}")


def leakage_of(setup: Setup, count: int, levels: int = 40) -> dict[str, tuple[float, float, float]]:
    """Worst phase error (rad, nm) over the peaks of a uniform-level sweep, per method."""
    peaks = simulator_peaks(setup, count)
    rows, cols = setup.shape
    probes = {
        "automatic taper": CarrierProbe(setup.shape, peaks, noise=False),
        "no taper": CarrierProbe(setup.shape, peaks, taper=0.0, noise=False),
        "Hann": CarrierProbe(setup.shape, peaks, taper=1.0, noise=False),
    }
    if setup.aperture_radius:
        y, x = np.mgrid[:rows, :cols]
        stop = (
            np.hypot(y - (rows - 1) / 2, x - (cols - 1) / 2)
            <= setup.aperture_radius / setup.pixel_pitch
        )
        probes["automatic taper + aperture"] = CarrierProbe(
            setup.shape, peaks, noise=False, aperture=stop
        )
    demod = Demodulator(setup.shape, peaks, reference="synthetic", unwrap="never", threads=1)
    synthesizer = HologramSynthesizer(setup, noise="none")
    alphas = np.array([p.alpha for p in peaks])
    ratios: dict[str, list[np.ndarray]] = {name: [] for name in (*probes, "map path")}
    for level in np.random.default_rng(1).uniform(0, 5e-6, levels):
        photons = synthesizer.intensity(level).astype(np.float64)
        image = np.clip(photons / setup.saturation, 0, 1) ** setup.gamma * setup.max_value
        truth = np.exp(1j * 4 * np.pi / setup.wavelength * alphas * level)
        for name, probe in probes.items():
            ratios[name].append(probe.measure(image).values / truth)
        ratios["map path"].append(
            np.array([r.carrier_value for r in demod.process(image).peaks]) / truth
        )
    out = {}
    for name, values in ratios.items():
        z = np.array(values)
        error = np.abs(np.angle(z * np.conj(np.mean(z / np.abs(z), axis=0)))).max(axis=0)
        nm = error * setup.wavelength / (4 * np.pi * alphas) * 1e9
        gain = probes[name].noise_gain if name in probes else 1.0
        out[name] = (float(error.max()), float(nm.max()), gain)
    weakest = min(p.amplitude for p in peaks)
    out["shot noise of the weakest peak"] = (
        probes["automatic taper"].noise_gain
        / (weakest * math.sqrt(2 * setup.photons_per_pixel * rows * cols)),
        math.nan,
        math.nan,
    )
    return out


def leakage(sizes: list[int]) -> float:
    """Section 3; returns the automatic taper's worst error over the weakest peak's shot noise."""
    print(
        "\n3. Leakage: worst phase error over the peaks of a uniform level swept over 5 um "
        "(noise-free frames)"
    )
    worst = 0.0
    for n in sizes:
        pitch = 20e-6
        base = Setup(shape=(n, n))
        setups = {
            "default bench, 5 peaks": (base, 5),
            "Gaussian beam": (base.replace(beam_waist=0.6 * n * pitch), 5),
            "field stop (r = 0.45 side)": (base.replace(aperture_radius=0.45 * n * pitch), 5),
            "reference ghost, 6 peaks": (
                base.replace(ghosts=(Ghost("reference", (0.4e-3, -0.3e-3), 0.1),)),
                6,
            ),
            "other tilts": (base.replace(m_r=(1.5e-3, 0.3e-3), m_b=(-0.9e-3, 0.8e-3)), 5),
            "gamma 0.7 (+ 2RB1)": (base.replace(gamma=0.7), 6),
            "near carriers": (base.replace(m_r=(1.0e-3, 0.6e-3), m_b=(-0.3e-3, 0.8e-3)), 5),
        }
        for name, (setup, count) in setups.items():
            result = leakage_of(setup, count)
            cells = "  ".join(
                f"{k}: {rad:.1e} rad"
                + ("" if math.isnan(nm) else f" {nm:.4f} nm")
                + ("" if math.isnan(g) else f" (noise x{g:.2f})")
                for k, (rad, nm, g) in result.items()
            )
            print(f"  {n}^2 {name:28s} {cells}")
            tapered = result.get("automatic taper + aperture", result["automatic taper"])
            worst = max(worst, tapered[0] / result["shot noise of the weakest peak"][0])
    return worst


def simulate_file(folder: Path, scenario: str, size: int, frames: int) -> Path:
    path = folder / f"{scenario}.h5"
    extra = (
        ["--evaporation-um-per-min", str(EVAPORATION_UM_PER_MIN)]
        if scenario == "evaporation"
        else []
    )
    argv = [
        "-q",
        "simulate",
        str(path),
        "--scenario",
        scenario,
        "--size",
        str(size),
        "--frames",
        str(frames),
        "--fps",
        "60",
        "--seed",
        "5",
        *extra,
    ]
    if holoview_main(argv) != 0:
        raise SystemExit(f"holoview simulate {scenario} failed")
    return path


def truth_phases(f: h5py.File, peaks: list[Peak], wavelength: float) -> np.ndarray:
    """Per frame and peak, the phase the true mean height (and reference jitter) gives, rad.

    ``4 pi alpha h / wavelength``, plus the reference arm's phase for RF and RB_j, with
    the sign that fits the series best (the stored twins of RF and RB_j see it with
    opposite signs).
    """
    height = f["truth/mean_height_m"][:]
    reference = f["truth/reference_phase_rad"][:]
    alphas = np.array([p.alpha for p in peaks])
    base = 4 * np.pi / wavelength * np.outer(height - height[0], alphas)
    return base, reference - reference[0]


def versus_truth(series: np.ndarray, base: np.ndarray, reference: np.ndarray, label: str) -> float:
    """Rms (rad) of a peak's unwrapped series against the truth, offset removed."""
    signs = (1.0, -1.0) if label.startswith("R") else (0.0,)
    best = math.inf
    for sign in signs:
        d = series - base - sign * reference
        best = min(best, float(np.sqrt(np.mean((d - d.mean()) ** 2))))
    return best


def equality(size: int, frames: int) -> dict[str, list[float]]:
    """Section 4; returns per scenario and peak rms(probe - map) over the shot noise, and the
    rates' difference over their standard error."""
    print(
        f"\n4. Equality with the map path: holoview simulate, {size}^2, {frames} frames, "
        "60 frames/s"
    )
    print(
        "   per peak: rms of the difference of the unwrapped series (offset removed); each "
        "series' rms error against the truth\n   (true mean height and reference jitter); "
        "the probe's shot-noise estimate; the fitted rates"
    )
    ratios: dict[str, list[float]] = {"noise": [], "rate": []}
    with tempfile.TemporaryDirectory() as folder:
        for scenario in ("evaporation", "waves"):
            start = time.perf_counter()
            path = simulate_file(Path(folder), scenario, size, frames)
            made = time.perf_counter() - start
            with h5py.File(path, "r") as f:
                fam = f["truth/families"]
                labels = [s.decode() for s in fam["label"][:]]
                peaks: list[Peak] = []
                for i in np.argsort(-fam["amplitude"][:]):
                    c = tuple(float(v) for v in fam["observed_carrier_cpp"][i])
                    if fam["alpha"][i] <= 0 or fam["kind"][i].decode() == "second-order":
                        continue
                    if any(math.dist(c, p.carrier) < 1e-6 for p in peaks):
                        continue
                    alpha = float(fam["alpha"][i])
                    amplitude = float(fam["amplitude"][i])
                    peaks.append(Peak(c, amplitude, 100.0, label=labels[i], alpha=alpha))
                    if len(peaks) == 5:
                        break
                wavelength = float(f["setup"].attrs["wavelength_m"])
                base, reference = truth_phases(f, peaks, wavelength)
            probe = CarrierProbe((size, size), peaks)
            demod = Demodulator(
                (size, size), peaks, reference="relative", unwrap="never", threads=1
            )
            probed, mapped, noise = [], [], []
            t_probe = t_demod = 0.0
            with RecordingReader(path) as reader:
                times = reader.t_device - reader.t_device[0]
                for image in reader:
                    t0 = time.perf_counter()
                    result = probe.measure(image)
                    t1 = time.perf_counter()
                    mapped.append([r.carrier_value for r in demod.process(image).peaks])
                    t_demod += time.perf_counter() - t1
                    t_probe += t1 - t0
                    probed.append(result.values)
                    noise.append(result.noise)
            up, um = unwrap_in_time(np.array(probed)), unwrap_in_time(np.array(mapped))
            own = np.nanmedian(np.array(noise), axis=0)
            n = len(up)
            print(
                f"  {scenario} (simulated in {made:.0f} s; taper {probe.taper[0]:.3f}, "
                f"noise x{probe.noise_gain:.3f}; per frame in this loop: probe "
                f"{1e3 * t_probe / n:.2f} ms, demodulation {1e3 * t_demod / n:.2f} ms)"
            )
            for j, peak in enumerate(peaks):
                nm = wavelength / (4 * np.pi * peak.alpha) * 1e9
                d = (up[:, j] - um[:, j]) - np.mean(up[:, j] - um[:, j])
                rms = float(np.sqrt(np.mean(d**2)))
                err_p = versus_truth(up[:, j], base[:, j], reference, peak.label or "")
                err_m = versus_truth(um[:, j], base[:, j], reference, peak.label or "")
                fp = fit_rate(times, up[:, j] * nm * 1e-9)
                fm = fit_rate(times, um[:, j] * nm * 1e-9)
                print(
                    f"    {peak.label:5s} probe - map {rms:.1e} rad {rms * nm:.3f} nm | vs truth: "
                    f"probe {err_p:.1e} map {err_m:.1e} rad | shot noise {own[j]:.1e} rad "
                    f"{own[j] * nm:.3f} nm | rate probe {fp.rate * 6e7:+.4f} +- "
                    f"{fp.stderr * 6e7:.4f}, map {fm.rate * 6e7:+.4f} +- "
                    f"{fm.stderr * 6e7:.4f} um/min"
                )
                if scenario == "evaporation":
                    ratios["noise"].append(rms / own[j])
                ratios["rate"].append(abs(fp.rate - fm.rate) / math.hypot(fp.stderr, fm.stderr))
    return ratios


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="1024^2 only, fewer rounds and frames")
    parser.add_argument("--frames", type=int, default=None, help="frames per simulated recording")
    args = parser.parse_args()
    quick = args.quick
    print(machine())
    threads = os.environ.get("OPENBLAS_NUM_THREADS", "unset")
    print(f"numpy {np.__version__}, OPENBLAS_NUM_THREADS={threads}")
    sizes = [1024] if quick else [1024, 2048]
    timings = speed(sizes, [5, 6], 30 if quick else 60)
    variants(1024, 20 if quick else 40)
    worst_leak = leakage([256] if quick else [256, 1024])
    frames = args.frames or (100 if quick else 200)
    ratios = equality(1024, frames)
    print("\n5. Targets")
    p = timings[(1024, 5)]["probe"]
    checks = [
        (
            f"probe at 1024^2, 5 peaks, under the issue's separable DFT ({ISSUE_PROBE_MS} ms)",
            p < ISSUE_PROBE_MS,
        ),
        (
            "probe at 1024^2, 5 peaks, under half of one single-threaded rfft2",
            p < 0.5 * timings[(1024, 5)]["rfft"],
        ),
        (
            "leakage of the automatic taper (with the aperture where there is a field stop) "
            "under a quarter of the weakest peak's shot noise, every setup",
            worst_leak < 0.25,
        ),
        (
            "evaporation: probe and map series differ by less than the per-frame shot noise, "
            "every peak",
            max(ratios["noise"]) < 1.0,
        ),
        (
            "evaporation and waves: the fitted rates of probe and map agree within one "
            "standard error, every peak",
            max(ratios["rate"]) < 1.0,
        ),
    ]
    for text, ok in checks:
        print(f"  [{'met' if ok else 'MISSED'}] {text}")
    print(f"  load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
