"""The map path's floor (issue 23), for ``bench_demodulation.py --floor``.

At 1024 x 1024, one thread, side by side in one run on the same float32 frames:

- one real FFT of the frame (pyFFTW, float32, the copy into its aligned input included);
- ``Demodulator.process`` with 4 and with 1 carrier (the bench's RB1, RF, FB1, RB2;
  RB1 alone), at its defaults (relative reference, ``unwrap="auto"``) on a surface of
  travelling waves (10 nm each, so the frame-to-frame maps hold no wrap), with
  ``unwrap="never"``, and on frames alternating flat and a 1 um bump (every map wraps:
  the guide is unwrapped in space, the others against it);
- the carrier probe (every carrier's mean phase), for scale;
- PyHoloscope 1.1.3's real-FFT path (``off_axis_demod(..., real_fft=True)`` on the
  float32 frame, RB1's crop and the same Tukey window as its mask), run by
  ``peer_pyholoscope.py`` in a child process with the interpreter of a separate
  virtual environment (``--peers``): PyHoloscope is no dependency of holoview.

The cases take turns, a few calls each, round after round, so that a shared machine's
changing load falls on all of them alike; ratios are the median over rounds of the ratio
of the rounds' medians, by the wall clock and by each thread's CPU time (what the code
itself took, when other work shares the cores). Then where the time of ``process``
goes (cProfile, per frame), and the rest of the map path (``map_path.py``: trusted maps,
co-registration, fusion, writing).
"""

from __future__ import annotations

import cProfile
import json
import os
import pstats
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from map_path import run_map_path

from holoview.processing.fourier.fftplans import rfft2_plan
from holoview.processing.fourier.half_spectrum import ROW_CHUNK
from holoview.processing.fourier.windows import (
    DEFAULT_TAPER,
    DEFAULT_WINDOW,
    radial_window,
    wrap_frequency,
)
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.peaks.detection import Peak
from holoview.processing.series.carrier_probe import CarrierProbe

SHAPE = (1024, 1024)
#: Calls of each case per round.
PER_ROUND = 4
#: The environment variable that may name the peers' interpreter.
PEERS_ENV = "HOLOVIEW_PEERS_PYTHON"
PEER_SCRIPT = Path(__file__).with_name("peer_pyholoscope.py")
INSTALL = (
    "python3 -m venv peers && peers/bin/pip install numpy==2.4.6 scipy==1.17.1 "
    "pyfftw==0.15.1 pyholoscope==1.1.3"
)


