"""Labels the carrier lattice contradicts are an error naming them, wherever they come from.

Before, the lattice's verdict was turned into a quiet note: ``--label RB1=<RF's carrier>
--label RF=<RB1's>`` exited 0 with RB1's rate -2.48 um/min (truth -0.816), RB1 on the
wrong twin gave +0.79, a swapped experiment file fused -0.661. Now labels typed in, an
experiment file and a recording's stored experiment go through the engine's one rule
(:func:`holoview.engine.resolve.resolve_peaks`): headless, one line and exit status 2;
live, the banner says it. The true carriers are the simulator's (``/truth/families``).
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from faults_helpers import one_line_error, run_main

from holoview.cli import main
from holoview.engine.experiment import Experiment, LabelledPeak
from holoview.ui.main_window import MainWindow

Carrier = tuple[float, float]


@pytest.fixture(scope="module")
def evaporation(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The issue's recording: evaporation, 256 x 256, 300 frames (true rate -0.816 um/min)."""
    path = tmp_path_factory.mktemp("labels") / "evap.h5"
    argv = ["-q", "simulate", str(path), "--scenario", "evaporation", "--size", "256"]
    assert main([*argv, "--frames", "300", "--seed", "7"]) == 0
    return path


@pytest.fixture(scope="module")
def truth(evaporation: Path) -> dict[str, Carrier]:
    with h5py.File(evaporation, "r") as f:
        families = f["truth/families"]
        labels = [name.decode() for name in families["label"][()]]
        carriers = families["carrier_cpp"][()]
    return {label: (float(c[0]), float(c[1])) for label, c in zip(labels, carriers, strict=True)}


def true_rate(path: Path) -> float:
    """The simulator's mean depth rate, m/s, fitted here by least squares."""
    with h5py.File(path, "r") as f:
        return float(np.polyfit(f["truth/time_s"][:], f["truth/mean_height_m"][:], 1)[0])


def other_twin(carrier: Carrier) -> Carrier:
    return (-carrier[0], -carrier[1])


def label_args(**labels: Carrier) -> list[str]:
    out = []
    for name, (fx, fy) in labels.items():
        out += ["--label", f"{name}={fx:.6f},{fy:.6f}"]
    return out


def experiment_file(path: Path, **labels: Carrier) -> Path:
    peaks = tuple(LabelledPeak(name, carrier) for name, carrier in labels.items())
    Experiment(peaks=peaks).save(path)
    return path


def store_experiment(source: Path, target: Path, **labels: Carrier) -> Path:
    """A copy of ``source`` whose stored experiment names ``labels``."""
    target.write_bytes(source.read_bytes())
    with h5py.File(target, "r") as f:
        stored = json.loads(f["experiment/json"][()].tobytes())
    stored["peaks"] = [{"label": k, "carrier": list(c)} for k, c in labels.items()]
    text = np.frombuffer(json.dumps(stored).encode(), np.uint8)
    with h5py.File(target, "a") as f:
        group = f["experiment"]
        del group["json"], group["changes"]
        group["json"] = text
        group["changes"] = np.array([[0, 0, text.size]], dtype=np.int64)
    return target


def swapped(truth: dict[str, Carrier]) -> dict[str, Carrier]:
    return {"RB1": truth["RF"], "RF": truth["RB1"]}


def process(path: Path, out: Path, capsys, *extra: str):
    return run_main(["-q", "process", str(path), "--out", str(out), *extra], capsys)


def test_right_labels_give_the_true_rate(
    evaporation: Path, truth: dict[str, Carrier], tmp_path: Path, capsys
) -> None:
    """The check refuses wrong labels only: the true ones give the simulator's rate."""
    out = tmp_path / "out"
    done = process(evaporation, out, capsys, *label_args(RB1=truth["RB1"], RF=truth["RF"]))
    assert done.status == 0, done.err
    summary = json.loads((out / "summary.json").read_text())
    rate = true_rate(evaporation)
    assert summary["peaks"]["RB1"]["rate_m_per_s"] == pytest.approx(rate, rel=0.03)
    assert summary["fused"]["rate_m_per_s"] == pytest.approx(rate, rel=0.03)


