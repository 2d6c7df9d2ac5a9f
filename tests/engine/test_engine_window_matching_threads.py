"""Live windows matched on another thread: measured on a snapshot, taken between frames.

The measurement (:meth:`WindowMatcher.propose`) runs on the live match thread; the maps'
core (:class:`FrameCore`) then builds its demodulator with the windows it is handed and
measures nothing (seconds on a large frame), also when its carriers or neighbours move.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "processing"))
from wavy_scene import render, travelling_waves, true_peaks, wavy_setup

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FrameCore
from holoview.engine.window_matching import WindowMatcher, windows_in_use
from holoview.processing.peaks import radii
from holoview.processing.peaks.radii import UNMEASURED_REASON


@pytest.fixture(scope="module")
def scenes():
    setup = wavy_setup()
    waves, _ = render(setup, travelling_waves(2, k_range=(300.0, 600.0), rms=10e-9), 4, seed=2)
    return setup, waves


def _core(setup, peaks) -> FrameCore:
    experiment = Experiment(reference="absolute", wavelength_m=setup.wavelength)
    return FrameCore(setup.shape, experiment, peaks)


def _no_measuring(monkeypatch) -> None:
    def refuse(*args, **kwargs):
        raise AssertionError("the maps' core measured a matched window")

    monkeypatch.setattr(radii, "matched_window", refuse)


def test_windows_measured_elsewhere_are_built_without_measuring(scenes, monkeypatch) -> None:
    setup, waves = scenes
    core = _core(setup, true_peaks(setup)[:4])
    matcher = WindowMatcher()
    assert matcher.propose(windows_in_use(core), waves[0]) is None  # one frame, no peak
    assert matcher.propose(windows_in_use(core), waves[1]) is None  # no demodulator yet
    core.build()
    in_use = windows_in_use(core)  # taken between frames; the measurement goes on elsewhere
    rematch = matcher.propose(in_use, waves[2])
    assert rematch is not None and "matched to the surface's change" in rematch.note
    _no_measuring(monkeypatch)
    rematch.apply(core)
    core.build()
    built = core.windows()
    assert {k: w.radius for k, w in built.items()} == {
        k: w.radius for k, w in rematch.windows.items()
    }
    assert {w.rule for w in built.values()} == {"matched"}
    # a carrier that moves a whole bin rebuilds the demodulator: the windows are kept,
    # within the new bounds, still without measuring
    rows, _ = setup.shape
    moved = [replace(p, carrier=(p.carrier[0], p.carrier[1] + 1.5 / rows)) for p in core.peaks]
    core.configure(core.experiment, moved)
    core.build()
    assert core.demodulator is not None and core.demodulator.peaks[0].carrier == moved[0].carrier
    for label, window in core.windows().items():
        assert window.radius == min(rematch.windows[label].radius, window.bound)


def test_a_peak_added_after_a_match_is_matched_at_the_next_measurement(scenes) -> None:
    setup, waves = scenes
    peaks = true_peaks(setup)
    core = _core(setup, peaks[:3])
    core.build()
    matcher = WindowMatcher()
    matcher.propose(windows_in_use(core), waves[0])
    first = matcher.propose(windows_in_use(core), waves[1])
    assert first is not None
    first.apply(core)
    core.configure(core.experiment, peaks[:4])  # a fourth label
    core.build()
    added = core.windows()[peaks[3].label]
    assert added.reason == UNMEASURED_REASON and added.radius == added.bound
    again = matcher.propose(windows_in_use(core), waves[2])
    assert again is not None and "new peaks" in again.note
    again.apply(core)
    core.build()
    assert core.windows()[peaks[3].label].reason != UNMEASURED_REASON
