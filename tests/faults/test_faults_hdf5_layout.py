"""Recordings that point outside themselves, or whose layout is damaged.

HDF5 lets a recording's ``/frames`` keep its bytes in any readable file (external
storage), name a dataset of another file (an external link), be assembled from other
files (a virtual dataset) or be a soft link to itself. Each is refused by every reader
(``process``, ``peaks``, ``record --source replay:``), one line naming the file and the
member; nothing outside the recording is read or copied.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
from faults_helpers import one_line_error, run_main, write_recording

#: A file outside the recording whose bytes must never be read into one.
SECRET = bytes(range(256)) * 64


@pytest.fixture(scope="module")
def frames(sim_recording: Path) -> np.ndarray:
    with h5py.File(sim_recording, "r") as f:
        return f["frames"][:6]


def _copy_attrs(source: h5py.Dataset, target: h5py.Dataset) -> None:
    for name, value in source.attrs.items():
        target.attrs[name] = value


def external_storage(f: h5py.File, secret: Path, source: Path) -> None:
    attrs = f["frames"]
    shape, dtype = attrs.shape, attrs.dtype
    saved = dict(attrs.attrs)
    del f["frames"]
    nbytes = int(np.prod(shape)) * dtype.itemsize
    ds = f.create_dataset("frames", shape, dtype, external=[(str(secret), 0, nbytes)])
    for name, value in saved.items():
        ds.attrs[name] = value


def external_link(f: h5py.File, secret: Path, source: Path) -> None:
    del f["frames"]
    f["frames"] = h5py.ExternalLink(str(source), "/frames")


def virtual_dataset(f: h5py.File, secret: Path, source: Path) -> None:
    shape, dtype = f["frames"].shape, f["frames"].dtype
    del f["frames"]
    layout = h5py.VirtualLayout(shape, dtype)
    layout[:] = h5py.VirtualSource(str(source), "frames", shape=shape)
    ds = f.create_virtual_dataset("frames", layout)
    with h5py.File(source, "r") as other:
        _copy_attrs(other["frames"], ds)


def soft_link_to_itself(f: h5py.File, secret: Path, source: Path) -> None:
    del f["frames"]
    f["frames"] = h5py.SoftLink("/frames")


def external_times(f: h5py.File, secret: Path, source: Path) -> None:
    del f["t_device_s"]
    f["t_device_s"] = h5py.ExternalLink(str(source), "/t_device_s")


def external_setup(f: h5py.File, secret: Path, source: Path) -> None:
    del f["setup"]
    f["setup"] = h5py.ExternalLink(str(source), "/setup")


LAYOUTS: dict[str, tuple[Callable[[h5py.File, Path, Path], None], str]] = {
    "external-storage": (external_storage, "/frames is stored in other files"),
    "external-link": (external_link, "/frames is an external link"),
    "virtual": (virtual_dataset, "/frames is a virtual dataset"),
    "soft-link-loop": (soft_link_to_itself, "/frames is a soft link to /frames"),
    "external-times": (external_times, "/t_device_s is an external link"),
    "external-setup": (external_setup, "/setup is an external link"),
}


@pytest.fixture
def outside(tmp_path: Path, frames: np.ndarray) -> tuple[Path, Path]:
    """A secret file and another recording, in a folder apart from the recording."""
    folder = tmp_path / "elsewhere"
    folder.mkdir()
    secret = folder / "secret.bin"
    secret.write_bytes(SECRET)
    return secret, write_recording(folder / "other.h5", frames[::-1].copy(), swmr=False)


def make(tmp_path: Path, frames: np.ndarray, outside: tuple[Path, Path], layout: str) -> Path:
    path = write_recording(tmp_path / f"{layout}.h5", frames, swmr=False)
    with h5py.File(path, "a") as f:
        LAYOUTS[layout][0](f, *outside)
    return path


@pytest.mark.parametrize("layout", list(LAYOUTS))
def test_members_outside_the_recording_are_refused_by_every_reader(
    tmp_path: Path,
    frames: np.ndarray,
    outside: tuple[Path, Path],
    capsys: pytest.CaptureFixture,
    layout: str,
) -> None:
    path = make(tmp_path, frames, outside, layout)
    message = LAYOUTS[layout][1]
    copy = tmp_path / "copy.h5"
    done = run_main(["-q", "record", str(copy), "--source", f"replay:{path}"], capsys)
    one_line_error(done, 2, str(path), message, "stored in the recording itself")
    assert not copy.exists()
    out = tmp_path / "out"
    done = run_main(["-q", "process", str(path), "--out", str(out), "--fluid", "water"], capsys)
    one_line_error(done, 2, str(path), message)
    assert not out.exists()
    one_line_error(run_main(["peaks", str(path)], capsys), 2, str(path), message)


def test_a_plain_recording_beside_them_is_copied_whole(
    tmp_path: Path, frames: np.ndarray, capsys: pytest.CaptureFixture
) -> None:
    """The check refuses what points outside, not recordings: a plain one copies as before."""
    path = write_recording(tmp_path / "plain.h5", frames, swmr=False)
    copy = tmp_path / "copy.h5"
    done = run_main(
        ["-q", "record", str(copy), "--source", f"replay:{path}", "--set", "speed=fast"], capsys
    )
    assert done.status == 0, done.err
    with h5py.File(copy, "r") as f:
        np.testing.assert_array_equal(f["frames"][:], frames)


def _damage_experiment(path: Path, how: str) -> None:
    with h5py.File(path, "a") as f:
        group = f["experiment"]
        if how == "changes-1d-float":
            del group["changes"]
            group["changes"] = np.array([0.0, 0.0, 10.0])
        elif how == "json-string":
            del group["json"]
            group["json"] = json.dumps({"format": "holoview-experiment", "version": 2})
        elif how == "offset-past-end":
            del group["changes"]
            group["changes"] = np.array([[0, 10**6, 40]], dtype=np.int64)
        elif how == "nested-100000":
            del group["json"], group["changes"]
            text = np.frombuffer(b"[" * 100_000 + b"]" * 100_000, np.uint8)
            group["json"] = text
            group["changes"] = np.array([[0, 0, text.size]], dtype=np.int64)
        elif how == "radius-5000-digits":
            del group["json"], group["changes"]
            raw = b'{"format": "holoview-experiment", "version": 2, "radius": ' + b"7" * 5000
            text = np.frombuffer(raw + b"}", np.uint8)
            group["json"] = text
            group["changes"] = np.array([[0, 0, text.size]], dtype=np.int64)
        elif how == "external-json":
            del group["json"]
            group["json"] = h5py.ExternalLink("/etc/hostname", "/json")


@pytest.mark.parametrize(
    "case",
    [
        ("changes-1d-float", "/experiment/changes is float64 of shape (3,)"),
        ("json-string", "/experiment/json is object of shape ()"),
        ("offset-past-end", "names bytes 1000000 to 1000040"),
        ("nested-100000", "nested too deeply"),
        ("radius-5000-digits", "radius must be finite"),
        ("external-json", "/experiment/json is an external link"),
    ],
)
def test_a_damaged_stored_experiment_falls_back_to_automatic_peaks(
    tmp_path: Path,
    sim_recording: Path,
    capsys: pytest.CaptureFixture,
    caplog: pytest.LogCaptureFixture,
    case: tuple[str, str],
) -> None:
    """README: a recording whose experiment cannot be read is processed with --auto, said so."""
    how, reason = case
    path = tmp_path / "damaged.h5"
    path.write_bytes(sim_recording.read_bytes())
    _damage_experiment(path, how)
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING):
        done = run_main(["process", str(path), "--out", str(out)], capsys)
    assert done.status == 0, done.err
    assert "Traceback" not in done.err
    assert reason in caplog.text and "ignored" in caplog.text, caplog.text
    assert "--auto 4" in caplog.text
    summary = json.loads((out / "summary.json").read_text())
    assert summary["parameters"]["peaks_from"] == "auto"
    assert any(reason in note for note in summary["notes"]), summary["notes"]
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        done = run_main(["-q", "peaks", str(path)], capsys)
    assert done.status == 0, done.err
    assert reason in caplog.text
    caplog.clear()
    copy = tmp_path / "copy.h5"
    with caplog.at_level(logging.WARNING):
        done = run_main(
            ["-q", "record", str(copy), "--source", f"replay:{path}", "--frames", "5"], capsys
        )
    assert done.status == 0, done.err
    assert "Traceback" not in done.err
    if how in ("nested-100000", "radius-5000-digits"):  # a text: carried, refused when parsed
        return
    assert reason in caplog.text and "the copy carries no experiment" in caplog.text
    with h5py.File(copy, "r") as f:
        assert "experiment" not in f or f["experiment/changes"].shape[0] == 0