@pytest.mark.parametrize(
    "case",
    [
        ("swapped", "label RB1 contradicts the lattice: the peak labelled RB1 is RF"),
        ("rb1-wrong-twin", "labels RB1 and RF contradict the lattice: they are given on opposite"),
        ("fb1-is-rb1", "label RB1 contradicts the lattice: the peak labelled RB1 is FB1"),
    ],
    ids=lambda case: case[0],
)
def test_contradicted_labels_typed_in_are_one_line(
    evaporation: Path, truth: dict[str, Carrier], tmp_path: Path, capsys, case: tuple[str, str]
) -> None:
    name, said = case
    labels = {
        "swapped": swapped(truth),
        "rb1-wrong-twin": {"RB1": other_twin(truth["RB1"]), "RF": truth["RF"]},
        "fb1-is-rb1": {"RB1": truth["FB1"], "FB1": truth["RB1"]},
    }[name]
    out = tmp_path / "out"
    done = process(evaporation, out, capsys, *label_args(**labels))
    one_line_error(done, 2, "the labels: ", said)
    assert not out.exists()
    done = run_main(["-q", "peaks", str(evaporation), *label_args(**labels)], capsys)
    one_line_error(done, 2, said)


@pytest.mark.parametrize(
    "case",
    [
        ("swapped", "label RB1 contradicts the lattice: the peak labelled RB1 is RF"),
        ("rb1-wrong-twin", "label RB1 contradicts the lattice of the other labels: it is given"),
    ],
    ids=lambda case: case[0],
)
def test_a_contradicted_experiment_file_is_one_line(
    evaporation: Path, truth: dict[str, Carrier], tmp_path: Path, capsys, case: tuple[str, str]
) -> None:
    name, said = case
    labels = {
        "swapped": {**swapped(truth), "FB1": truth["FB1"]},
        "rb1-wrong-twin": {"RB1": other_twin(truth["RB1"]), "RF": truth["RF"], "FB1": truth["FB1"]},
    }[name]
    experiment = experiment_file(tmp_path / "experiment.json", **labels)
    done = process(evaporation, tmp_path / "out", capsys, "--experiment", str(experiment))
    one_line_error(done, 2, "the experiment file: ", said)
    done = run_main(["-q", "peaks", str(evaporation), "--experiment", str(experiment)], capsys)
    one_line_error(done, 2, said)


def test_a_recordings_contradicted_experiment_is_one_line(
    evaporation: Path, truth: dict[str, Carrier], tmp_path: Path, capsys
) -> None:
    labels = {**swapped(truth), "FB1": truth["FB1"]}
    path = store_experiment(evaporation, tmp_path / "stored.h5", **labels)
    said = "the experiment the recording carries: label RB1 contradicts the lattice"
    done = process(path, tmp_path / "out", capsys)
    one_line_error(done, 2, said, "--label, --experiment or --auto N")
    one_line_error(run_main(["-q", "peaks", str(path)], capsys), 2, said)
    done = process(path, tmp_path / "out", capsys, *label_args(RB1=truth["RB1"], RF=truth["RF"]))
    assert done.status == 0, done.err  # labels given replace the stored ones


@pytest.mark.gui
@pytest.mark.qt_log_ignore(r"This plugin does not support (propagateSizeHints|raise)\(\)")
def test_the_live_window_says_a_contradiction_aloud_and_runs(
    qtbot, evaporation: Path, truth: dict[str, Carrier], tmp_path: Path, caplog
) -> None:
    """Live, the same rule: the banner names the label; relabelling clears it.

    The spectrum's warning stands while the contradiction holds; the banner says it once
    (and is logged), so a later message may replace it: it is read from the log.
    """
    experiment = experiment_file(tmp_path / "experiment.json", **swapped(truth))
    # the replay carries the same labels: a recording's own experiment replaces the
    # window's when it opens (as process does), and the simulator's names the true peaks,
    # so the contradiction lasted only until then and a loaded machine could miss it
    replayed = store_experiment(evaporation, tmp_path / "swapped.h5", **swapped(truth))
    window = MainWindow(source=f"replay:{replayed}", experiment_path=experiment)
    qtbot.addWidget(window)
    window.show()
    try:
        qtbot.waitUntil(lambda: window.session is not None, timeout=20000)
        said = "label RB1 contradicts the lattice: the peak labelled RB1 is RF"

        def warned() -> None:
            drawn = window._drawn
            label = window.spectrum.warning_label
            assert any(w.startswith(said) for w in window.spectrum.warnings), (
                None if drawn is None else (drawn.seq, drawn.frame_index, drawn.notes),
                label.text(),
                label.isVisibleTo(window.spectrum),
            )

        qtbot.waitUntil(warned, timeout=20000)
        banners = [r.getMessage() for r in caplog.records if r.name == "holoview.ui.main_window"]
        assert any(message.startswith(said) for message in banners), banners
        assert window.source_panel.start_button.isEnabled()
        window.label_peak("RB1", *truth["RB1"])
        window.label_peak("RF", *truth["RF"])
        qtbot.waitUntil(
            lambda: (
                window._drawn is not None
                and window._drawn.contradiction is None
                and {"RB1", "RF"} <= set(window._drawn.labelled)
            ),
            timeout=20000,
        )
        assert said not in window.spectrum.warning_label.text()
    finally:
        window.close()
