"""The live pipeline (Qt-free) on synthetic holograms: labels, model predictions, maps, trends."""

from __future__ import annotations

import math

import numpy as np
import pytest

from holoview.acquire.source import FrameMeta
from holoview.engine.experiment import Experiment, LabelledPeak
from holoview.live import maps_pipeline, series_pipeline
from holoview.live.maps_pipeline import MapsPipeline, block_max
from holoview.live.series_pipeline import SeriesPipeline

from .holograms import FB1, N1, N2, RB1, WAVELENGTH_M, carriers, hologram_stack


def _experiment(**changes: object) -> Experiment:
    base = Experiment(
        wavelength_m=WAVELENGTH_M,
        n1=N1,
        n2=N2,
        radius=0.05,
        reference="absolute",
        peaks=(LabelledPeak("RB1", RB1), LabelledPeak("FB1", FB1)),
    )
    return Experiment(**{**base.__dict__, **changes})


def _run(pipeline: MapsPipeline, frames: np.ndarray, dt: float = 0.1) -> list:
    return [
        pipeline.process(frame, FrameMeta(frame_id=i, t_device=i * dt, t_host=100.0 + i * dt))
        for i, frame in enumerate(frames)
    ]


def test_block_max_keeps_narrow_peaks() -> None:
    image = np.zeros((1024, 1000), np.float32)
    image[517, 3] = 5.0
    small = block_max(image, 512)
    assert small.shape == (512, 500) and small.max() == 5.0 and small[258, 1] == 5.0


