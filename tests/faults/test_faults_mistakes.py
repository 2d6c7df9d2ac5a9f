"""A user's mistakes on record and simulate: one line, exit 2, checked first, no file left."""

from __future__ import annotations

import signal
from pathlib import Path

import numpy as np
import pytest
from faults_helpers import (
    finish,
    one_line_error,
    run_main,
    start_holoview,
    wait_for,
    write_recording,
)

from holoview.acquire import recorder


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--size", "100000"], "--size must be from 8 to 8192"),
        (["--seed", "-1"], "--seed must be an integer from 0"),
        (["--seed", str(10**27)], "--seed must be an integer from 0"),
        (["--photons", "1e300"], "photons_per_pixel = 1e+300 photons is beyond any camera"),
        (["--wavelength-nm", "532e-9"], "looks like metres: --wavelength-nm takes nanometres"),
        (["--pixel-pitch-um", "2e-5"], "looks like metres: --pixel-pitch-um takes micrometres"),
        (["--png", "{tmp}"], "is a folder"),
        (["--png", "{tmp}/existing.png"], "exists; holoview does not overwrite it"),
        (["--png", "{tmp}/figure.xyz"], "no image writer for that suffix"),
    ],
)
def test_simulate_checks_every_option_first(
    tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], message: str
) -> None:
    (tmp_path / "existing.png").write_bytes(b"keep")
    out = tmp_path / "sim.h5"
    argv = ["simulate", str(out), "--size", "32", "--frames", "3"]
    done = run_main([*argv, *(a.format(tmp=tmp_path) for a in args)], capsys)
    one_line_error(done, 2, message)
    assert not out.exists()
    assert (tmp_path / "existing.png").read_bytes() == b"keep"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["existing.png"]


def test_a_stopped_simulation_leaves_no_file(tmp_path: Path) -> None:
    out = tmp_path / "sim.h5"
    child = start_holoview("simulate", str(out), "--size", "256", "--frames", "5000")
    wait_for(lambda: any(tmp_path.glob(".sim.*.partial.h5")), timeout=60, what="the simulation")
    child.send_signal(signal.SIGTERM)
    done = finish(child, timeout=30)
    assert done.status == 130, done.err
    assert "interrupted by SIGTERM" in done.err and "Traceback" not in done.err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--wavelength-nm", "nan"], "'nan' is not a finite positive number"),
        (["--wavelength-nm", "532e-9"], "looks like metres"),
        (["--pixel-pitch-um", "-5"], "'-5' is not a finite positive number"),
        (["--n2", "0.9"], "--n2 0.9: a refractive index is at least 1"),
        (["--n1", "1.5"], "the source's n2 = 1.333 must be above n1 = 1.5"),
        (["--ring-mb", "1e9"], "more than half this machine's memory"),
        (["--ring-mb", "inf"], "--ring-mb must be a positive number"),
    ],
)
def test_record_refuses_implausible_setups_and_rings(
    tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], message: str
) -> None:
    out = tmp_path / "rec.h5"
    done = run_main(["record", str(out), "--frames", "3", *args], capsys)
    one_line_error(done, 2, message)
    assert list(tmp_path.iterdir()) == []


def test_a_recording_with_no_frame_is_not_kept(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
):
    """A source that gave nothing: no empty file blocks the next attempt. The duration counts
    from the first frame; with none, the recorder ends after its wait for one."""
    monkeypatch.setattr(recorder, "FIRST_FRAME_WAIT_S", 0.5)
    frames = np.zeros((3, 32, 32), np.uint16) + np.arange(32, dtype=np.uint16)
    source = write_recording(tmp_path / "in.h5", frames)
    out = tmp_path / "rec.h5"
    argv = ["-q", "record", str(out), "--source", f"replay:{source}", "--set", "speed=step"]
    done = run_main([*argv, "--seconds", "0.3"], capsys)
    assert done.status == 2
    assert "acquired 0, recorded 0" in done.out
    assert done.err.strip() == f"holoview record: no frame was recorded; {out} is not kept"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.h5"]
