"""One engine: the live session and ``holoview process`` give the same numbers on the same frames.

A simulated recording (which carries its true experiment) goes through the live engine
(no Qt: a replay source, the camera thread, the ring, the series worker taking every
frame) and through ``holoview process`` with no peak options; the per-frame carrier
values, the mean heights per peak and fused, and the rates must agree to float32
rounding; every frame's maps, the fused one included, are the same maps step's
(:class:`holoview.engine.map_step.MapStep`), equal to the last bit.
"""

from __future__ import annotations

import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from holoview.cli import main
from holoview.engine.depth import summarise
from holoview.headless.run import process_file
from holoview.headless.settings import ProcessOptions
from holoview.live import maps_pipeline
from holoview.live.session import LiveSession


@pytest.fixture(scope="module")
def recording(simulate_evaporation) -> Path:
    """Evaporation at 60 um/min, 128 x 128, 60 frames at 20 frames/s, with its experiment."""
    return simulate_evaporation(60)


def _live_run(
    path: Path, experiment, monkeypatch: pytest.MonkeyPatch, results: list | None = None
) -> LiveSession:
    """Replay ``path`` once, as fast as it reads, every frame through the live worker.

    ``results``: every frame's :class:`~holoview.live.maps_pipeline.LiveResult` is added to it.
    """
    # peaks are detected once (on the first frame, as process does): the parity is the
    # per-frame core's, not the live re-detection's schedule
    monkeypatch.setattr(maps_pipeline, "PEAKS_HZ", 1e-9)
    session = LiveSession(
        f"replay:{path}",
        experiment,
        source_options={"loop": False, "hold": False, "speed": "fast"},
        every_frame=True,
    )
    if results is not None:
        session.on_maps(lambda: results.append(session.latest()))  # on the maps thread
    session.start()
    deadline = time.monotonic() + 60
    while session.worker.running and time.monotonic() < deadline:
        time.sleep(0.05)
    session.close()
    assert session.stop_reason == "stopped" or "end of stream" in session.stop_reason
    return session


@pytest.mark.parametrize("reference", ["relative", "absolute"])
def test_live_engine_and_process_agree_on_every_frame(
    recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, reference: str
) -> None:
    from holoview.headless.settings import ProcessSettings

    options = ProcessOptions(settings=ProcessSettings(reference=reference), report=False)
    outcome = process_file(recording, tmp_path / "out", options)
    assert outcome.selection.source == "recording"
    session = _live_run(recording, outcome.experiment, monkeypatch)
    for worker in (session.worker, session.series_worker):
        status = worker.status()
        assert status.dropped == 0 and status.skipped == 0 and status.read == 60
    live, headless = session.series_worker.series, outcome.data.series
    assert live is not None and live.labels == headless.labels
    assert {"RB1", "RF", "FB1", "RB2"} <= set(live.labels)
    np.testing.assert_array_equal(live.frames, headless.frames)
    np.testing.assert_allclose(live.times, headless.times, rtol=0, atol=1e-9)
    np.testing.assert_allclose(live.values, headless.values, rtol=2e-6)
    peak_set = session.worker.peak_set()
    assert peak_set is not None
    alphas = [p.alpha for p in peak_set[0]]
    assert alphas == [p.alpha for p in outcome.selection.peaks]
    wavelength = outcome.experiment.wavelength_m
    a, b = summarise(live, alphas, wavelength), session.summary()
    assert b is not None
    np.testing.assert_array_equal(a.heights, b.heights)  # the session's own summary
    analysis = outcome.analysis
    np.testing.assert_allclose(a.heights, analysis.heights, rtol=1e-5, atol=1e-12)
    np.testing.assert_allclose(a.fused, analysis.fused, rtol=1e-5, atol=1e-12)
    assert a.fit.rate == pytest.approx(analysis.fit.rate, rel=1e-5)
    for fit, peak in zip(a.peak_fits, analysis.peaks, strict=True):
        assert fit.rate == pytest.approx(peak.rate, rel=1e-5)


def test_a_fast_injection_watched_live_gives_the_headless_rates(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """25 frames/s at 1.74 um/s, peaks stepping 2-3 rad a frame: live and headless agree."""
    path = tmp_path / "injection.h5"
    argv = ["-q", "simulate", str(path), "--scenario", "injection", "--size", "256"]
    argv += ["--frames", "80", "--fps", "25", "--seed", "2", "--injection-ul-per-s", "12.3"]
    assert main([*argv, "--basin-area-cm2", "70.6"]) == 0
    outcome = process_file(path, tmp_path / "out", ProcessOptions(report=False))
    session = _live_run(path, outcome.experiment, monkeypatch)
    assert session.series_worker.status().read == 80
    live = session.summary()
    assert live is not None and live.margins is not None  # the joint estimate
    headless = outcome.analysis
    assert live.fit.rate == pytest.approx(headless.fit.rate, rel=1e-5)
    with h5py.File(path, "r") as f:
        truth = np.polyfit(f["truth/time_s"][:], f["truth/mean_height_m"][:], 1)[0]
    assert live.fit.rate == pytest.approx(truth, rel=0.01)  # the target: within 1 %
    for fit, peak in zip(live.peak_fits, headless.peaks, strict=True):
        assert fit is not None and fit.rate == pytest.approx(peak.rate, rel=1e-5)


@pytest.mark.parametrize("reference", ["relative", "absolute"])
def test_live_maps_are_those_process_writes(
    recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, reference: str
) -> None:
    """Every frame's maps of each peak and the fused map, live and ``process --maps``: equal.

    The displacements are the one thing the live maps measure as they go (``process``
    before its maps); the evaporating surface has no structure to measure them on, so
    they are zero in both, and the fused maps must be equal too. The windows are the
    bound in both: matched windows are measured on the frames each one sees (``process``
    on frames spread over the run, live on the change between two detections).
    """
    from holoview.headless.settings import ProcessSettings

    settings = ProcessSettings(reference=reference, maps=True, radius="bound")
    outcome = process_file(
        recording, tmp_path / "out", ProcessOptions(settings=settings, report=False)
    )
    results: list = []
    _live_run(recording, outcome.experiment, monkeypatch, results)
    assert [r.frame_index for r in results] == list(range(60))
    assert not any(d.measured for d in outcome.data.displacements[1:])
    with h5py.File(tmp_path / "out" / "results.h5", "r") as f:
        labels = [p.label for p in outcome.analysis.peaks]
        assert {*labels, "fused"} <= set(f["maps"])
        for r in results:
            assert set(r.heights_m) == set(labels)
            for label in labels:
                written = f["maps"][label][r.frame_index]
                trusted = np.isfinite(written)
                assert trusted.any() or r.frame_index == 0
                np.testing.assert_array_equal(r.heights_m[label][trusted], written[trusted])
            assert r.fused_m is not None
            np.testing.assert_array_equal(r.fused_m, f["maps"]["fused"][r.frame_index])