def test_two_labels_bring_predicted_peaks_and_maps() -> None:
    frames = hologram_stack(6, (128, 128))
    results = _run(MapsPipeline(_experiment(), (128, 128)), frames)
    last = results[-1]
    truth = carriers()
    assert set(last.predicted) >= {"RF", "RB2"}
    assert last.predicted["RF"] == pytest.approx(truth["RF"], abs=1 / 128)
    assert set(last.labelled) == set(truth)  # RF and RB2 matched on detected peaks
    for name, carrier in truth.items():
        assert last.labelled[name] == pytest.approx(carrier, abs=2 / 128)
    assert set(last.heights_m) == set(truth)
    assert last.fused_m is not None and last.fused_m.shape == last.heights_m["RB1"].shape
    # the bump rises 5 nm per frame at its centre; the absolute map after 5 frames shows ~25 nm
    centre = last.fused_m[last.fused_m.shape[0] // 2, last.fused_m.shape[1] // 2]
    assert centre == pytest.approx(25e-9, rel=0.3)
    assert last.spectrum is not None and last.spectrum.shape == (128, 128)


def test_maps_are_co_registered_by_their_measured_displacements(monkeypatch) -> None:
    """Families imaging the bump at shifted places: the shifts are measured, in camera pixels,
    against the first labelled peak, and the fused map is put on its grid."""
    monkeypatch.setattr(maps_pipeline, "COREGISTER_HZ", math.inf)  # every frame
    images = {"RB1": (0.5, -0.5), "RF": (3.0, -2.0), "RB2": (-2.0, 1.5)}
    frames = hologram_stack(40, (128, 128), shifts=images)
    results = _run(MapsPipeline(_experiment(), (128, 128)), frames)
    assert results[0].shifts_px == {"RB1": (0.0, 0.0)}  # a reference frame: nothing measured
    last = results[-1]
    assert last.grid_of == "RB1" and last.fused_m is not None
    assert last.shifts_px["RB1"] == (0.0, 0.0)
    for name in ("FB1", "RF", "RB2"):
        image = images.get(name, (0.0, 0.0))
        expected = (images["RB1"][0] - image[0], images["RB1"][1] - image[1])
        # 0.6 camera pixel is 0.075 of these maps' pixels (8 camera pixels, 16 x 16 maps):
        # a residual under 3 standard errors (about 0.035 map pixel here) leaves the
        # estimate where it is (the ringdown's false shifts), so FB1's 0.0625 map pixel
        # along y may stay unmeasured within 40 frames
        assert last.shifts_px[name] == pytest.approx(expected, abs=0.6), name


def test_maps_too_small_to_co_register_are_fused_unmoved() -> None:
    frames = hologram_stack(3, (32, 32))
    last = _run(MapsPipeline(_experiment(radius=0.06), (32, 32)), frames)[-1]
    assert last.fused_m is not None and min(last.fused_m.shape) < 8
    assert last.shifts_px == {} and last.grid_of is None


def test_custom_label_has_phase_but_no_height() -> None:
    frames = hologram_stack(3, (128, 128))
    experiment = _experiment(peaks=(LabelledPeak("mine", RB1),))
    last = _run(MapsPipeline(experiment, (128, 128)), frames)[-1]
    assert last.predicted == {}
    assert "mine" in last.phases_rad and "mine" not in last.heights_m


def test_commands_change_settings_between_frames() -> None:
    pipeline = MapsPipeline(_experiment(peaks=()), (128, 128))
    frames = hologram_stack(2, (128, 128))
    assert _run(pipeline, frames[:1])[0].labelled == {}
    pipeline.apply("experiment", _experiment())
    result = _run(pipeline, frames)[-1]
    assert "RB1" in result.labelled


def test_reset_restarts_the_absolute_reference() -> None:
    pipeline = MapsPipeline(_experiment(), (128, 128))
    frames = hologram_stack(6, (128, 128))
    before = _run(pipeline, frames[:4])[-1]
    assert np.nanmax(np.abs(before.fused_m)) > 5e-9
    pipeline.apply("reset", None)
    after = _run(pipeline, frames[4:5])[-1]
    assert np.nanmax(np.abs(after.fused_m)) < 1e-12  # the new reference frame


def _series_run(frames: np.ndarray, dt: float = 0.1) -> tuple[SeriesPipeline, list]:
    """The maps pipeline resolves the peaks; the series pipeline takes every frame."""
    maps = MapsPipeline(_experiment(), (128, 128))
    series = SeriesPipeline((128, 128))
    trends = []
    for i, frame in enumerate(frames):
        meta = FrameMeta(frame_id=i, t_device=i * dt, t_host=100.0 + i * dt)
        maps.process(frame, meta)
        series.set_peaks(maps.peaks, maps.experiment)
        trends.append(series.process(frame, meta))
    return series, trends


def test_series_takes_every_frame_and_summarises_depths_and_rate(monkeypatch) -> None:
    monkeypatch.setattr(series_pipeline, "TREND_HZ", math.inf)  # a summary every frame
    series, trends = _series_run(hologram_stack(6, (128, 128)))
    assert trends[:2] == [None, None]  # fewer than three frames
    last = trends[-1]
    assert last is not None and len(last.times_s) == 6
    np.testing.assert_allclose(last.times_s, np.arange(6) * 0.1)
    assert set(last.depths_m) >= {"RB1", "FB1", "RF", "RB2", "fused"}
    # the mean of the bump rises with it: a positive rate; the series holds every frame
    assert last.rate_m_per_s is not None and last.rate_m_per_s > 0
    assert series.series is not None and len(series.series) == 6
    assert [t.seq for t in trends if t is not None] == [1, 2, 3, 4]


def test_series_restarts_on_reset_and_on_new_peaks(monkeypatch) -> None:
    monkeypatch.setattr(series_pipeline, "TREND_HZ", math.inf)
    frames = hologram_stack(6, (128, 128))
    series, _ = _series_run(frames[:4])
    series.apply("reset")
    assert series.process(frames[4], FrameMeta(4, 0.4, 0.4)) is None  # one frame since
    assert len(series.series) == 1
    series.set_peaks(series.carriers.peaks[:2], series.experiment)
    assert series.series is None  # other peaks: a new series from the next frame
    series.apply("pca", True)
    assert series.pca
