"""End-to-end: ``holoview process`` on simulated recordings, outputs checked against the truth."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
import tifffile
from headless_sim import Simulated, run_cli

from holoview.acquire.recording_writer import RecordingWriter
from holoview.headless.results.outputs import TRENDS_HEADER

FIRST_ORDER = {"RB1", "RF", "FB1", "RB2"}


def read_trends(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        return list(reader.fieldnames or []), list(reader)


def fused_series(rows: list[dict[str, str]]) -> tuple[np.ndarray, np.ndarray]:
    fused = [r for r in rows if r["label"] == "fused"]
    return (
        np.array([float(r["time_s"]) for r in fused]),
        np.array([float(r["mean_height_m"]) for r in fused]),
    )


def test_labels_mode_trends_rates_and_summary(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "out"
    status, stdout, _ = run_cli(
        [
            "process",
            str(evaporation.path),
            "--out",
            str(out),
            *evaporation.label_args("RB1", "FB1"),
        ],
        capsys,
    )
    assert status == 0
    assert str(out) in stdout and "um/min" in stdout
    assert sorted(p.name for p in out.iterdir()) == [
        "report.png",
        "results.h5",
        "summary.json",
        "trends.csv",
    ]
    header, rows = read_trends(out / "trends.csv")
    assert tuple(header) == TRENDS_HEADER
    summary = json.loads((out / "summary.json").read_text())
    labels = list(summary["peaks"])
    assert set(labels) >= FIRST_ORDER
    assert len(rows) == evaporation.frames * (len(labels) + 1)
    first = rows[: len(labels) + 1]
    assert [r["label"] for r in first] == [*labels, "fused"]
    assert all(r["frame"] == "0" and float(r["mean_height_m"]) == 0.0 for r in first)
    # heights relative to the first frame follow the truth
    times, fused = fused_series(rows)
    np.testing.assert_allclose(times, evaporation.time_s - evaporation.time_s[0], atol=1e-9)
    truth = evaporation.mean_height_m - evaporation.mean_height_m[0]
    assert np.max(np.abs(fused - truth)) < 5e-9
    # the fused rate against the truth, and its standard error
    rate = summary["fused"]["rate_m_per_s"]
    assert rate == pytest.approx(evaporation.rate, rel=0.01)
    assert 0 < summary["fused"]["rate_stderr_m_per_s"] < 0.01 * abs(evaporation.rate)
    for label in FIRST_ORDER:
        peak = summary["peaks"][label]
        assert peak["alpha"] == pytest.approx(evaporation.alphas[label], rel=1e-9)
        np.testing.assert_allclose(peak["carrier"], evaporation.carriers[label], atol=2 / 128)
        assert peak["rate_m_per_s"] == pytest.approx(evaporation.rate, rel=0.02)
        assert set(peak) >= {"amplitude", "snr", "rate_stderr_m_per_s", "flags"}
        # the map noise in height is the phase noise through the peak's alpha
        to_height = evaporation.wavelength / (4 * np.pi * peak["alpha"])
        assert 0 < peak["map_noise_rad"] < 1
        assert peak["map_noise_m"] == pytest.approx(peak["map_noise_rad"] * to_height)
    # RB3 steps 3.5 rad per frame at 20 frames/s: flagged, and unwrapped by the others
    if "RB3" in summary["peaks"]:
        rb3 = summary["peaks"]["RB3"]
        assert "aliased_in_time" in rb3["flags"] and rb3["used_in_fused"]
        assert rb3["rate_m_per_s"] == pytest.approx(evaporation.rate, rel=0.02)
    assert set(summary) >= {
        "format",
        "holoview_version",
        "input",
        "parameters",
        "peaks",
        "fused",
        "pca",
        "frames",
    }
    assert summary["holoview_version"]
    assert summary["frames"]["processed"] == evaporation.frames
    with h5py.File(out / "results.h5", "r") as f:
        assert f["trends/mean_height_m"].shape == (evaporation.frames, len(labels))
        assert f["trends/mean_height_m"].attrs["units"] == "m"
        assert [s.decode() for s in f["peaks/label"][:]] == labels
        np.testing.assert_allclose(f["trends/fused_height_m"][:], fused, rtol=1e-6, atol=1e-15)
    assert summary["input"]["kind"] == "hdf5"
    assert summary["parameters"]["optics_from"]["wavelength_m"] == "recording"
    assert summary["pca"]["confidence"] > 0.99


def test_auto_mode_identifies_the_peaks_by_pca(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "auto"
    fx, fy = evaporation.carriers["RB1"]
    argv = ["process", str(evaporation.path), "--out", str(out), "--auto", "4"]
    status, _, _ = run_cli([*argv, "--anchor", f"RB1={fx},{fy}"], capsys)
    assert status == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["peaks"]) == FIRST_ORDER
    assert summary["pca"]["confidence"] > 0.99
    for label, value in summary["pca"]["prefactors"].items():
        assert value == pytest.approx(evaporation.alphas[label], rel=0.02), label
    assert summary["fused"]["rate_m_per_s"] == pytest.approx(evaporation.rate, rel=0.01)
    assert not any("--anchor" in note for note in summary["notes"])
    # without the anchor the brightest peak is taken on the other twin: the sign flips
    status, _, _ = run_cli([*argv[:3], str(tmp_path / "plain"), *argv[4:]], capsys)
    assert status == 0
    plain = json.loads((tmp_path / "plain" / "summary.json").read_text())
    assert plain["fused"]["rate_m_per_s"] == pytest.approx(-evaporation.rate, rel=0.01)
    assert any("--anchor" in note for note in plain["notes"])


def test_maps_against_the_truth(
    waves: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Absolute maps of standing waves: the fused delta-h map follows the true surface."""
    out = tmp_path / "maps"
    argv = ["process", str(waves.path), "--out", str(out), "--maps", "--reference", "absolute"]
    status, _, _ = run_cli([*argv, *waves.label_args("RB1", "FB1"), "--frames", "0:40"], capsys)
    assert status == 0
    with h5py.File(out / "results.h5", "r") as f:
        assert f.attrs["format"] == "holoview-results"
        labels = [s.decode() for s in f["trends/label"][:]]
        for name in [*labels, "fused"]:
            maps = f["maps"][name]
            assert maps.dtype == np.float32
            assert maps.ndim == 3 and maps.shape[0] == 40
            assert maps.attrs["units"] == "m"
            assert maps.attrs["reference"] == "absolute"
        fused = f["maps/fused"][:]
        step = f["maps/fused"].attrs["pixel_step_px"]
    assert np.all(fused[0][np.isfinite(fused[0])] == 0)
    assert waves.height_maps is not None
    rows = (np.arange(fused.shape[1]) * step[0]).round().astype(int)
    cols = (np.arange(fused.shape[2]) * step[1]).round().astype(int)
    border = 3  # box pixels next to the frame edge carry the FFT's wrap-around
    inner = (slice(border, -border), slice(border, -border))
    for k in (20, 39):
        truth = (waves.height_maps[k] - waves.height_maps[0])[np.ix_(rows, cols)][inner]
        measured = fused[k][inner]
        keep = np.isfinite(measured)
        assert keep.mean() > 0.9
        correlation = np.corrcoef(truth[keep], measured[keep])[0, 1]
        assert correlation > 0.9
        # the reference arm's jitter moves RB_j and RF maps by one piston each (opposite
        # signs; the series' joint estimate takes it out): the surface's shape is checked
        error = truth[keep] - measured[keep]
        assert np.std(error) < 0.15 * np.std(truth[keep])
        assert abs(np.mean(error)) < 1.0 * np.std(truth[keep])


