"""Inputs a lab hands over: numpy arrays, ImageJ stacks, macOS folders, videos, odd values."""

from __future__ import annotations

import codecs
import json
import logging
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
import tifffile
from faults_helpers import one_line_error, run_holoview, run_main, write_recording

from holoview.acquire.replay_files import open_frame_file

OPTICS = ["--wavelength-nm", "532", "--fluid", "water"]


@pytest.fixture(scope="module")
def frames(sim_recording: Path) -> np.ndarray:
    with h5py.File(sim_recording, "r") as f:
        return f["frames"][:]


def process_args(path: Path, tmp_path: Path, *extra: str) -> list[str]:
    return [
        "-q",
        "process",
        str(path),
        "--out",
        str(tmp_path / "out"),
        "--fps",
        "20",
        *OPTICS,
        *extra,
    ]


@pytest.mark.parametrize(
    "save",
    [
        lambda path, a: np.save(path.with_suffix(".npy"), a),
        lambda path, a: np.save(path.with_suffix(".npy"), a.astype(">u2")),
        lambda path, a: np.savez(path.with_suffix(".npz"), a),
        lambda path, a: np.savez_compressed(path.with_suffix(".npz"), frames=a, dark=a[:2]),
    ],
    ids=["npy", "npy-big-endian", "npz", "npz-frames-compressed"],
)
def test_numpy_stacks_are_frames(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture, save
) -> None:
    save(tmp_path / "stack", frames)
    path = next(tmp_path.glob("stack.*"))
    stack = open_frame_file(path)
    try:
        assert (len(stack), stack.frame_shape, stack.dtype, stack.kind) == (
            40,
            (128, 128),
            np.dtype(np.uint16),
            "numpy",
        )
        for i in (0, 17, 39, 3):  # forward and back
            np.testing.assert_array_equal(stack.read(i), frames[i])
    finally:
        stack.close()
    done = run_main(process_args(path, tmp_path), capsys)
    assert done.status == 0, done.err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["input"]["kind"] == "numpy" and summary["frames"]["processed"] == 40


def test_a_2d_array_is_one_frame_for_peaks_and_replay(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture, sim_recording: Path
) -> None:
    np.save(tmp_path / "one.npy", frames[0])
    from_array = run_main(["peaks", str(tmp_path / "one.npy"), "--json"], capsys)
    from_recording = run_main(["peaks", str(sim_recording), "--json"], capsys)
    assert from_array.status == 0, from_array.err

    def canonical(document: str) -> list[tuple[float, float]]:  # twins aside
        carriers = [p["carrier"] for p in json.loads(document)["detected"]]
        return sorted((abs(fx), fy if fx > 0 else -fy) for fx, fy in carriers)

    assert canonical(from_array.out) == canonical(from_recording.out)
    assert len(canonical(from_array.out)) >= 4
    np.save(tmp_path / "stack.npy", frames[:7])
    out = tmp_path / "copy.h5"
    done = run_main(
        [
            "-q",
            "record",
            str(out),
            "--source",
            f"replay:{tmp_path / 'stack.npy'}",
            "--set",
            "speed=fast",
        ],
        capsys,
    )
    assert done.status == 0, done.err
    with h5py.File(out, "r") as f:
        np.testing.assert_array_equal(f["frames"][:], frames[:7])


@pytest.mark.parametrize(
    ("array", "message"),
    [
        (np.zeros((4, 64, 64), np.complex64), "complex field is not a hologram"),
        (np.zeros((2, 4, 64, 64), np.uint16), "frames are 2-D (rows, cols) or 3-D"),
        (np.zeros(4096, np.uint16), "frames are 2-D"),
        (np.zeros((64, 64, 3), np.uint8), "colour image"),
        (np.zeros((3, 64, 64), bool), "does not hold pixel values"),
        (np.array([{"a": 1}] * 3, dtype=object), "does not hold pixel values"),
        (np.asfortranarray(np.zeros((4, 64, 64), np.uint16)), "Fortran order"),
        (np.zeros((4, 8, 8), np.uint16), "too small"),
    ],
    ids=["complex", "4d", "1d", "colour", "bool", "objects", "fortran", "tiny"],
)
def test_arrays_that_are_not_frames_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture, array: np.ndarray, message: str
) -> None:
    np.save(tmp_path / "bad.npy", array, allow_pickle=True)
    done = run_main(process_args(tmp_path / "bad.npy", tmp_path), capsys)
    one_line_error(done, 2, message, "bad.npy")


