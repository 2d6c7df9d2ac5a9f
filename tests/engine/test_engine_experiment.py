"""The experiment model and its one JSON format: round trips, old versions, bad files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from holoview.engine.experiment import (
    EXPERIMENT_VERSION,
    Experiment,
    LabelledPeak,
    config_dir,
    default_experiment_path,
)
from holoview.errors import InputError


def test_round_trip_keeps_every_field(tmp_path: Path) -> None:
    experiment = Experiment(
        wavelength_m=633e-9,
        pixel_pitch_m=4e-6,
        n1=1.0,
        n2=1.377,
        window="tukey",
        radius=0.05,
        reference="absolute",
        unwrap="never",
        peaks=(LabelledPeak("RB1", (0.12, -0.05)), LabelledPeak("G1", (0.3, 0.02), alpha=0.5)),
    )
    experiment.save(tmp_path / "sub" / "exp.json")
    loaded = Experiment.load(tmp_path / "sub" / "exp.json")
    assert loaded == experiment
    document = json.loads((tmp_path / "sub" / "exp.json").read_text())
    assert document["format"] == "holoview-experiment"
    assert document["version"] == 2  # a numeric radius: readable by holoview before 3
    assert document["peaks"][0] == {"label": "RB1", "carrier": [0.12, -0.05]}
    assert document["peaks"][1]["alpha"] == 0.5
    assert not list((tmp_path / "sub").glob(".*partial"))  # written whole, then renamed


def test_radius_rules_are_spelled_in_the_file(tmp_path: Path) -> None:
    # null and "matched": matched to the surface; "bound": the widest (null before 3)
    bound = Experiment(radius="bound")
    assert bound.radius_rule == "bound" and bound.fixed_radius is None
    document = bound.to_dict()
    assert document["radius"] == "bound" and document["version"] == EXPERIMENT_VERSION == 3
    assert Experiment.from_dict(document) == bound
    for text in ('"matched"', "null"):
        loaded = Experiment.from_json(
            f'{{"format": "holoview-experiment", "version": 3, "radius": {text}}}'
        )
        assert loaded.radius is None and loaded.radius_rule == "matched"
        assert loaded.to_dict()["version"] == 2
    assert Experiment(radius=0.05).fixed_radius == 0.05
    with pytest.raises(InputError, match="'matched' or 'bound'"):
        Experiment(radius="widest")


def test_changes_replace_a_label_or_a_carrier() -> None:
    experiment = Experiment().with_peak(LabelledPeak("RB1", (0.12, -0.05)))
    experiment = experiment.with_peak(LabelledPeak("RB1", (0.13, -0.05)))  # the same label
    assert experiment.peaks == (LabelledPeak("RB1", (0.13, -0.05)),)
    experiment = experiment.with_peak(LabelledPeak("FB1", (0.13, -0.05)))  # the same carrier
    assert experiment.peaks == (LabelledPeak("FB1", (0.13, -0.05)),)
    assert experiment.without_label("FB1").peaks == ()


def test_alpha_comes_from_the_label_or_the_peak() -> None:
    experiment = Experiment(n1=1.0, n2=1.333)
    assert experiment.alpha(LabelledPeak("RB2", (0.1, 0.1))) == pytest.approx(2 * 1.333 - 1.0)
    assert experiment.alpha(LabelledPeak("FB1", (0.1, 0.1))) == pytest.approx(1.333)
    assert experiment.alpha(LabelledPeak("mine", (0.1, 0.1))) is None
    assert experiment.alpha(LabelledPeak("mine", (0.1, 0.1), alpha=2.5)) == 2.5
    assert Experiment(n2=None).alpha(LabelledPeak("RF", (0.1, 0.1))) is None


def test_version_1_files_are_read(tmp_path: Path) -> None:
    path = tmp_path / "old.json"
    path.write_text(
        json.dumps(
            {
                "format": "holoview-experiment",
                "version": 1,
                "wavelength_m": 5.32e-07,
                "radius": 0.06,
                "reference": "relative",
                "peaks": [{"label": "RB1", "fx": 0.12, "fy": -0.05}],
            }
        )
    )
    loaded = Experiment.load(path)
    assert loaded.peaks == (LabelledPeak("RB1", (0.12, -0.05)),)
    assert loaded.radius == 0.06 and loaded.unwrap == "auto"


def test_partial_experiment_leaves_optics_unknown() -> None:
    loaded = Experiment.from_json(
        '{"format": "holoview-experiment", "version": 2, '
        '"peaks": [{"label": "RB1", "carrier": [0.1, 0.2]}]}'
    )
    assert loaded.wavelength_m is None and loaded.n2 is None and loaded.radius is None
    with pytest.raises(InputError, match=r"give --wavelength-nm.*give --n2"):
        loaded.require("wavelength_m", "n2")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{not json", "not valid JSON"),
        ('{"format": "other"}', "not a holoview-experiment file"),
        ('{"peaks": [{"label": "RB1", "carrier": [0.1, 0.1]}]}', "format field is missing"),
        ('{"format": "holoview-experiment", "version": 9}', "version 9 is not supported"),
        ('{"format": "holoview-experiment", "version": 2, "radius": 0.7}', "beyond Nyquist"),
        ('{"format": "holoview-experiment", "version": 2, "reference": "x"}', "reference 'x'"),
        ('{"format": "holoview-experiment", "version": 2, "n1": 1.5, "n2": 1.3}', "above n1"),
        ('{"format": "holoview-experiment", "version": 2, "wavelength_m": -1}', "positive"),
        ('{"format": "holoview-experiment", "version": 2, "wavelength_m": 532}', "nanometres"),
        ('{"format": "holoview-experiment", "version": 2, "peaks": {}}', "must be a list"),
        ('{"format": "holoview-experiment", "version": 2, "peaks": [{"fx": 1}]}', "peak 0"),
        (
            '{"format": "holoview-experiment", "version": 2, '
            '"peaks": [{"label": "RB1", "carrier": [0.7, 0.1]}]}',
            "outside the spectrum",
        ),
        (
            '{"format": "holoview-experiment", "version": 2, '
            '"peaks": [{"label": "bad label", "carrier": [0.1, 0.1]}]}',
            "not usable",
        ),
        (
            '{"format": "holoview-experiment", "version": 2, '
            '"peaks": [{"label": "X", "carrier": [0.1, 0.1], "alpha": "two"}]}',
            "alpha must be a number",
        ),
        (  # an object's keys were read as fx and fy before the carrier's type was checked
            '{"format": "holoview-experiment", "version": 2, '
            '"peaks": [{"label": "RB1", "carrier": {"0.1": 0, "0.2": 0}}]}',
            "carrier must be \\[fx, fy\\]",
        ),
        (
            '{"format": "holoview-experiment", "version": 2, "peaks": ['
            '{"label": "RB1", "carrier": [0.1, 0.1]}, {"label": "RB1", "carrier": [0.2, 0.1]}]}',
            "given twice",
        ),
    ],
)
def test_bad_experiment_file_is_one_clear_error(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as caught:
        Experiment.load(path)
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)


def test_utf16_is_read_binary_and_missing_files_are_named(tmp_path: Path) -> None:
    path = tmp_path / "powershell.json"
    path.write_text(Experiment(radius=0.05).to_json(), encoding="utf-16")
    assert Experiment.load(path).radius == 0.05
    (tmp_path / "binary.json").write_bytes(b"\x00\x93\xff\xd8binary")
    with pytest.raises(InputError, match="not text"):
        Experiment.load(tmp_path / "binary.json")
    with pytest.raises(InputError, match="cannot be read"):
        Experiment.load(tmp_path / "missing.json")


def test_config_folder_follows_xdg_config_home(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    assert config_dir() == tmp_path / "holoview"
    assert default_experiment_path() == tmp_path / "holoview" / "experiment.json"
