"""The camera thread: fetch, stamp, store into the ring; nothing else.

It runs on a thread named ``holoview-camera``, never waits for a consumer (the
ring overwrites the oldest frame; only a replay may be paced, :attr:`CameraThread.pace`),
passes the source's transport losses on to the ring, and closes the ring when it
ends, which is the shutdown sentinel every consumer sees. An error (a camera
unplugged mid-stream) ends the thread cleanly: it is kept in
:attr:`CameraThread.error` for the caller to show, and the frames already in the
ring stay readable.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from collections.abc import Callable

from holoview.acquire.ring import FrameRing
from holoview.acquire.source import AcquisitionError, EndOfStream, Source
from holoview.errors import HoloviewError, InputError

logger = logging.getLogger(__name__)

#: Seconds without a frame after which the frame rate reads 0.
RATE_STALE_S = 2.0


class CameraThread:
    """Drive a started :class:`Source` into a :class:`FrameRing` on its own thread.

    Parameters
    ----------
    source : Source
        An open source; :meth:`start` starts its stream, the thread stops it.
    ring : FrameRing
        Where frames go; its shape and dtype must be the source's. Closed at the end.
    max_frames : int, optional
        Stop after this many frames (None: until :meth:`stop` or the end of the stream).
    fetch_timeout_s : float
        Seconds each fetch waits before the thread checks whether it should stop.
    """

    def __init__(
        self,
        source: Source,
        ring: FrameRing,
        *,
        max_frames: int | None = None,
        fetch_timeout_s: float = 0.25,
    ) -> None:
        if source.frame_shape != ring.frame_shape or source.dtype != ring.dtype:
            raise InputError(
                f"ring {ring.frame_shape} {ring.dtype} does not fit the source's "
                f"{source.frame_shape} {source.dtype}"
            )
        if max_frames is not None and max_frames < 1:
            raise InputError(f"max_frames must be at least 1, got {max_frames}")
        self.source = source
        self.ring = ring
        self.max_frames = max_frames
        self.fetch_timeout_s = fetch_timeout_s
        #: The error that ended the thread, or None.
        self.error: BaseException | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="holoview-camera", daemon=True)
        self._frames = 0
        self._times: collections.deque[float] = collections.deque(maxlen=64)
        self._lost_seen = 0
        #: Called with the stop flag before each fetch; it may wait (a replay played as
        #: fast as it reads waits for a consumer that must see every frame). Never set
        #: for a camera: the producer of a live stream never waits.
        self.pace: Callable[[threading.Event], None] | None = None

    @property
    def frames(self) -> int:
        """Frames put into the ring so far."""
        return self._frames

    @property
    def running(self) -> bool:
        """True while the thread runs."""
        return self._thread.is_alive()

    @property
    def started(self) -> bool:
        """True once :meth:`start` has started the thread (it closes the ring when it ends)."""
        return self._thread.ident is not None

    def rate_hz(self) -> float:
        """Frame rate over the last 64 frames, frames per second.

        0 before two frames, and after :data:`RATE_STALE_S` without one (a paused
        replay, a stalled camera).
        """
        times = list(self._times)
        if len(times) < 2 or times[-1] <= times[0]:
            return 0.0
        if time.monotonic() - times[-1] > RATE_STALE_S:
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0])

    def start(self) -> None:
        """Start the source's stream (errors raise here) and then the thread."""
        self.source.start()
        self._lost_seen = self.source.counters.get("lost", 0)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Ask the thread to stop and join it; the ring is closed when it returns."""
        self._stop.set()
        self.join(timeout)

    def join(self, timeout: float | None = None) -> bool:
        """Wait for the thread to end (max_frames reached, end of stream, error, stop).

        Returns
        -------
        bool
            True when the thread has ended.
        """
        if self._thread.ident is not None:
            self._thread.join(timeout)
        return not self._thread.is_alive()

    def _run(self) -> None:
        source, ring = self.source, self.ring
        try:
            while not self._stop.is_set():
                if self.pace is not None:
                    self.pace(self._stop)
                frame = source.fetch(self.fetch_timeout_s)
                self._pass_on_losses()
                if frame is None:
                    continue
                if frame.data.shape != ring.frame_shape or frame.data.dtype != ring.dtype:
                    raise AcquisitionError(
                        f"{source.name} delivered a {frame.data.shape} {frame.data.dtype} frame "
                        f"where the stream began with {ring.frame_shape} {ring.dtype}: "
                        "restart the stream after changing the region or pixel format"
                    )
                ring.put(frame.data, frame.meta)
                self._frames += 1
                self._times.append(time.monotonic())
                if self.max_frames is not None and self._frames >= self.max_frames:
                    break
        except EndOfStream:
            logger.info("%s: end of stream after %d frames", source.name, self._frames)
        except HoloviewError as exc:
            self.error = exc
            logger.error("%s: %s", source.name, exc)
        except Exception as exc:  # a bug: keep the traceback, still shut down cleanly
            self.error = exc
            logger.exception("camera thread failed on %s", source.name)
        finally:
            try:
                source.stop()
            except HoloviewError as exc:
                logger.warning("%s: stopping failed: %s", source.name, exc)
            self._pass_on_losses()
            ring.close()

    def _pass_on_losses(self) -> None:
        lost = self.source.counters.get("lost", 0)
        if lost > self._lost_seen:
            self.ring.add_transport_lost(lost - self._lost_seen)
            self._lost_seen = lost
