"""The live engine: a source streaming through a ring into the demodulation worker, Qt-free.

:class:`~holoview.live.session.LiveSession` runs the camera thread, the frame ring, the
recorder and the workers (:mod:`holoview.live.worker`), each frame's maps made by
:class:`~holoview.live.maps_pipeline.MapsPipeline` on the engine's per-frame core, in a
process of its own (:mod:`holoview.live.maps_server`), and the series of every frame in
another (:mod:`holoview.live.series_server`). The GUI
(:mod:`holoview.ui`) only reads the latest result and sends commands; a script or a
test can do the same without a display; a replay is steered through
:class:`~holoview.live.replay_control.ReplayControl` (``LiveSession.replay``). While the
Waves panel is open, :mod:`holoview.live.wave_worker` has its map made from every
frame in a process of its own (:mod:`holoview.live.wave_map`) and analyses the last N
(:mod:`holoview.live.wave_window`; ``LiveSession.open_waves``); the window matching
runs in another (:mod:`holoview.live.child_work`).
"""

from holoview.live.maps_pipeline import LiveResult, MapsPipeline
from holoview.live.replay_control import ReplayControl, ReplayState
from holoview.live.session import LiveSession, RecordingProgress, RecordRequest, discover_sources

__all__ = [
    "LiveResult",
    "LiveSession",
    "MapsPipeline",
    "RecordRequest",
    "RecordingProgress",
    "ReplayControl",
    "ReplayState",
    "discover_sources",
]
