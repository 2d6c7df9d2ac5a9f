"""``holoview peaks``: detected peaks, labels and twins, an experiment that ``process`` reads."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import tifffile
from headless_sim import Simulated, run_cli


def test_table_lists_the_detected_peaks(
    evaporation: Simulated, capsys: pytest.CaptureFixture
) -> None:
    status, out, _ = run_cli(["peaks", str(evaporation.path)], capsys)
    assert status == 0
    lines = out.strip().splitlines()
    count = int(lines[0].split(": ")[1].split()[0])
    assert count >= 4
    rows = [line for line in lines[2:] if line.split()[0].isdigit()]
    assert len(rows) == count
    assert "amplitude" in lines[1] and "flags" in lines[1]
    # the recording's own experiment names the peaks
    assert {"RB1", "FB1", "RF"} <= {name for row in rows for name in row.split()[1].split("/")}


def test_json_with_two_labels_names_the_rest_on_the_right_twin(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    argv = ["peaks", str(evaporation.path), "--frame", "5", "--json"]
    status, out, _ = run_cli([*argv, *evaporation.label_args("RB1", "FB1")], capsys)
    assert status == 0
    document = json.loads(out)
    assert document["format"] == "holoview-experiment"
    assert document["frame"] == 5
    assert document["frame_shape"] == [128, 128]
    named = {p["label"]: p["carrier"] for p in document["peaks"]}
    assert {"RB1", "RF", "FB1", "RB2"} <= set(named)
    by_label = {p["label"]: p for p in document["detected"] if p["label"]}
    for label, peak in by_label.items():
        np.testing.assert_allclose(peak["carrier"], evaporation.carriers[label], atol=1.5 / 128)
        np.testing.assert_allclose(named[label], peak["carrier"], atol=1e-12)
        assert peak["alpha"] == pytest.approx(evaporation.alphas[label])
        assert set(peak) >= {"amplitude", "snr", "flags", "twin", "labels"}
    amplitudes = [p["amplitude"] for p in document["detected"]]
    assert amplitudes == sorted(amplitudes, reverse=True)
    # the same document is an experiment for holoview process
    experiment = tmp_path / "experiment.json"
    experiment.write_text(out)
    status, _, _ = run_cli(
        [
            "process",
            str(evaporation.path),
            "--out",
            str(tmp_path / "o"),
            "--experiment",
            str(experiment),
            "--frames",
            ":30",
        ],
        capsys,
    )
    assert status == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["parameters"]["peaks_from"] == "experiment file"
    assert set(summary["peaks"]) == set(named)
    assert summary["fused"]["rate_m_per_s"] == pytest.approx(evaporation.rate, rel=0.03)


def test_without_labels_the_lattice_names_the_peaks(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    with h5py.File(evaporation.path, "r") as f:
        tifffile.imwrite(tmp_path / "stack.tif", f["frames"][:5], photometric="minisblack")
    argv = ["peaks", str(tmp_path / "stack.tif"), "--fluid", "water", "--json"]
    status, out, _ = run_cli(argv, capsys)
    assert status == 0
    document = json.loads(out)
    assert document["basis"] == "auto" and document["precision_bins"] < 0.5
    by_label = {p["label"]: p for p in document["detected"] if p["label"]}
    assert {"RB1", "RF", "FB1", "RB2"} <= set(by_label)
    expected = {"RB1": [1, -1], "RF": [0, 1], "FB1": [1, 0], "RB2": [2, -1]}
    for label, point in expected.items():
        peak = by_label[label]
        assert peak["lattice"] == point and peak["residual_bins"] < 1.0
        assert peak["coupling"] == point[1] and peak["kind"] == "first order"
        assert peak["alpha"] == pytest.approx(evaporation.alphas[label], rel=1e-3)
        # one global twin: the truth's or its negative for every peak alike
        sign = np.sign(np.dot(peak["carrier"], evaporation.carriers[label]))
        assert sign == np.sign(np.dot(by_label["RB1"]["carrier"], evaporation.carriers["RB1"]))
    assert any("twins are a convention" in note for note in document["notes"])


def test_without_labels_twins_are_unknown(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    with h5py.File(evaporation.path, "r") as f:
        tifffile.imwrite(tmp_path / "stack.tif", f["frames"][:5])  # carries no experiment
    status, out, _ = run_cli(["peaks", str(tmp_path / "stack.tif"), "--json"], capsys)
    assert status == 0
    document = json.loads(out)
    assert document["peaks"] == []
    detected = document["detected"]
    assert all(p["label"] is None and p["twin"] is None for p in detected)
    assert all(p["carrier"][0] >= 0 for p in detected)  # find_peaks keeps the fx > 0 twin


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--frame", "1000"], "--frame must be in 0.."),
        (["--label", "RB1=0.2,0.06", "--label", "FB1=0.6,0.1"], "outside the spectrum"),
        (["--label", "RB1=0.01,0.45"], "RB1: no detected peak within"),
        (["--label", "RB1=0.2,0.06", "--experiment", "e.json"], "not both"),
    ],
)
def test_bad_input_is_one_line_exit_2(
    evaporation: Simulated, capsys: pytest.CaptureFixture, extra: list[str], message: str
) -> None:
    status, _, err = run_cli(["peaks", str(evaporation.path), *extra], capsys)
    assert status == 2
    assert len(err.strip().splitlines()) == 1, err
    assert message in err


def test_missing_input_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    status, _, err = run_cli(["peaks", str(tmp_path / "none.tif")], capsys)
    assert status == 2
    assert "no such file" in err
