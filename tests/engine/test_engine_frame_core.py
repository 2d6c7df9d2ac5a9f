"""The frame core's demodulator: which peaks it is rebuilt with (and so which series goes on)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import CarrierCore, FrameCore
from holoview.processing.peaks.detection import Peak

SHAPE = (128, 128)
CARRIERS = {"RB1": (0.1875, 0.0625), "RF": (-0.125, 0.21875)}


def _peaks(offset_bins: float = 0.0) -> tuple[Peak, ...]:
    """The two peaks, their carriers moved by ``offset_bins`` FFT bins along x."""
    step = offset_bins / SHAPE[1]
    return tuple(
        Peak(carrier=(fx + step, fy), amplitude=0.05, snr=50.0).relabelled(label, 1.0)
        for label, (fx, fy) in CARRIERS.items()
    )


def _frame() -> np.ndarray:
    y, x = np.mgrid[: SHAPE[0], : SHAPE[1]]
    image = np.full(SHAPE, 1000.0)
    for fx, fy in CARRIERS.values():
        image += 200 * np.cos(2 * np.pi * (fx * x + fy * y))
    return image


def test_a_rebuild_for_the_windows_keeps_the_carriers_and_the_series() -> None:
    """A detection refines the carriers differently each time (a fraction of a bin); a
    rebuild for another reason (here the unwrapping; live, the windows matched again)
    once took those new carriers, which restarted the series measured at them."""
    experiment = Experiment()
    core = FrameCore(SHAPE, experiment, _peaks())
    core.process(_frame())
    first = core.demodulator
    assert first is not None
    series = CarrierCore(SHAPE)
    assert series.configure(first.peaks)  # the series' first set

    core.configure(replace(experiment, unwrap="never"), _peaks(0.4))
    core.process(_frame())
    rebuilt = core.demodulator
    assert rebuilt is not None and rebuilt is not first
    assert rebuilt.peaks == first.peaks
    assert not series.configure(rebuilt.peaks)  # the same series goes on

    core.configure(replace(experiment, unwrap="never"), _peaks(1.5))  # a whole bin: taken
    core.process(_frame())
    moved = core.demodulator
    assert moved is not None and moved.peaks == _peaks(1.5)
    assert series.configure(moved.peaks)
