"""Peak detection on frames damaged in transfer: flagged with the reason, never minutes long."""

from __future__ import annotations

import itertools
import logging
from pathlib import Path

import h5py
import numpy as np
import pytest
from faults_helpers import one_line_error, run_main, write_recording

from holoview.acquire.simulated import SimulatedSource
from holoview.optics.setup import Setup
from holoview.optics.synthesis import HologramSynthesizer
from holoview.processing.fourier.frames import DamagedFrameError, frame_damage
from holoview.processing.fourier.windows import wrap_frequency
from holoview.processing.peaks.detection import (
    MAX_CANDIDATES,
    RELATION_TOLERANCE_BINS,
    Peak,
    find_peaks,
    flag_relations,
)


def corrupted_frames(n: int) -> list[np.ndarray]:
    """Frames of the simulated camera with a band of rows zeroed (its ``corrupt_rate``)."""
    with SimulatedSource(shape=(256, 256), frame_rate_hz=1000, seed=3, corrupt_rate=1.0) as cam:
        cam.start()
        out = []
        while len(out) < n:
            frame = cam.fetch(1.0)
            if frame is not None:
                out.append(frame.data.copy())
        cam.stop()
    return out


def test_the_simulators_lost_packets_are_flagged_and_not_searched() -> None:
    for frame in corrupted_frames(5):
        reason = frame_damage(frame)
        assert reason is not None and "are all 0 (lost packets?)" in reason
        with pytest.raises(DamagedFrameError, match="frame is damaged: rows") as damaged:
            find_peaks(frame)
        assert damaged.value.reason == reason


@pytest.mark.parametrize("edge", ["top", "bottom"])
def test_packets_lost_at_an_edge_are_damage_a_dark_border_is_not(edge: str) -> None:
    frame = HologramSynthesizer(Setup(shape=(256, 256))).render(0.0, rng=np.random.default_rng(1))
    cut = frame.copy()
    rows = slice(0, 40) if edge == "top" else slice(216, 256)
    cut[rows] = 0
    assert "are all 0" in frame_damage(cut)
    apertured = Setup(shape=(256, 256), aperture_radius=2.3e-3, beam_waist=2e-3)
    dark_border = HologramSynthesizer(apertured).render(0.0, rng=np.random.default_rng(1))
    assert (dark_border[:3] == 0).all()  # whole rows of zeros outside the field stop
    assert frame_damage(dark_border) is None
    assert find_peaks(dark_border)


def test_a_clean_frame_is_not_damaged(sim_recording: Path) -> None:
    with h5py.File(sim_recording, "r") as f:
        for frame in f["frames"][::5]:
            assert frame_damage(frame) is None
    flat_row = frame.copy()
    flat_row[60] = 1234
    assert frame_damage(flat_row) == "row 60 of 128 is constant at 1234"


def cubic_relations(peaks: list[Peak], shape: tuple[int, int], radius: float) -> list[set[str]]:
    """The definition, checked pair by pair (what holoview did before, cubic in n)."""

    def bins(a: np.ndarray, b: np.ndarray) -> float:
        d = wrap_frequency(np.asarray(a) - np.asarray(b))
        return float(np.hypot(d[0] * shape[1], d[1] * shape[0]))

    carriers = np.array([p.carrier for p in peaks])
    out = []
    for i, peak in enumerate(peaks):
        flags: set[str] = set()
        stronger = [j for j, p in enumerate(peaks) if p.amplitude > peak.amplitude]
        f = carriers[i]
        if any(
            min(bins(f, 2 * carriers[j]), bins(f, -2 * carriers[j])) <= RELATION_TOLERANCE_BINS
            for j in stronger
        ):
            flags.add("harmonic")
        for j, k in itertools.combinations(stronger, 2):
            for sj, sk in itertools.product((1, -1), repeat=2):
                if bins(f, sj * carriers[j] + sk * carriers[k]) <= RELATION_TOLERANCE_BINS:
                    flags.add("sum")
        others = np.concatenate([np.delete(carriers, i, axis=0), -carriers])
        d = wrap_frequency(f - others)
        if np.hypot(d[:, 0], d[:, 1]).min() < 2 * radius:
            flags.add("overlap")
        if np.abs(f).max() + radius > 0.5:
            flags.add("near_nyquist")
        out.append(flags)
    return out


@pytest.mark.parametrize("seed", range(8))
def test_relations_by_trees_equal_the_definition(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shape = (int(rng.choice([128, 200, 256])), int(rng.choice([128, 256, 320])))
    base = rng.uniform(-0.4, 0.4, (4, 2))
    carriers = [*base, 2 * base[0], -2 * base[1] + rng.normal(0, 0.8 / shape[0], 2)]
    for _ in range(20):  # sums of the strong ones, a little off, and strays
        a, b = rng.integers(0, 4, 2)
        s1, s2 = rng.choice([-1, 1], 2)
        near = s1 * base[a] + s2 * base[b] + rng.normal(0, 0.8 / shape[0], 2)
        carriers.append(near if rng.random() < 0.7 else rng.uniform(-0.5, 0.5, 2))
    amplitudes = [*rng.uniform(0.9, 1.0, 4), *rng.uniform(0.001, 0.95, len(carriers) - 4)]
    peaks = [
        Peak(tuple(float(v) for v in wrap_frequency(c)), float(a), 10.0)
        for c, a in zip(carriers, amplitudes, strict=True)
    ]
    for radius in (0.01, 0.04):
        found = [set(p.flags) for p in flag_relations(peaks, shape, radius=radius)]
        assert found == cubic_relations(peaks, shape, radius)
        assert any("sum" in f for f in found) and any("harmonic" in f for f in found)


def test_relations_of_thousands_of_candidates_are_found() -> None:
    """Cubic, this took hours; with trees it is a fraction of a second (benchmarks/ times it)."""
    rng = np.random.default_rng(0)
    peaks = [
        Peak((float(x), float(y)), float(a), 10.0)
        for (x, y), a in zip(
            rng.uniform(-0.5, 0.5, (3000, 2)), rng.uniform(0, 1, 3000), strict=True
        )
    ]
    flagged = flag_relations(peaks, (1024, 1024), radius=0.01)
    assert len(flagged) == 3000
    assert sum("overlap" in p.flags for p in flagged) > 100


def test_candidates_are_capped_on_a_frame_of_speckle() -> None:
    rng = np.random.default_rng(2)
    speckle = rng.exponential(100.0, (256, 256)).astype(np.float32)
    peaks = find_peaks(speckle, threshold=1.01, min_separation=1)
    assert 0 < len(peaks) <= MAX_CANDIDATES


def test_peaks_on_a_damaged_frame_is_one_line(tmp_path: Path, capsys) -> None:
    path = write_recording(tmp_path / "lost.h5", np.stack(corrupted_frames(3)))
    done = run_main(["peaks", str(path), "--frame", "1"], capsys)
    one_line_error(done, 2, "lost.h5 frame 1 is damaged: rows", "(lost packets?)", "--frame")


def test_process_detects_on_the_first_undamaged_frame(
    sim_recording: Path, tmp_path: Path, capsys, caplog
) -> None:
    with h5py.File(sim_recording, "r") as f:
        frames = f["frames"][:]
    frames[0, 40:56] = 0  # frame 0 lost packets
    path = write_recording(tmp_path / "first.h5", frames)
    with caplog.at_level(logging.WARNING):
        done = run_main(["-q", "process", str(path), "--out", str(tmp_path / "o")], capsys)
    assert done.status == 0, done.err
    assert "peaks detected on frame 1 (frame 0 is damaged: rows 40-55 of 128" in caplog.text