def test_truncated_and_ambiguous_npz_are_one_line(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    np.save(tmp_path / "full.npy", frames)
    data = (tmp_path / "full.npy").read_bytes()
    (tmp_path / "cut.npy").write_bytes(data[: len(data) // 3])
    one_line_error(run_main(process_args(tmp_path / "cut.npy", tmp_path), capsys), 2, "truncated")
    np.savez(tmp_path / "two.npz", a=frames, b=frames)
    done = run_main(process_args(tmp_path / "two.npz", tmp_path), capsys)
    one_line_error(done, 2, "2 arrays (a, b)", "name it frames")


def test_an_imagej_stack_of_two_channels_is_refused(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    path = tmp_path / "two.tif"
    tifffile.imwrite(
        path, np.stack([frames[:20], frames[20:]], axis=1), imagej=True, metadata={"axes": "TCYX"}
    )
    done = run_main(process_args(path, tmp_path), capsys)
    one_line_error(done, 2, "2 channels", "TCYX", "Split Channels")


def test_macos_companion_files_do_not_spoil_a_folder(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    folder = tmp_path / "images"
    folder.mkdir()
    for i, frame in enumerate(frames[:12]):
        cv2.imwrite(str(folder / f"f{i:02d}.png"), frame)
        (folder / f"._f{i:02d}.png").write_bytes(b"\x00\x05\x16\x07Mac OS X" + bytes(200))
    assert len(open_frame_file(folder)) == 12
    assert run_main(process_args(folder, tmp_path), capsys).status == 0


def test_a_runs_output_folder_is_not_taken_for_frames(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """A run's output folder given as the input: its report.png was read as a frame (peaks
    and the window said 'frame is damaged'), process took its results.h5 for a recording.
    Beside recordings, a results.h5 does not stop a batch."""
    out = tmp_path / "run"
    out.mkdir()
    cv2.imwrite(str(out / "report.png"), frames[0])
    with h5py.File(out / "results.h5", "w") as f:
        f.attrs["format"] = "holoview-results"
    for args in (["peaks", str(out)], process_args(out, tmp_path)):
        done = run_main(args, capsys)
        one_line_error(done, 2, f"{out} is the output folder of a holoview run (results.h5)")
    assert not (tmp_path / "out").exists()
    write_recording(out / "take1.h5", frames[:6])
    assert run_main(process_args(out, tmp_path), capsys).status == 2  # results.h5: a failed row
    assert (tmp_path / "out" / "take1" / "summary.json").is_file()


@pytest.mark.parametrize(("fourcc", "suffix"), [("MJPG", ".avi"), ("mp4v", ".mp4")])
def test_lossy_videos_are_read_quietly(
    frames: np.ndarray, tmp_path: Path, fourcc: str, suffix: str
) -> None:
    path = tmp_path / f"v{suffix}"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 20, (128, 128))
    for frame in frames:
        writer.write(cv2.cvtColor((frame >> 4).astype(np.uint8), cv2.COLOR_GRAY2BGR))
    writer.release()
    done = run_holoview("-q", "process", str(path), "--out", str(tmp_path / "o"), *OPTICS)
    assert done.status == 0, done.err
    assert done.err == ""  # OpenCV and FFmpeg printed a warning per frame before


def test_values_beyond_mono12_are_refused_naming_the_frame(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    data = frames.copy()
    data[7, 3, 3] = 40000  # 16-bit data in a file that says Mono12
    path = write_recording(tmp_path / "m12.h5", data, pixel_format="Mono12", significant_bits=12)
    done = run_main(
        ["-q", "process", str(path), "--out", str(tmp_path / "o"), "--fluid", "water"], capsys
    )
    one_line_error(done, 2, "frame 7", "40000", "12-bit", "0..4095")


def test_background_subtracted_frames_are_refused(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    values = frames.astype(np.float32)
    tifffile.imwrite(tmp_path / "bg.tif", values - values.mean(axis=0))
    done = run_main(process_args(tmp_path / "bg.tif", tmp_path), capsys)
    one_line_error(done, 2, "bg.tif frame 0", "background-subtracted", "raw frames")
    done = run_main(["peaks", str(tmp_path / "bg.tif")], capsys)
    one_line_error(done, 2, "background-subtracted")


def test_nan_frames_are_named_and_skipped_for_detection(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture, caplog
) -> None:
    values = frames.astype(np.float32)
    values[0, 5, 5] = np.nan
    tifffile.imwrite(tmp_path / "nan.tif", values)
    with caplog.at_level(logging.WARNING):
        done = run_main(process_args(tmp_path / "nan.tif", tmp_path), capsys)
    assert done.status == 0, done.err
    assert "peaks detected on frame 1 (frame 0 holds 1 NaN" in caplog.text
    done = run_main(["peaks", str(tmp_path / "nan.tif")], capsys)
    one_line_error(done, 2, "nan.tif frame 0 holds 1 NaN", "--frame")
    values[:, 0, 0] = np.nan
    tifffile.imwrite(tmp_path / "all.tif", values)
    done = run_main(process_args(tmp_path / "all.tif", tmp_path, "--overwrite"), capsys)
    one_line_error(done, 2, "all.tif: no peaks can be detected on frames 0..9", "frame 0 holds")


@pytest.mark.parametrize(
    ("encode", "message"),
    [
        (lambda text: codecs.BOM_UTF8 + text.encode("utf-8"), None),  # Notepad's UTF-8
        (lambda text: codecs.BOM_UTF16_LE + text.encode("utf-16-le"), None),  # PowerShell's
        (lambda text: bytes(range(256)) * 8, "not text"),
    ],
    ids=["utf8-bom", "utf16", "binary"],
)
def test_experiment_files_from_windows_shells(
    sim_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture, encode, message
) -> None:
    """PowerShell's ``>`` writes UTF-16: read as such; a binary file is one line."""
    from holoview.acquire.recording_reader import RecordingReader

    with RecordingReader(sim_recording) as reader:
        (_, text), *_ = reader.experiments()  # the simulator's true labels
    experiment = json.loads(text)
    experiment["peaks"] = [p for p in experiment["peaks"] if p["label"] in ("RB1", "FB1")]
    (tmp_path / "e.json").write_bytes(encode(json.dumps(experiment)))
    argv = ["-q", "process", str(sim_recording), "--out", str(tmp_path / "o")]
    done = run_main([*argv, "--experiment", str(tmp_path / "e.json")], capsys)
    if message is None:
        assert done.status == 0, done.err
    else:
        one_line_error(done, 2, "e.json", message)


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--wavelength-nm", "532e-9"], "looks like metres: --wavelength-nm takes nanometres"),
        (["--wavelength-nm", "0.532"], "0.532 looks like micrometres"),
        (["--pixel-pitch-um", "2e4"], "20000 looks like nanometres: --pixel-pitch-um takes"),
        (["--n1", "0.5"], "--n1 0.5: a refractive index is at least 1"),
        (["--n1", "1.5"], "n2 = 1.333 must be above n1 = 1.5"),
        (["--fps", "1e-300"], "not a plausible frame rate"),
        (["--fps", "1e300"], "not a plausible frame rate"),
        (["--area", "1e300"], "not a plausible basin area"),
        (["--area", "1e-300"], "not a plausible basin area"),
        (["--radius", "1e-9"], "give a radius from"),
        (["--radius", "0.6"], "beyond Nyquist (0.5)"),
    ],
)
def test_implausible_parameters_are_one_line_without_warnings(
    sim_recording: Path, tmp_path: Path, option: list[str], message: str
) -> None:
    done = run_holoview("-q", "process", str(sim_recording), "--out", str(tmp_path / "o"), *option)
    one_line_error(done, 2, message)
    assert "Warning" not in done.err


def test_a_recording_with_an_implausible_wavelength_needs_the_option(
    frames: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture, caplog
) -> None:
    path = tmp_path / "nm.h5"
    from holoview.acquire.recording_writer import RecordingWriter

    with RecordingWriter(path, (128, 128), np.uint16, setup={"wavelength_m": 532.0}) as w:
        for i, frame in enumerate(frames[:10]):
            w.append(frame, i, i / 20, 1e9 + i / 20)
    with caplog.at_level(logging.WARNING):
        done = run_main(
            ["-q", "process", str(path), "--out", str(tmp_path / "o"), "--fluid", "water"], capsys
        )
    one_line_error(done, 2, "give --wavelength")
    assert "the recording's wavelength_m 532" in caplog.text and "ignored" in caplog.text


def test_threads_are_capped_to_the_cores(
    sim_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture, caplog
) -> None:
    with caplog.at_level(logging.WARNING):
        done = run_main(
            [
                "-q",
                "process",
                str(sim_recording),
                "--out",
                str(tmp_path / "o"),
                "--threads",
                "10000",
                "--frames",
                ":10",
            ],
            capsys,
        )
    assert done.status == 0, done.err
    assert "--threads 10000: this machine has" in caplog.text
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["frames"]["processed"] == 10
