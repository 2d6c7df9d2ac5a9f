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


def test_peaks_names_a_ghost_the_model_does_not_label(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """A beam-splitter ghost of the reference arm repeats RB1, RF, RB2 at an offset. The
    recording's labels (the model) name no ghost; the table shows the lattice's name for
    it (``RB1~g0``) rather than a bare ``-`` beside its lattice indices."""
    path = tmp_path / "ghost.h5"
    simulate = ["simulate", str(path), "--scenario", "evaporation", "--frames", "1"]
    ghost = ["--ghost", "reference", "0.3", "-0.2", "0.3"]
    assert main(["-q", *simulate, "--size", "256", "--seed", "3", *ghost]) == 0
    capsys.readouterr()
    assert main(["peaks", str(path)]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[2:]]
    rows = [row for row in rows if row and row[0].isdigit()]
    named = {row[1] for row in rows}
    assert {"RB1", "RF", "RB1~g0", "RF~g0"} <= named
    for row in rows:  # a row on the lattice has a name
        assert row[1] != "-" or row[7] == "-", row