class Peer:
    """PyHoloscope's real-FFT path in a child process (``peer_pyholoscope.py``)."""

    def __init__(self, python: str, frames: list[np.ndarray], peak: Peak, radius: float) -> None:
        rows, cols = frames[0].shape
        fx, fy = peak.carrier
        if fx < 0:  # the real FFT holds the twin with fx > 0
            fx, fy = -fx, -fy
        centre = (round(fy * rows) % rows, round(fx * cols))
        half = int(np.ceil(radius * max(rows, cols))) + 1
        y, x = np.mgrid[-half:half, -half:half]
        # the crop is centred on the carrier's bin: the window around the sub-bin carrier
        rho = np.hypot(
            wrap_frequency((y + centre[0]) / rows - fy), wrap_frequency((x + centre[1]) / cols - fx)
        )
        mask = radial_window(DEFAULT_WINDOW, rho, radius, taper=DEFAULT_TAPER)
        self._dir = tempfile.TemporaryDirectory(prefix="holoview-peer-")
        folder = Path(self._dir.name)
        np.save(folder / "frames.npy", np.array(frames, dtype=np.float32))
        np.save(folder / "mask.npy", mask.astype(np.complex64))
        self._child = subprocess.Popen(
            [python, str(PEER_SCRIPT)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env={**os.environ, "OMP_NUM_THREADS": "1"},
        )
        setup = {
            "frames": str(folder / "frames.npy"),
            "mask": str(folder / "mask.npy"),
            "centre": centre,
            "radius": half,
        }
        self.hello = self._ask(setup)

    def _ask(self, message: dict) -> dict:
        assert self._child.stdin is not None and self._child.stdout is not None
        self._child.stdin.write(json.dumps(message) + "\n")
        self._child.stdin.flush()
        line = self._child.stdout.readline()
        if not line:
            raise RuntimeError("the PyHoloscope child ended without an answer")
        return json.loads(line)

    def times(self, calls: int) -> dict[str, list[float]]:
        """Wall and CPU times (s, ``"seconds"`` and ``"cpu"``) of ``calls`` demodulations."""
        return self._ask({"calls": calls})

    def close(self) -> None:
        if self._child.stdin is not None:
            self._child.stdin.write("\n")
            self._child.stdin.close()
        self._child.wait(timeout=30)
        self._dir.cleanup()


def peers_python(given: str | None) -> tuple[str | None, str]:
    """The peers' interpreter, or None and why not."""
    python = given or os.environ.get(PEERS_ENV)
    if not python:
        return None, f"no --peers interpreter given (nor ${PEERS_ENV}); to add it: {INSTALL}"
    probe = subprocess.run(
        [python, "-c", "import pyholoscope"], capture_output=True, text=True, check=False
    )
    if probe.returncode:
        return None, f"{python} cannot import pyholoscope; install it with: {INSTALL}"
    return python, ""


def floor_frames(
    peaks: list[Peak], synth: Callable, bump: Callable, waves: Callable, count: int = 8
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Float32 frames: travelling waves back and forth, and flat / 1 um bump alternating."""
    rng = np.random.default_rng(23)
    y, x = np.mgrid[: SHAPE[0], : SHAPE[1]].astype(float)
    moving = [synth(SHAPE, peaks, waves(t, y, x), rng).astype(np.float32) for t in range(count)]
    moving += moving[-2:0:-1]  # back and forth: each frame follows a neighbour
    wrapped = [
        synth(SHAPE, peaks, 0.0, rng).astype(np.float32),
        synth(SHAPE, peaks, bump(SHAPE, 1.0e-6, SHAPE[0] / 7), rng).astype(np.float32),
    ]
    return moving, wrapped


def _stepper(demod: Demodulator, sequence: list[np.ndarray]) -> Callable[[int], object]:
    """A case: call ``k`` demodulates frame ``k`` of the sequence (cyclically)."""

    def step(k: int) -> object:
        return demod.process(sequence[k % len(sequence)])

    return step


def run_floor(
    targets: list[tuple[str, str]],
    peaks: list[Peak],
    frames: tuple[list[np.ndarray], list[np.ndarray]],
    *,
    wavelength: float,
    rounds: int,
    peers: str | None,
) -> None:
    """Print the floor's figures and ratios, and add the issue's two targets."""
    moving, wrapped = frames
    plan = rfft2_plan(SHAPE, threads=1)
    cases: dict[str, Callable[[int], object]] = {}

    def fft(k: int) -> None:
        np.copyto(plan.input_array, moving[k % len(moving)], casting="unsafe")
        plan.execute()

    cases["one float32 rfft2 (copy included)"] = fft

    def convert(k: int) -> None:  # the copy alone, as the half spectrum makes it
        frame = moving[k % len(moving)]
        for start in range(0, SHAPE[0], ROW_CHUNK):
            rows = slice(start, start + ROW_CHUNK)
            np.copyto(chunk[: frame[rows].shape[0]], frame[rows], casting="unsafe")

    chunk = np.empty((ROW_CHUNK, SHAPE[1]), dtype=np.float32)
    cases["frame -> float32 copy alone"] = convert
    for count in (4, 1):
        chosen = peaks[:count]
        for unwrap, sequence in (("auto", moving), ("never", moving), ("auto", wrapped)):
            demod = Demodulator(SHAPE, chosen, wavelength=wavelength, unwrap=unwrap, threads=1)
            what = "wrapping" if sequence is wrapped else "waves"
            name = f"{count} carrier{'s' if count > 1 else ''}, unwrap {unwrap}, {what}"
            cases[name] = _stepper(demod, sequence)
    probe = CarrierProbe(SHAPE, peaks)
    cases["carrier probe, 4 carriers"] = lambda k: probe.measure(moving[k % len(moving)])
    rb1 = Demodulator(SHAPE, peaks[:1], threads=1)
    python, why = peers_python(peers)
    peer = None
    if python is not None:
        peer = Peer(python, moving, peaks[0], rb1.radii[0])
        print(f"PyHoloscope {peer.hello['version']} in {python}: crop {peer.hello['shape']}")
    else:
        print(f"PyHoloscope skipped: {why}")
    # per case, per clock (wall, the thread's CPU time), per round: the calls' seconds
    times: dict[str, dict[str, list[list[float]]]] = {
        name: {"wall": [], "cpu": []} for name in cases
    }
    for k in range(2):  # plans, references, caches
        for fn in cases.values():
            fn(k)
    calls = 0
    peer_name = "PyHoloscope 1.1.3 real_fft, 1 carrier"
    if peer is not None:
        times[peer_name] = {"wall": [], "cpu": []}
    for _ in range(rounds):
        for name, fn in cases.items():
            wall, cpu = [], []
            for _ in range(PER_ROUND):
                start, start_cpu = time.perf_counter(), time.thread_time()
                fn(calls)
                cpu.append(time.thread_time() - start_cpu)
                wall.append(time.perf_counter() - start)
                calls += 1
            times[name]["wall"].append(wall)
            times[name]["cpu"].append(cpu)
        if peer is not None:
            answer = peer.times(PER_ROUND)
            times[peer_name]["wall"].append(answer["seconds"])
            times[peer_name]["cpu"].append(answer["cpu"])
    if peer is not None:
        peer.close()
    fft_name = "one float32 rfft2 (copy included)"

    def versus(a: str, b: str, clock: str) -> tuple[float, float]:
        """Median over rounds of the ratio of the rounds' medians; best over best."""
        rounds_ratio = statistics.median(
            statistics.median(x) / statistics.median(y)
            for x, y in zip(times[a][clock], times[b][clock], strict=True)
        )
        best = min(t for r in times[a][clock] for t in r) / min(
            t for r in times[b][clock] for t in r
        )
        return rounds_ratio, best

    print(
        f"{'case':>40} {'wall: median':>12} {'best':>6} {'/ rfft2':>7}   "
        f"{'CPU: median':>11} {'best':>6} {'/ rfft2':>7}  (ms)"
    )
    for name, clocks in times.items():
        row = f"{name:>40}"
        for clock in ("wall", "cpu"):
            flat = [t for r in clocks[clock] for t in r]
            ratio = versus(name, fft_name, clock)[0]
            row += f" {1e3 * statistics.median(flat):12.2f} {1e3 * min(flat):6.2f} {ratio:7.2f}  "
        print(row)
    print(
        "(on a machine shared with other work, the wall clock holds the others' load; the "
        "CPU time is this thread's own)"
    )
    for clock in ("wall", "cpu"):
        four = versus("4 carriers, unwrap auto, waves", fft_name, clock)
        verdict = "met" if four[0] <= 2 else "MISSED"
        targets.append(
            (
                f"4 carriers at the defaults within 2 x one float32 rfft2 ({clock})",
                f"{verdict} (median of rounds {four[0]:.2f} x, best/best {four[1]:.2f} x)",
            )
        )
        if peer is None:
            targets.append(
                (f"1 carrier faster than PyHoloscope 1.1.3's real-FFT path ({clock})", "not run")
            )
            continue
        one = versus("1 carrier, unwrap auto, waves", peer_name, clock)
        verdict = "met" if one[0] < 1 else "MISSED"
        targets.append(
            (
                f"1 carrier faster than PyHoloscope 1.1.3's real-FFT path ({clock})",
                f"{verdict} (median of rounds {one[0]:.2f} x its time, best/best {one[1]:.2f} x)",
            )
        )
    profile(peaks, moving, wrapped, wavelength)
    run_map_path(peaks, moving, wavelength=wavelength, rounds=rounds)


#: The functions whose time :func:`profile` reports, by the name cProfile gives them.
STEPS = (
    ("half_spectrum.py", "_rows", "conversion to float32 and the rows' FFT"),
    ("half_spectrum.py", "_floor_samples", "FFT of the noise floor's columns"),
    ("half_spectrum.py", "_columns", "FFT of the windows' columns"),
    ("phase_maps.py", "floor_power", "noise floor of the spectrum"),
    ("box_maps.py", "invert_box", "cut and window the boxes, inverse FFTs"),
    ("box_maps.py", "trusted_pixels", "masks (|f|^2, threshold, border)"),
    ("fastmath.py", "angle", "phases"),
    ("phase_maps.py", "phase_noise", "noise of each map"),
    ("box_maps.py", "trusted_level", "level of each map (its 2 pi offset)"),
    ("box_maps.py", "phase_map", "rest of the per-peak step (mean, product)"),
    ("unwrap.py", "has_wraps", "wrap checks (every caller)"),
    ("phase_maps.py", "unwrap_maps", "unwrapping (the guide's wrap bounds included)"),
    ("demodulate.py", "_finish", "2 pi offset, delta-h"),
    ("demodulate.py", "process", "the whole call"),
)


def profile(
    peaks: list[Peak], moving: list[np.ndarray], wrapped: list[np.ndarray], wavelength: float
) -> None:
    """Print where the time of ``process`` goes (4 carriers, defaults), per frame."""
    for what, sequence in (("waves", moving), ("wrapping", wrapped)):
        demod = Demodulator(SHAPE, peaks, wavelength=wavelength, threads=1)
        for k in range(2):
            demod.process(sequence[k])
        profiler = cProfile.Profile(time.perf_counter)
        count = 40
        profiler.enable()
        for k in range(count):
            demod.process(sequence[k % len(sequence)])
        profiler.disable()
        stats = pstats.Stats(profiler).stats  # type: ignore[attr-defined]
        whole = next(
            total
            for (path, _, name), (_, _, _, total, _) in stats.items()
            if path.endswith("demodulate.py") and name == "process"
        )
        print(
            f"\nwhere the time goes, 4 carriers, defaults, {what} (ms per frame under "
            "cProfile, which adds its own time to every Python call; share of the call):"
        )
        for module, function, label in STEPS:
            for (path, _, name), (_, _, own, total, _) in stats.items():
                if path.endswith(module) and name == function:
                    value = own if function == "phase_map" else total
                    print(f"{label:>56}: {1e3 * value / count:6.3f} {100 * value / whole:5.1f} %")
                    break
        sys.stdout.flush()