def experiment_file(path: Path, peaks: list[dict], **fields: object) -> Path:
    """Write a holoview-experiment file naming ``peaks``."""
    document = {"format": "holoview-experiment", "version": 2, **fields, "peaks": peaks}
    path.write_text(json.dumps(document))
    return path


def test_process_with_no_options_uses_the_experiment_the_recording_carries(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """`holoview simulate` stores the true labels; `process` needs no peak options."""
    out = tmp_path / "plain"
    status, stdout, _ = run_cli(["process", str(evaporation.path), "--out", str(out)], capsys)
    assert status == 0
    assert "(from the recording)" in stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["parameters"]["peaks_from"] == "recording"
    assert set(summary["peaks"]) >= FIRST_ORDER
    points = {"RB1": [1, -1], "RF": [0, 1], "FB1": [1, 0], "RB2": [2, -1]}
    for label in FIRST_ORDER:
        peak = summary["peaks"][label]
        assert peak["alpha"] == pytest.approx(evaporation.alphas[label])
        assert peak["lattice"] == points[label] and peak["residual_bins"] < 1.0
        assert peak["coupling"] == points[label][1]
    assert evaporation.rate < 0  # a falling level...
    assert summary["fused"]["rate_m_per_s"] == pytest.approx(evaporation.rate, rel=0.01)
    assert summary["experiment"]["format"] == "holoview-experiment"
    assert not any("--auto" in note for note in summary["notes"])


def test_an_unreadable_stored_experiment_falls_back_to_auto_with_a_note(
    evaporation: Simulated,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    caplog: pytest.LogCaptureFixture,
) -> None:
    path = tmp_path / "broken.h5"
    with h5py.File(evaporation.path, "r") as f:
        frames, times = f["frames"][:30], f["t_device_s"][:30]
        setup = dict(f["setup"].attrs)
    with RecordingWriter(
        path, frames.shape[1:], frames.dtype, setup=setup, experiment="{oops"
    ) as w:
        for i, frame in enumerate(frames):
            w.append(frame, i, float(times[i]), 0.0)
    out = tmp_path / "out"
    status, _, _ = run_cli(["process", str(path), "--out", str(out)], capsys)
    assert status == 0
    assert "not valid JSON" in caplog.text and "--auto 4" in caplog.text  # warned
    summary = json.loads((out / "summary.json").read_text())
    assert summary["parameters"]["peaks_from"] == "auto"
    notes = "\n".join(summary["notes"])
    assert "not valid JSON" in notes and "carries no usable experiment" in notes


def test_peaks_file_and_auto_maps_agree(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """An experiment file and --auto give the same labelled maps (phase converted after PCA)."""
    peaks = [
        {"label": label, "carrier": list(evaporation.carriers[label])} for label in ("RB1", "RF")
    ]
    experiment_file(tmp_path / "peaks.json", peaks)
    common = ["--maps", "--frames", "10:50", "--radius", "0.06"]  # same windows, same maps
    status, _, _ = run_cli(
        [
            "process",
            str(evaporation.path),
            "--out",
            str(tmp_path / "file"),
            "--experiment",
            str(tmp_path / "peaks.json"),
            *common,
        ],
        capsys,
    )
    assert status == 0
    fx, fy = evaporation.carriers["RB1"]
    status, _, _ = run_cli(
        [
            "process",
            str(evaporation.path),
            "--out",
            str(tmp_path / "auto"),
            "--auto",
            "2",
            "--anchor",
            f"RB1={fx},{fy}",
            *common,
        ],
        capsys,
    )
    assert status == 0
    with (
        h5py.File(tmp_path / "file" / "results.h5", "r") as a,
        h5py.File(tmp_path / "auto" / "results.h5", "r") as b,
    ):
        # the model adds the other families to two labels, as the live window does
        assert set(a["maps"]) >= FIRST_ORDER | {"fused"}
        assert set(b["maps"]) == {"RB1", "RF", "fused", "time", "frame", "y", "x"}
        np.testing.assert_array_equal(a["trends/frame"][:], np.arange(10, 50))
        step = evaporation.rate / evaporation.fps
        heights = a["trends/mean_height_m"][:]
        for j, name in enumerate(("RB1", "RF")):
            # relative maps: each frame's mean is the step of the mean height since the last
            means = np.nanmean(a["maps"][name][1:], axis=(1, 2))
            np.testing.assert_allclose(means, np.diff(heights[:, j]), atol=1e-9)
            assert np.mean(means) == pytest.approx(step, rel=0.1)
        for name in ("RB1", "RF"):
            np.testing.assert_allclose(
                a["maps"][name][1:], b["maps"][name][1:], atol=0.05 * abs(step)
            )


@pytest.mark.parametrize("kind", ["tiff", "folder"])
def test_image_files_with_options_and_volume(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture, kind: str
) -> None:
    with h5py.File(evaporation.path, "r") as f:
        frames = f["frames"][:60]
    if kind == "tiff":
        path = tmp_path / "stack.tif"
        tifffile.imwrite(path, frames)
    else:
        path = tmp_path / "images"
        path.mkdir()
        for i, frame in enumerate(frames):
            assert cv2.imwrite(str(path / f"frame{i}.png"), frame)
    out = tmp_path / "out"
    argv = ["process", str(path), "--out", str(out), "--wavelength-nm", "532"]
    argv += ["--fluid", "water", "--n1", "1.000293", "--fps", str(evaporation.fps)]
    argv += ["--area", "0.01", *evaporation.label_args("RB1", "FB1")]
    status, _, _ = run_cli(argv, capsys)
    assert status == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["input"]["kind"] == kind
    assert summary["parameters"]["optics_from"]["n2"] == "option"
    fused = summary["fused"]
    assert fused["rate_m_per_s"] == pytest.approx(evaporation.rate, rel=0.01)
    assert fused["volume_rate_m3_per_s"] == pytest.approx(0.01 * fused["rate_m_per_s"])
    with h5py.File(out / "results.h5", "r") as f:
        np.testing.assert_allclose(
            f["trends/fused_volume_m3"][:], 0.01 * f["trends/fused_height_m"][:]
        )
        assert f["trends/fused_volume_m3"].attrs["units"] == "m3"
        assert "maps" not in f


def write_garbage(path: Path) -> Path:
    path.write_bytes(b"not an hdf5 file at all")
    return path


@pytest.mark.parametrize(
    ("make_args", "message"),
    [
        (lambda e, t: [str(t / "missing.h5")], "no such file"),
        (lambda e, t: [str(write_garbage(t / "bad.h5"))], "not a readable HDF5"),
        (lambda e, t: [str(e.path), "--wavelength-nm", "-1"], "not a finite positive number"),
        (lambda e, t: [str(e.path), "--n2", "0.9"], "must be above n1"),
        (lambda e, t: [str(e.path), "--frames", "500:"], "selects no frame"),
        (lambda e, t: [str(e.path), "--frames", "a:b"], "--frames takes integers"),
        (lambda e, t: [str(e.path), "--radius", "0.4"], "window radius"),
        (lambda e, t: [str(e.path), "--area", "0"], "--area must be a positive"),
        (lambda e, t: [str(e.path), "--anchor", "RB1=0.1,0.1", "--experiment", "x"], "with --auto"),
        (lambda e, t: [str(e.path), "--auto", "4", "--experiment", "x.json"], "one way"),
        (lambda e, t: [str(e.path), "--label", "RB1=0.01,0.4"], "RB1: no detected peak within"),
        (lambda e, t: [str(e.path), "--experiment", str(t / "none.json")], "cannot be read"),
        (lambda e, t: [str(e.path), "--label", "RB1=0.9,0.1"], "outside the spectrum"),
        (lambda e, t: [str(e.path), "--auto", "4", "--anchor", "RB1=0.01,0.4"], "no detected"),
        (lambda e, t: [str(e.path), "--auto", "0"], "needs at least 2 peaks for the PCA, got 0"),
    ],
)
def test_bad_input_is_one_line_exit_2(
    evaporation: Simulated,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    make_args,
    message: str,
) -> None:
    argv = ["process", *make_args(evaporation, tmp_path), "--out", str(tmp_path / "out")]
    status, _, err = run_cli(argv, capsys)
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("holoview process: error:")
    assert message in lines[0]


def _rb1(e: Simulated) -> list[float]:
    return list(e.carriers["RB1"])


@pytest.mark.parametrize(
    ("make_content", "message"),
    [
        (lambda e: "{not json", "not valid JSON"),
        (lambda e: '{"peaks": []}', "not a holoview-experiment file"),
        (lambda e: '{"format": "holoview-experiment", "version": 2}', "names no peak"),
        (lambda e: [{"label": "RB1"}], '"carrier"'),
        (lambda e: [{"label": "RB1", "carrier": [0.7, 0.1]}], "outside the spectrum"),
        (lambda e: [{"label": "RB1", "carrier": "here"}], "carrier must be [fx, fy]"),
        (lambda e: [{"label": "XY9", "carrier": _rb1(e)}], "give its alpha"),
        (lambda e: [{"label": "RB1", "carrier": [0.2, 0.1], "alpha": 0}], "nonzero"),
        (lambda e: [{"label": "..", "carrier": [0.2, 0.1], "alpha": 1}], "not usable"),
        (
            lambda e: [
                {"label": "A", "carrier": _rb1(e), "alpha": 1},
                {"label": "B", "carrier": [-c for c in _rb1(e)], "alpha": 2},
            ],
            "same detected peak as A",
        ),
    ],
)
def test_bad_experiment_file_is_one_line_exit_2(
    evaporation: Simulated,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    make_content,
    message: str,
) -> None:
    content = make_content(evaporation)
    path = tmp_path / "exp.json"
    if isinstance(content, str):
        path.write_text(content)
    else:
        experiment_file(path, content)
    out = tmp_path / "o"
    argv = ["process", str(evaporation.path), "--out", str(out), "--experiment", str(path)]
    status, _, err = run_cli(argv, capsys)
    assert status == 2
    assert len(err.strip().splitlines()) == 1, err
    assert message in err
    assert not out.exists()  # nothing written


def test_files_without_times_need_fps(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    with h5py.File(evaporation.path, "r") as f:
        tifffile.imwrite(tmp_path / "stack.tif", f["frames"][:5])
    argv = ["process", str(tmp_path / "stack.tif"), "--out", str(tmp_path / "o")]
    status, _, err = run_cli([*argv, "--wavelength-nm", "532", "--fluid", "water"], capsys)
    assert status == 2
    assert "give --fps" in err
    status, _, err = run_cli([*argv, "--fluid", "water", "--fps", "10"], capsys)
    assert status == 2
    assert "--wavelength-nm" in err


def test_output_folder_that_is_a_file_is_one_line_exit_2(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    (tmp_path / "taken").write_text("")
    argv = ["process", str(evaporation.path), "--out", str(tmp_path / "taken"), "--frames", ":5"]
    status, _, err = run_cli([*argv, *evaporation.label_args("RB1", "FB1")], capsys)
    assert status == 2
    assert "is a file" in err


def test_quiet_prints_nothing(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    argv = ["process", str(evaporation.path), "--out", str(tmp_path / "q"), "--frames", ":10"]
    status, out, err = run_cli([*argv, *evaporation.label_args("RB1", "FB1"), "-q"], capsys)
    assert status == 0
    assert out == "" and err == ""
    assert (tmp_path / "q" / "trends.csv").is_file()


def test_labels_on_a_file_without_optics_ask_for_the_fluid(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    with h5py.File(evaporation.path, "r") as f:
        tifffile.imwrite(tmp_path / "stack.tif", f["frames"][:5], photometric="minisblack")
    argv = ["process", str(tmp_path / "stack.tif"), "--out", str(tmp_path / "o")]
    argv += ["--wavelength-nm", "532", "--fps", "20", *evaporation.label_args("RB1", "FB1")]
    status, _, err = run_cli(argv, capsys)
    assert status == 2
    assert "give --n2 or --fluid" in err and len(err.strip().splitlines()) == 1


def test_background_hologram_by_index_or_file(
    waves: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """--background: absolute maps against frame 0 although the run starts at frame 10."""
    common = [*waves.label_args("RB1", "FB1"), "--maps", "--frames", "10:40"]
    with h5py.File(waves.path, "r") as f:
        tifffile.imwrite(tmp_path / "empty.tif", f["frames"][0])
    maps = {}
    for name, spec in (("index", "0"), ("file", str(tmp_path / "empty.tif"))):
        out = tmp_path / name
        argv = ["process", str(waves.path), "--out", str(out), "--background", spec, *common]
        status, _, _ = run_cli(argv, capsys)
        assert status == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary["parameters"]["reference"] == "absolute"  # implied
        assert summary["parameters"]["background"] == spec
        with h5py.File(out / "results.h5", "r") as f:
            maps[name] = f["maps/fused"][:]
            step = f["maps/fused"].attrs["pixel_step_px"]
            assert "background hologram" in f["maps/fused"].attrs["reference_description"]
    np.testing.assert_allclose(maps["index"], maps["file"], equal_nan=True, atol=1e-12)
    fused = maps["index"]
    assert waves.height_maps is not None
    rows = (np.arange(fused.shape[1]) * step[0]).round().astype(int)
    cols = (np.arange(fused.shape[2]) * step[1]).round().astype(int)
    inner = (slice(3, -3), slice(3, -3))
    for k in (0, 29):  # run positions: frames 10 and 39, both against frame 0
        truth = (waves.height_maps[10 + k] - waves.height_maps[0])[np.ix_(rows, cols)][inner]
        measured = fused[k][inner]
        keep = np.isfinite(measured)
        assert np.corrcoef(truth[keep], measured[keep])[0, 1] > 0.9


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--background", "500"], "has frames 0 to"),
        (["--background", "0", "--reference", "relative"], "--reference absolute"),
        (["--background", "SMALL"], "the input's are"),
    ],
)
def test_background_bad_input_is_one_line_exit_2(
    waves: Simulated,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    extra: list[str],
    message: str,
) -> None:
    small = tmp_path / "small.tif"
    tifffile.imwrite(small, np.zeros((16, 16), np.uint16))
    extra = [str(small) if e == "SMALL" else e for e in extra]
    argv = ["process", str(waves.path), "--out", str(tmp_path / "out"), *extra]
    status, _, stderr = run_cli([*argv, *waves.label_args("RB1", "FB1")], capsys)
    assert status == 2
    assert message in stderr and len(stderr.strip().splitlines()) == 1
    assert "Traceback" not in stderr


def test_frames_damaged_in_transfer_are_counted_and_left_out(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Lost packets (a band of zeroed rows) in two frames: no values, no maps, counted."""
    path = tmp_path / "damaged.h5"
    with h5py.File(evaporation.path, "r") as f:
        frames, times = f["frames"][:40], f["t_device_s"][:40]
        setup = dict(f["setup"].attrs)
        experiment = f["experiment/json"][()].tobytes().decode()
    frames[[10, 25], 40:72] = 0
    with RecordingWriter(
        path, frames.shape[1:], frames.dtype, setup=setup, experiment=experiment
    ) as w:
        for i, frame in enumerate(frames):
            w.append(frame, i, float(times[i]), 0.0)
    out = tmp_path / "out"
    status, _, _ = run_cli(["process", str(path), "--out", str(out), "--maps"], capsys)
    assert status == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"]["damaged"] == 2
    rate = summary["fused"]["rate_m_per_s"]
    assert rate == pytest.approx(evaporation.rate, rel=0.02)
    with h5py.File(out / "results.h5", "r") as f:
        heights = f["trends/fused_height_m"][:]
        assert np.isfinite(heights[[9, 11, 24, 26]]).all()
        rb1 = f["maps/RB1"]
        assert np.isnan(rb1[10]).all() and np.isnan(rb1[25]).all()
        assert np.isfinite(rb1[11]).any()
