"""An input replaced while it is processed: refused by name, nothing written (issue 25).

Before: ``mv`` of another recording of the same shape over the input of ``process
--jobs 2`` gave exit 0 with the chunks of two recordings stitched (fused -1.04 um/min
for -0.82), and a shorter one an ``IndexError``: the workers compared the frame shape
only. Real files, replaced with ``os.replace`` (what ``mv`` does) or rewritten in place.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path

import h5py
import numpy as np
import pytest
import tifffile
from faults_helpers import (
    finish,
    one_line_error,
    start_holoview,
    wait_for,
    write_recording,
)

from holoview.acquire.recording_writer import RecordingWriter
from holoview.errors import InputError
from holoview.headless.input_identity import InputIdentity
from holoview.headless.parallel.chunks import make_tasks, measure_chunk
from holoview.processing.peaks.detection import Peak

SHAPE = (3, 64, 48)  # frames, rows, cols of the small inputs


def _frames(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(100, 4000, SHAPE, dtype=np.uint16)


def _write_video(path: Path, frames: np.ndarray) -> None:
    import cv2

    fourcc = cv2.VideoWriter_fourcc(*"FFV1")
    writer = cv2.VideoWriter(str(path), fourcc, 10.0, frames.shape[:0:-1], isColor=False)
    for frame in frames:
        writer.write((frame >> 4).astype(np.uint8))
    writer.release()


def _write(kind: str, path: Path, frames: np.ndarray) -> Path:
    """An input of ``kind`` holding ``frames`` at ``path`` (a folder for ``folder``)."""
    if kind == "hdf5":
        return write_recording(path.with_suffix(".h5"), frames)
    if kind == "tiff":
        tifffile.imwrite(path.with_suffix(".tif"), frames, photometric="minisblack")
        return path.with_suffix(".tif")
    if kind == "numpy":
        np.save(path.with_suffix(".npy"), frames)
        return path.with_suffix(".npy")
    if kind == "video":
        _write_video(path.with_suffix(".avi"), frames)
        return path.with_suffix(".avi")
    path.mkdir()
    for k, frame in enumerate(frames):
        tifffile.imwrite(path / f"img{k:03d}.tif", frame)
    return path


def _replace(kind: str, original: Path, other: Path) -> None:
    """Put ``other``'s content at ``original``'s path, as ``mv`` does."""
    if kind != "folder":
        os.replace(other, original)
        return
    # one image of the folder replaced by one of the other's: same name, same size; a
    # later modification time, as any copy made after the run started has
    image = original / "img001.tif"
    os.replace(other / "img001.tif", image)
    later = image.stat().st_mtime + 10
    os.utime(image, (later, later))


@pytest.mark.parametrize("kind", ["hdf5", "tiff", "numpy", "video", "folder"])
def test_each_kind_of_input_knows_when_it_was_replaced(kind: str, tmp_path: Path) -> None:
    """The identity of every kind of input: the same when untouched, changed when replaced."""
    original = _write(kind, tmp_path / "input", _frames(1))
    other = _write(kind, tmp_path / "other", _frames(2))
    identity = InputIdentity.of(original)
    identity.check()  # untouched: nothing raised
    assert InputIdentity.of(original) == identity
    _replace(kind, original, other)
    with pytest.raises(InputError, match="replaced during the run") as caught:
        identity.check()
    assert str(original.resolve()) in str(caught.value)


def test_a_recording_still_being_written_keeps_its_identity(tmp_path: Path) -> None:
    """Frames appended to a recording (its size and time change): the same recording."""
    frames = _frames(3)
    path = tmp_path / "growing.h5"
    setup = {"wavelength_m": 532e-9, "pixel_pitch_m": 20e-6, "n1": 1.0, "n2": 1.333}
    with RecordingWriter(path, frames.shape[1:], frames.dtype, setup=setup) as writer:
        writer.append(frames[0], 0, 0.0, 1e9)
        identity = InputIdentity.of(path)
        for i in (1, 2):
            writer.append(frames[i], i, i / 50, 1e9 + i / 50)
        identity.check()
    identity.check()


def test_a_worker_refuses_an_input_replaced_since_the_run_started(tmp_path: Path) -> None:
    """The worker's check before its chunk: the file's name, the worker's host, exit 2's error."""
    original = write_recording(tmp_path / "run.h5", _frames(4))
    other = write_recording(tmp_path / "other.h5", _frames(5))
    task = make_tasks(
        original,
        range(3),
        [range(0, 3)],
        peaks=(Peak(carrier=(0.2, 0.1), amplitude=0.1, snr=10.0),),
        frame_shape=SHAPE[1:],
        saturation=4095.0,
        identity=InputIdentity.of(original),
    )[0]
    assert len(measure_chunk(task)) == 3  # untouched: measured
    os.replace(other, original)
    host = socket.gethostname()
    with pytest.raises(InputError, match=f"replaced during the run \\(a worker on {host} finds"):
        measure_chunk(task)


@pytest.fixture(scope="module")
def long_recording(tmp_path_factory: pytest.TempPathFactory, sim_recording: Path) -> Path:
    """2000 frames (the simulation's 40, over and over) as a holoview recording."""
    with h5py.File(sim_recording, "r") as f:
        frames = f["frames"][:]
    path = tmp_path_factory.mktemp("long") / "long.h5"
    return write_recording(path, np.tile(frames, (50, 1, 1)))


def _rolled_copy(path: Path, target: Path) -> Path:
    """Another stack of the same shape and length: the frames of ``path``, shifted by 7."""
    np.save(target, np.roll(np.load(path, mmap_mode="r"), 7, axis=0))
    return target


@pytest.mark.slow
@pytest.mark.parametrize(
    "case",
    ["numpy, same length", "recording, shorter", "recording, same length, --maps"],
)
def test_an_input_replaced_mid_run_is_refused_and_nothing_written(
    case: str,
    long_stack: Path,
    long_recording: Path,
    sim_recording: Path,
    tmp_path: Path,
) -> None:
    """``mv`` over the input of ``process --jobs 2`` mid-run: one line naming it, exit 2."""
    if case.startswith("numpy"):
        source = tmp_path / "s.npy"
        source.write_bytes(long_stack.read_bytes())
        replacement = _rolled_copy(long_stack, tmp_path / "other.npy")
    else:
        source = tmp_path / "s.h5"
        source.write_bytes(long_recording.read_bytes())
        replacement = tmp_path / "other.h5"  # another recording (its own uuid)
        if case.endswith("shorter"):
            replacement.write_bytes(sim_recording.read_bytes())  # 40 frames
        else:
            with h5py.File(long_recording, "r") as f:
                write_recording(replacement, np.roll(f["frames"][:], 7, axis=0))
    out = tmp_path / "results"
    extra = ["--maps"] if "--maps" in case else []
    child = start_holoview(
        "-q", "process", str(source), "--out", str(out), "--fps", "20",
        "--wavelength-nm", "532", "--fluid", "water", "--jobs", "2", *extra,
    )  # fmt: skip
    wait_for(lambda: out.is_dir() and any(out.glob(".results.*.partial.h5")), what="the run")
    os.replace(replacement, source)
    done = finish(child, timeout=120)
    line = one_line_error(done, 2, "replaced during the run")
    assert str(source.resolve()) in line
    assert not out.exists() or list(out.iterdir()) == []  # nothing written, no temporary left
