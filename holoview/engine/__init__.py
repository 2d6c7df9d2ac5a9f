"""The one engine: the experiment and the per-frame core the GUI and ``holoview process`` share.

No Qt, no threads: the live session (:mod:`holoview.live`) runs it frame by frame on its
worker thread, ``holoview process`` (:mod:`holoview.headless`) on every frame of a file,
so both give the same numbers on the same frames.

- :mod:`~holoview.engine.experiment`: optics, labelled peaks, window, reference and
  unwrapping; the one JSON format.
- :mod:`~holoview.engine.resolve`: which peaks to demodulate (one snapping rule; the
  model's families added).
- :mod:`~holoview.engine.frame_core`: the carrier probe and the demodulator of a set of peaks.
- :mod:`~holoview.engine.map_step`: one frame's maps: trusted maps, phase steps,
  co-registration, fusion, shifts in camera pixels.
- :mod:`~holoview.engine.series`: the mean-phase series, depths, fused depth and rates.
- :mod:`~holoview.engine.peak_geometry`: window warnings for the operator.
"""

from holoview.engine.depth import DepthSummary, summarise
from holoview.engine.experiment import Experiment, LabelledPeak
from holoview.engine.frame_core import FrameCore
from holoview.engine.map_step import FrameMaps, MapStep, fuse_maps, trusted_maps
from holoview.engine.resolve import Resolution, resolve_peaks
from holoview.engine.series import PhaseSeries

__all__ = [
    "DepthSummary",
    "Experiment",
    "FrameCore",
    "FrameMaps",
    "LabelledPeak",
    "MapStep",
    "PhaseSeries",
    "Resolution",
    "fuse_maps",
    "resolve_peaks",
    "summarise",
    "trusted_maps",
]
