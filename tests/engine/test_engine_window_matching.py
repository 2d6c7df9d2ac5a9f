"""Live windows matched again: the first change measured, on request, when the bandwidth changes."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "processing"))
from wavy_scene import render, travelling_waves, true_peaks, wavy_setup

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FrameCore
from holoview.engine.window_matching import CONFIRMATIONS, WindowMatcher


@pytest.fixture(scope="module")
def scenes():
    setup = wavy_setup()
    flat, _ = render(setup, travelling_waves(1, rms=0.0), 2, seed=1)
    waves, _ = render(setup, travelling_waves(2, k_range=(300.0, 600.0), rms=10e-9), 8, seed=2)
    return setup, flat, waves


def _core(setup, **changes) -> FrameCore:
    experiment = Experiment(reference="absolute", wavelength_m=setup.wavelength, **changes)
    return FrameCore(setup.shape, experiment, true_peaks(setup)[:4])


def _radii(core: FrameCore) -> list[float]:
    core.build()
    return [w.radius for w in core.windows().values()]


def test_windows_follow_a_change_of_the_surfaces_bandwidth_and_say_so(scenes) -> None:
    setup, flat, waves = scenes
    core = _core(setup)
    matcher = WindowMatcher()
    assert matcher.measure(core, flat[0]) is None  # one frame: nothing to compare yet
    bound = _radii(core)
    note = matcher.measure(core, flat[1])
    assert note is not None and "matched to the surface's change" in note
    assert _radii(core) == bound  # a flat surface: the bound, with its reason
    assert {w.rule for w in core.windows().values()} == {"bound"}
    notes = [matcher.measure(core, frame) for frame in waves[: CONFIRMATIONS + 1]]
    assert notes[: CONFIRMATIONS - 1] == [None] * (CONFIRMATIONS - 1)  # not at once
    changed = next(n for n in notes if n is not None)
    assert "the surface's bandwidth changed" in changed and "RB1 0.0496 -> " in changed
    narrow = _radii(core)
    assert max(narrow) < 0.8 * max(bound)
    assert {w.rule for w in core.windows().values()} == {"matched"}
    # steady: no change, no note; asked: matched again at once, said so
    assert matcher.measure(core, waves[CONFIRMATIONS + 1]) is None
    matcher.request()
    asked = matcher.measure(core, waves[CONFIRMATIONS + 2])
    assert asked is not None and "on request" in asked


def test_a_radius_rule_other_than_matched_is_left_alone(scenes) -> None:
    setup, flat, waves = scenes
    core = _core(setup, radius="bound")
    matcher = WindowMatcher()
    for frame in (*flat, *waves):
        assert matcher.measure(core, frame) is None
    assert _radii(core) and core.spectrum is None
    assert {w.rule for w in core.windows().values()} == {"bound"}


def test_a_frame_equal_to_the_last_changes_nothing(scenes) -> None:
    """A stuck camera sends one frame twice: nothing to measure, the windows stay (before:
    InputError 'the spectrum has no noise floor' out of the live maps worker)."""
    setup, _flat, waves = scenes
    core = _core(setup)
    matcher = WindowMatcher()
    matcher.measure(core, waves[0])
    matcher.measure(core, waves[1])
    before = core.windows()
    assert matcher.measure(core, waves[1].copy()) is None
    assert core.windows() == before
