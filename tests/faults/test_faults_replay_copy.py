"""``record --source replay:`` copies keep the experiment the source carries, and its changes."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from faults_helpers import run_holoview

from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.recording_writer import RecordingWriter


def fused_rate(out: Path) -> float:
    return json.loads((out / "summary.json").read_text())["fused"]["rate_m_per_s"]


def test_a_copy_is_processed_as_its_source(sim_recording: Path, tmp_path: Path) -> None:
    """Without the experiment the copy fell back to automatic peaks: the rate's sign flipped."""
    copy = tmp_path / "copy.h5"
    done = run_holoview("-q", "record", str(copy), "--source", f"replay:{sim_recording}",
                        "--set", "speed=fast")  # fmt: skip
    assert done.status == 0, done.err
    with RecordingReader(sim_recording) as source, RecordingReader(copy) as copied:
        assert copied.experiments() == source.experiments() != []
    with h5py.File(sim_recording, "r") as f:
        truth = -float(f["truth"].attrs["evaporation_rate_m_per_s"])  # the level falls
    for name, path in (("source", sim_recording), ("copy", copy)):
        done = run_holoview("-q", "process", str(path), "--out", str(tmp_path / name))
        assert done.status == 0, done.err
        assert "--auto" not in done.err  # the copy's peaks come from its experiment
    assert fused_rate(tmp_path / "copy") == fused_rate(tmp_path / "source")
    assert fused_rate(tmp_path / "copy") == pytest.approx(truth, rel=0.05)


@pytest.fixture
def changing(tmp_path: Path) -> Path:
    """40 frames carrying experiment A from frame 0 and B from frame 20."""
    frames = np.random.default_rng(3).integers(0, 4000, (40, 16, 16), dtype=np.uint16)
    path = tmp_path / "changing.h5"
    setup = {"wavelength_m": 532e-9, "pixel_pitch_m": 20e-6, "n1": 1.0, "n2": 1.333}
    with RecordingWriter(path, (16, 16), np.uint16, setup=setup, experiment='{"name": "A"}') as w:
        for i, frame in enumerate(frames):
            if i == 20:
                w.note_experiment('{"name": "B"}')
            w.append(frame, i, i / 50.0, 1e9 + i / 50.0)
    return path


def test_changes_are_copied_at_the_copy_s_frame_numbers(changing: Path, tmp_path: Path) -> None:
    copy = tmp_path / "looped.h5"
    done = run_holoview("-q", "record", str(copy), "--source", f"replay:{changing}",
                        "--set", "speed=fast", "--set", "loop=true", "--frames", "70")  # fmt: skip
    assert done.status == 0, done.err
    with RecordingReader(copy) as copied:
        ids = copied.frame_ids
        changes = copied.experiments()
    assert len(ids) == 70
    # where each copied frame came from in the source, and what was in force there
    expected, last = [], None
    for k, source_index in enumerate(ids % 40):
        text = '{"name": "A"}' if source_index < 20 else '{"name": "B"}'
        if text != last:
            expected.append((k, text))
            last = text
    assert changes == expected
    assert [k for k, _ in changes] == [0, 20, 40, 60]


def test_an_experiment_given_replaces_the_source_s(changing: Path, tmp_path: Path) -> None:
    experiment = tmp_path / "mine.json"
    experiment.write_text(
        json.dumps({"format": "holoview-experiment", "version": 2, "wavelength_m": 6.33e-7})
    )
    copy = tmp_path / "copy.h5"
    done = run_holoview("-q", "record", str(copy), "--source", f"replay:{changing}",
                        "--set", "speed=fast", "--experiment", str(experiment))  # fmt: skip
    assert done.status == 0, done.err
    with RecordingReader(copy) as copied:
        changes = copied.experiments()
    assert len(changes) == 1 and changes[0][0] == 0
    assert json.loads(changes[0][1])["wavelength_m"] == 6.33e-7
