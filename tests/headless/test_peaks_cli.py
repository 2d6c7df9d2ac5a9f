"""``holoview peaks``: detected peaks, model labels and twins, JSON that ``process`` reads."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from headless_sim import Simulated, run_cli


def test_table_lists_the_detected_peaks(
    evaporation: Simulated, capsys: pytest.CaptureFixture
) -> None:
    status, out, _ = run_cli(["peaks", str(evaporation.path)], capsys)
    assert status == 0
    lines = out.strip().splitlines()
    count = int(lines[0].split(": ")[1].split()[0])
    assert count >= 4
    assert len(lines) == 2 + count
    assert "amplitude" in lines[1] and "flags" in lines[1]


def test_json_with_two_labels_names_the_rest_on_the_right_twin(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    argv = ["peaks", str(evaporation.path), "--frame", "5", "--json"]
    status, out, _ = run_cli([*argv, *evaporation.label_args("RB1", "FB1")], capsys)
    assert status == 0
    document = json.loads(out)
    assert document["frame"] == 5
    assert document["frame_shape"] == [128, 128]
    by_label = {p["label"]: p for p in document["peaks"] if p["label"]}
    assert {"RB1", "RF", "FB1", "RB2"} <= set(by_label)
    for label, peak in by_label.items():
        np.testing.assert_allclose(peak["carrier"], evaporation.carriers[label], atol=1.5 / 128)
        assert peak["alpha"] == pytest.approx(evaporation.alphas[label])
        assert set(peak) >= {"amplitude", "snr", "flags", "twin", "labels"}
    amplitudes = [p["amplitude"] for p in document["peaks"]]
    assert amplitudes == sorted(amplitudes, reverse=True)
    # the same document is a peaks file for holoview process
    peaks_file = tmp_path / "peaks.json"
    peaks_file.write_text(out)
    status, _, _ = run_cli(
        [
            "process",
            str(evaporation.path),
            "--out",
            str(tmp_path / "o"),
            "--peaks",
            str(peaks_file),
            "--frames",
            ":30",
        ],
        capsys,
    )
    assert status == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert set(summary["peaks"]) == set(by_label)
    assert summary["fused"]["rate_m_per_s"] == pytest.approx(evaporation.rate, rel=0.03)


def test_without_labels_twins_are_unknown(
    evaporation: Simulated, capsys: pytest.CaptureFixture
) -> None:
    status, out, _ = run_cli(["peaks", str(evaporation.path), "--json"], capsys)
    assert status == 0
    peaks = json.loads(out)["peaks"]
    assert all(p["label"] is None and p["twin"] is None for p in peaks)
    assert all(p["carrier"][0] >= 0 for p in peaks)  # find_peaks keeps the fx > 0 twin


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--frame", "1000"], "--frame must be in 0.."),
        (["--label", "RB1=0.2,0.06"], "at least two"),
        (["--label", "RB1=0.2,0.06", "--label", "FB1=0.6,0.1"], "outside the spectrum"),
        (["--label", "RB1=0.01,0.45", "--label", "FB1=0.3,0.1"], "matches no detected peak"),
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
