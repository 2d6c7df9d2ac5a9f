"""``holoview record``: replay and counting sources to a file, summary line, one-line errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.recording_writer import RecordingWriter
from holoview.cli import main
from holoview.cli.record import parse_setting

SHAPE = (16, 20)


def make_recording(path: Path, n: int = 12) -> np.ndarray:
    data = np.random.default_rng(4).integers(0, 4096, (n, *SHAPE), dtype=np.uint16)
    with RecordingWriter(path, SHAPE, np.uint16, setup={"wavelength_m": 532e-9}) as w:
        for i, frame in enumerate(data):
            w.append(frame, i, i * 0.001, 1e9 + i * 0.001)
    return data


def test_record_replay_with_frames_limit(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    data = make_recording(tmp_path / "in.h5")
    out = tmp_path / "out.h5"
    status = main(
        [
            "-q",
            "record",
            str(out),
            "--source",
            f"replay:{tmp_path / 'in.h5'}",
            "--frames",
            "7",
            "--set",
            "speed=fast",
            "--n2",
            "1.333",
            "--pixel-pitch-um",
            "5.5",
        ]
    )
    assert status == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith(f"{out}: acquired 7, recorded 7, dropped 0")
    assert "lost 0 (transport)" in line
    with RecordingReader(out) as reader:
        np.testing.assert_array_equal(reader[:], data[:7])
        assert reader.setup["wavelength_m"] == pytest.approx(532e-9)  # from the source
        assert reader.setup["n2"] == pytest.approx(1.333)  # from the command line
        assert reader.setup["pixel_pitch_m"] == pytest.approx(5.5e-6)
        assert reader.settings["speed"] == "fast"
        assert reader.settings_units["rate_hz"] == "Hz"
        assert reader.source.startswith("replay:")


def test_record_until_the_end_of_a_replay(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    make_recording(tmp_path / "in.h5")
    out = tmp_path / "out.h5"
    assert main(["-q", "record", str(out), "--source", f"replay:{tmp_path / 'in.h5'}"]) == 0
    assert "recorded 12," in capsys.readouterr().out
    with RecordingReader(out) as reader:
        assert len(reader) == 12


def test_record_seconds_limit(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    make_recording(tmp_path / "in.h5")
    out = tmp_path / "out.h5"
    spec = f"replay:{tmp_path / 'in.h5'}"
    args = ["-q", "record", str(out), "--source", spec, "--seconds", "0.3"]
    assert main([*args, "--set", "loop=on", "--set", "rate_hz=50"]) == 0
    with RecordingReader(out) as reader:
        assert 3 <= len(reader) <= 30  # about 15 at 50 frames/s
        assert (np.diff(reader.frame_ids) > 0).all()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--source", "webcam"], "unknown source"),
        (["--source", "replay:/no/such/file.h5"], "no such file"),
        (["--frames", "0"], "--frames must be at least 1"),
        (["--set", "exposure"], "NAME=VALUE"),
    ],
)
def test_bad_input_is_one_line_exit_2(tmp_path: Path, args: list[str], message: str) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "holoview", "record", str(tmp_path / "o.h5"), *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 2
    assert message in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert not (tmp_path / "o.h5").exists()


def test_existing_output_is_never_overwritten(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    make_recording(tmp_path / "in.h5")
    before = (tmp_path / "in.h5").read_bytes()
    status = main(["record", str(tmp_path / "in.h5"), "--source", f"replay:{tmp_path / 'in.h5'}"])
    assert status == 2
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "in.h5").read_bytes() == before


def test_unknown_setting_is_an_error_naming_the_known_ones(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    make_recording(tmp_path / "in.h5")
    spec = f"replay:{tmp_path / 'in.h5'}"
    assert main(["record", str(tmp_path / "o.h5"), "--source", spec, "--set", "gain_db=3"]) == 2
    err = capsys.readouterr().err
    assert "no setting 'gain_db'" in err
    assert "speed" in err


def test_parse_setting() -> None:
    assert parse_setting("exposure_s=2e-3") == ("exposure_s", 2e-3)
    assert parse_setting("roi=0,0,640,480") == ("roi", (0, 0, 640, 480))
    assert parse_setting("loop=on") == ("loop", True)
    assert parse_setting("pixel_format=Mono12p") == ("pixel_format", "Mono12p")
    assert parse_setting("frames = 3") == ("frames", 3)


def test_record_from_the_default_simulated_camera(tmp_path: Path) -> None:
    out = tmp_path / "sim.h5"
    result = subprocess.run(
        [sys.executable, "-m", "holoview", "record", str(out), "--frames", "5"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "acquired 5, recorded 5, dropped 0" in result.stdout
    with RecordingReader(out) as reader:
        assert len(reader) == 5
        assert reader.frame_shape == (1024, 1024)
        assert reader.source == "sim:waves"
        assert reader.setup["wavelength_m"] > 0


def test_source_failing_mid_run_keeps_the_recording_and_exits_2(tmp_path: Path) -> None:
    import cv2

    folder = tmp_path / "imgs"
    folder.mkdir()
    data = np.random.default_rng(5).integers(0, 255, (4, *SHAPE), dtype=np.uint8)
    for i, frame in enumerate(data):
        cv2.imwrite(str(folder / f"f{i}.png"), frame)
    damaged = folder / "f2.png"
    damaged.write_bytes(damaged.read_bytes()[:40])  # the header survives, the pixels do not
    out = tmp_path / "out.h5"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "holoview",
            "record",
            str(out),
            "--source",
            f"replay:{folder}",
            "--set",
            "speed=fast",
        ],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 2
    assert "recorded 2," in result.stdout
    errors = result.stderr.strip().splitlines()
    assert errors[-1].startswith("holoview record: error: ")
    assert "f2.png" in errors[-1]
    with RecordingReader(out) as reader:
        np.testing.assert_array_equal(reader[:], data[:2])


def test_record_stores_the_experiment_with_the_optics_options_over_it(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    from holoview.engine.experiment import Experiment, LabelledPeak

    make_recording(tmp_path / "in.h5")
    given = Experiment(
        wavelength_m=532e-9,
        n1=1.0,
        n2=1.333,
        radius=0.1,
        peaks=(LabelledPeak("RB1", (0.2, -0.1)), LabelledPeak("FB1", (0.1, 0.2))),
    )
    given.save(tmp_path / "exp.json")
    out = tmp_path / "out.h5"
    argv = ["-q", "record", str(out), "--source", f"replay:{tmp_path / 'in.h5'}", "--frames"]
    argv += ["4", "--set", "speed=fast", "--experiment", str(tmp_path / "exp.json")]
    assert main([*argv, "--wavelength-nm", "633", "--fluid", "ethanol"]) == 0
    with RecordingReader(out) as reader:
        stored = reader.experiments()
        assert reader.setup["wavelength_m"] == pytest.approx(633e-9)
        assert reader.setup["n2"] == pytest.approx(1.361)
    assert [start for start, _ in stored] == [0]
    experiment = Experiment.from_json(stored[0][1])
    assert experiment.peaks == given.peaks and experiment.radius == 0.1
    assert experiment.wavelength_m == pytest.approx(633e-9)
    assert experiment.n2 == pytest.approx(1.361)


def test_record_refuses_a_bad_experiment_before_creating_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    (tmp_path / "exp.json").write_text('{"format": "holoview-experiment", "version": 7}')
    out = tmp_path / "out.h5"
    assert (
        main(["record", str(out), "--frames", "2", "--experiment", str(tmp_path / "exp.json")]) == 2
    )
    assert "version 7 is not supported" in capsys.readouterr().err
    assert not out.exists()
