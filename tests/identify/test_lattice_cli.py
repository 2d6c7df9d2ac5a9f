"""``holoview simulate --scenario evaporation``, then the lattice and ``process --auto`` name it."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from holoview.acquire.recording_reader import RecordingReader
from holoview.cli import main
from holoview.processing.naming.lattice import identify_lattice
from holoview.processing.naming.lattice_geometry import LatticeKind
from holoview.processing.peaks.detection import find_peaks

NAMED = ("RF", "RB1", "FB1", "RB2", "FB2")


def _apart(a, b, shape) -> float:
    delta = (np.subtract(a, b) + 0.5) % 1.0 - 0.5
    return float(np.hypot(delta[0] * shape[1], delta[1] * shape[0]))


def test_simulated_evaporation_is_named_by_the_lattice(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """The issue's case: the RF peak was named ``P1 (unexplained)`` by its PCA prefactor
    (1.031 against 1.000); by its carrier it is RF. The recording's defaults (512 x 512).

    Each name must fall on the detected peak nearest that family's true carrier. FB2 is
    weak at 512 x 512: its detected carrier lies 0.5 to 1.2 bins from the truth in 30
    seeds of 100, so the test fixes a seed (``bench_lattice.py`` covers random setups).
    """
    path = tmp_path / "evaporation.h5"
    simulate = ["simulate", str(path), "--scenario", "evaporation", "--frames", "40"]
    assert main(["-q", *simulate, "--seed", "24"]) == 0
    with RecordingReader(path) as reader:
        first = np.asarray(reader[0])
        n1, n2 = reader.setup["n1"], reader.setup["n2"]
    with h5py.File(path, "r") as f:
        labels = [s.decode() for s in f["truth/families/label"][:]]
        carriers = f["truth/families/carrier_cpp"][:]
    truth = dict(zip(labels, carriers, strict=True))
    peaks = find_peaks(first)
    ident = identify_lattice(
        [p.carrier for p in peaks], first.shape, n1, n2, amplitudes=[p.amplitude for p in peaks]
    )
    flips = set()
    for label in NAMED:
        p = ident.peak(label)
        assert p.kind is LatticeKind.FIRST_ORDER
        folded = (np.asarray(truth[label]) + 0.5) % 1.0 - 0.5
        direct = _apart(p.carrier, folded, first.shape)
        flips.add(direct > 2.0)
        distances = [
            min(_apart(q.carrier, folded, first.shape), _apart(q.carrier, -folded, first.shape))
            for q in peaks
        ]
        assert p.index == int(np.argmin(distances)), label
        assert min(distances) < 2.0, label
    assert len(flips) == 1  # one global twin
    out = tmp_path / "auto"
    assert main(["-q", "process", str(path), "--out", str(out), "--auto", "8"]) == 0
    capsys.readouterr()
    summary = json.loads((out / "summary.json").read_text())
    assert set(NAMED) <= set(summary["peaks"])
    for label in NAMED:
        assert "unexplained" not in summary["peaks"][label]["flags"]
