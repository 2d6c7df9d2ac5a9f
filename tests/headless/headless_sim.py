"""Helpers of the headless tests: small simulated recordings with their truth, the CLI in-process.

A module of its own (not ``conftest``) so that test modules import it by a unique name.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import pytest

from holoview.cli import main

#: Frame side, pixels; frames; frame rate, frames/s.
SIZE = 128
FRAMES = 120
FPS = 20.0
#: Evaporation, um/min (1e-6 m/s: RB1 steps 0.4 rad per frame, RB3 past pi).
EVAPORATION_UM_PER_MIN = 60.0


@dataclass(frozen=True)
class Simulated:
    """A simulated recording and what it was made from."""

    path: Path
    frames: int
    fps: float
    time_s: np.ndarray
    mean_height_m: np.ndarray
    carriers: dict[str, tuple[float, float]]
    alphas: dict[str, float]
    wavelength: float
    height_maps: np.ndarray | None

    @property
    def rate(self) -> float:
        """Fitted rate of the true mean height, m/s."""
        return float(np.polyfit(self.time_s, self.mean_height_m, 1)[0])

    def label_args(self, *labels: str) -> list[str]:
        """``--label L=fx,fy`` arguments at the true (stored-twin) carriers."""
        args = []
        for label in labels:
            fx, fy = self.carriers[label]
            args += ["--label", f"{label}={fx:.6f},{fy:.6f}"]
        return args


def simulate(path: Path, scenario: str, *extra: str) -> Simulated:
    """Run ``holoview simulate`` into ``path`` and read its truth back."""
    argv = ["-q", "simulate", str(path), "--scenario", scenario, "--size", str(SIZE)]
    argv += ["--frames", str(FRAMES), "--fps", str(FPS), "--seed", "3", *extra]
    assert main(argv) == 0
    with h5py.File(path, "r") as f:
        truth = f["truth"]
        families = truth["families"]
        labels = [s.decode() for s in families["label"][:]]
        carriers = {
            label: (float(c[0]), float(c[1]))
            for label, c in zip(labels, families["observed_carrier_cpp"][:], strict=True)
        }
        alphas = dict(zip(labels, map(float, families["alpha"][:]), strict=True))
        maps = truth["height_m"][:] if "height_m" in truth else None
        return Simulated(
            path=path,
            frames=FRAMES,
            fps=FPS,
            time_s=truth["time_s"][:],
            mean_height_m=truth["mean_height_m"][:],
            carriers=carriers,
            alphas=alphas,
            wavelength=float(f["setup"].attrs["wavelength_m"]),
            height_maps=maps,
        )


def run_cli(argv: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str, str]:
    """Run ``holoview ARGV`` in this process; return (status, stdout, stderr)."""
    status = main(argv)
    captured = capsys.readouterr()
    return status, captured.out, captured.err
