"""PyHoloscope's real-FFT demodulation timed in a process of its own, for a benchmark.

Run by ``bench_demodulation.py --floor`` with the interpreter of a separate virtual
environment that holds ``pyholoscope==1.1.3`` (never holoview's: PyHoloscope is no
dependency of holoview), so both are timed side by side on the same frames. It imports
nothing from holoview.

Protocol, one JSON object a line: the first line on stdin gives ``frames`` (a .npy
file, float32, shape (count, rows, cols): the calls take them in turn), ``centre``
((row, col) of the carrier in ``scipy.fft.rfft2``'s layout), ``radius`` (the crop's
half side, bins) and ``mask`` (a .npy file of the window on the crop, complex64); the
script answers ``{"version": ...}``. Then each line ``{"calls": N}`` is answered with
``{"seconds": [...], "cpu": [...]}``, the wall time and the thread's CPU time of each
of N calls of ``off_axis_demod(frame, centre, radius, real_fft=True, mask=mask)``; an
empty line ends it.
"""

from __future__ import annotations

import json
import sys
import time
from importlib.metadata import version

import numpy as np
import pyholoscope  # type: ignore[import-not-found]  # the peers' environment only


def main() -> int:
    setup = json.loads(sys.stdin.readline())
    frames = np.load(setup["frames"])
    mask = np.load(setup["mask"])
    centre = tuple(setup["centre"])
    radius = int(setup["radius"])

    turn = [0]

    def call() -> np.ndarray:
        frame = frames[turn[0] % len(frames)]
        turn[0] += 1
        return pyholoscope.off_axis_demod(frame, centre, radius, real_fft=True, mask=mask)

    field = call()
    print(json.dumps({"version": version("pyholoscope"), "shape": list(field.shape)}), flush=True)
    for line in sys.stdin:
        if not line.strip():
            break
        seconds, cpu = [], []
        for _ in range(int(json.loads(line)["calls"])):
            start, start_cpu = time.perf_counter(), time.thread_time()
            call()
            cpu.append(time.thread_time() - start_cpu)
            seconds.append(time.perf_counter() - start)
        print(json.dumps({"seconds": seconds, "cpu": cpu}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
