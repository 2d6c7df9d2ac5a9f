"""Camera sources, the frame ring, the HDF5 recording format and the recorder. No Qt.

``open_source(spec)`` turns ``sim``, ``aravis[:ID]``, ``v4l2[:N]`` or ``replay:PATH``
into an open :class:`~holoview.acquire.source.Source`; a
:class:`~holoview.acquire.camera_thread.CameraThread` drives it into a
:class:`~holoview.acquire.ring.FrameRing`, which a
:class:`~holoview.acquire.recorder.Recorder` (every frame, to a
:class:`~holoview.acquire.recording_writer.RecordingWriter`) and processing (the newest frame)
read at their own pace.
"""

from holoview.acquire.factory import open_source, parse_source_spec

__all__ = ["open_source", "parse_source_spec"]
