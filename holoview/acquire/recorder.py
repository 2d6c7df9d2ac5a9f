"""The recorder thread: every frame of a ring into a holoview recording.

It reads the ring as an ``"every"`` consumer, so it gets every frame in order and
counts exactly the frames the ring overwrote before it could write them. It
flushes the file at least every ``flush_interval_s`` of the writer, also when no
frame comes. It stops when the ring closes (after writing what remains), once it
has written ``max_frames`` or ``max_seconds`` have passed since the first frame it
records arrived (a GigE camera can take seconds to start streaming; frames that
arrived within the time are written, whenever the thread gets to them; no caller
needs to poll; with no frame at all, after :data:`FIRST_FRAME_WAIT_S` or
``max_seconds``, whichever is longer), on :meth:`Recorder.stop`, or on a write error (kept in
:attr:`Recorder.error`: a full disk, an I/O error); in every case it closes the
file, so everything written stays readable, also by plain h5py. After a write
error :meth:`Recorder.accounting` counts the frames the camera went on acquiring
as lost to the disk: every frame acquired is recorded, dropped or lost.
"""

from __future__ import annotations

import logging
import math
import os
import queue
import threading
import time
from collections.abc import Callable, Mapping
from typing import NamedTuple

import numpy as np

from holoview.acquire.pixel_formats import PIXEL_FORMATS
from holoview.acquire.recording_writer import RecordingWriteError, RecordingWriter
from holoview.acquire.ring import FrameRing, RingStatus
from holoview.acquire.source import Source
from holoview.errors import InputError

logger = logging.getLogger(__name__)

#: Seconds a recorder with a duration waits for a first frame (a GigE camera can take a
#: few to stream), or the duration where that is longer, before it ends with none.
FIRST_FRAME_WAIT_S = 10.0


def _significant_bits(pixel_format: object) -> int | None:
    """Bits of data per value for a known pixel format name, else None."""
    fmt = PIXEL_FORMATS.get(pixel_format) if isinstance(pixel_format, str) else None
    return fmt.bits if fmt is not None else None


class Accounting(NamedTuple):
    """Where every frame the camera acquired during a recording went.

    ``acquired == recorded + dropped + lost_to_disk`` once the recorder has ended.

    Attributes
    ----------
    acquired : int
        Frames put into the ring since the recorder started.
    recorded : int
        Frames written to the file.
    dropped : int
        Frames the ring overwrote before the recorder could write them (overflow).
    lost_to_disk : int
        Frames acquired after a write error ended the recording (or that it could
        not write).
    transport_lost : int
        Frames the camera or its transport lost before the ring (not in ``acquired``).
    """

    acquired: int
    recorded: int
    dropped: int
    lost_to_disk: int
    transport_lost: int


class Recorder:
    """Write every frame of ``ring`` with ``writer`` on a thread named ``holoview-recorder``.

    The recorder owns ``writer`` and closes it when it ends.

    Parameters
    ----------
    ring : FrameRing
        Frames to record; the recorder becomes one of its consumers at construction
        and records from the next frame put.
    writer : RecordingWriter
        An open writer whose frame shape and dtype are the ring's.
    max_frames : int, optional
        Stop after writing this many frames (None: until stopped or the ring closes).
    max_seconds : float, optional
        Record the frames that arrive within this many seconds of the first one
        recorded (by their host arrival times), then stop (None: no time limit).
    carried : callable, optional
        ``carried(index)``: the experiment (JSON text, or None) a replayed file carries
        for its frame ``index`` (:meth:`Source.carried_experiment`). Each frame's is
        looked up by the frame's index in the file, and stored from that frame of the
        recording whenever it differs from the one stored last: a copy keeps the
        experiment and its changes, at frame numbers of the copy.
    """

    def __init__(
        self,
        ring: FrameRing,
        writer: RecordingWriter,
        *,
        max_frames: int | None = None,
        max_seconds: float | None = None,
        carried: Callable[[int], str | None] | None = None,
    ) -> None:
        if max_frames is not None and max_frames < 1:
            writer.close()
            raise InputError(f"max_frames must be at least 1, got {max_frames}")
        if max_seconds is not None and not (math.isfinite(max_seconds) and max_seconds > 0):
            writer.close()
            raise InputError(f"max_seconds must be positive, got {max_seconds}")
        if writer.frame_shape != ring.frame_shape or writer.dtype != ring.dtype:
            writer.close()
            raise InputError(
                f"recording {writer.frame_shape} {writer.dtype} does not fit the ring's "
                f"{ring.frame_shape} {ring.dtype}"
            )
        self.ring = ring
        self.writer = writer
        self.max_frames = max_frames
        self.max_seconds = max_seconds
        # host time (UNIX epoch, s) past which frames are not recorded: set by the first frame
        self._deadline = math.inf
        self._consumer = ring.consumer("recorder", mode="every")
        #: The error that ended recording early, or None.
        self.error: BaseException | None = None
        self._dropped_at_end: int | None = None
        self._acquired_at_limit: int | None = None  # a limit ended it: later frames not counted
        self._span = [math.nan, math.nan]  # monotonic start and end of the thread, s
        self._stop = threading.Event()
        self._stop_at = 0  # with drain, the ring position to record up to before stopping
        self._experiments: queue.SimpleQueue[str] = queue.SimpleQueue()
        self._carried = carried
        self._carried_last: str | None = None
        self._thread = threading.Thread(target=self._run, name="holoview-recorder", daemon=True)

    @classmethod
    def for_source(
        cls,
        ring: FrameRing,
        path: str | os.PathLike[str],
        source: Source,
        *,
        setup: Mapping[str, object] | None = None,
        max_frames: int | None = None,
        max_seconds: float | None = None,
        experiment: str | None = None,
    ) -> Recorder:
        """Return a recorder to a new file at ``path`` that describes ``source``.

        The file gets the source's name, every setting the source reads back, with
        its unit (a value HDF5 cannot hold as an attribute is left out, with a
        warning), the source's pixel format, the setup: the source's own
        (:attr:`Source.setup`) updated with ``setup``, and the ``experiment`` in force
        (JSON text). Without ``experiment``, the experiments a replayed source carries
        are copied, with their changes (``carried`` of :class:`Recorder`); an
        ``experiment`` replaces them. ``max_frames`` and ``max_seconds`` as for
        :class:`Recorder`.
        """
        infos = source.describe_settings()
        settings = {}
        for name, value in source.get_all().items():
            if not isinstance(value, int | float | str | bool | tuple):
                logger.warning("setting %s (%s) is not recorded", name, type(value).__name__)
                continue
            settings[name] = (tuple(value) if isinstance(value, tuple) else value, infos[name].unit)
        pixel_format = settings.get("pixel_format", (None, ""))[0]
        writer = RecordingWriter(
            path,
            ring.frame_shape,
            ring.dtype,
            setup={**source.setup, **(setup or {})},
            settings=settings,
            source=source.name,
            pixel_format=pixel_format if isinstance(pixel_format, str) else None,
            significant_bits=_significant_bits(pixel_format),
            experiment=experiment,
        )
        carried = source.carried_experiment if experiment is None else None
        return cls(ring, writer, max_frames=max_frames, max_seconds=max_seconds, carried=carried)

    @property
    def written(self) -> int:
        """Frames written to the file so far."""
        return len(self.writer)

    @property
    def elapsed_s(self) -> float:
        """Seconds from :meth:`start` to the end of recording (to now while running)."""
        start, end = self._span
        if math.isnan(start):
            return 0.0
        return (time.monotonic() if math.isnan(end) else end) - start

    @property
    def running(self) -> bool:
        """True while the thread runs."""
        return self._thread.is_alive()

    def status(self) -> RingStatus:
        """The recorder's ring accounting: acquired, unread, dropped, capacity, ..."""
        return self._consumer.status()

    def accounting(self) -> Accounting:
        """Acquired, recorded, dropped, lost to the disk, and lost in transport so far."""
        status = self._consumer.status()
        recorded = len(self.writer)
        if self._dropped_at_end is None:  # running: what waits in the ring is not lost yet
            return Accounting(status.acquired, recorded, status.dropped, 0, status.transport_lost)
        acquired = status.acquired if self._acquired_at_limit is None else self._acquired_at_limit
        lost = max(0, acquired - recorded - self._dropped_at_end)
        return Accounting(acquired, recorded, self._dropped_at_end, lost, status.transport_lost)

    def start(self) -> None:
        """Start the thread (the clock of ``max_seconds`` starts with the first frame)."""
        if self.max_seconds is not None:  # until a first frame comes
            self._deadline = time.time() + max(self.max_seconds, FIRST_FRAME_WAIT_S)
        self._span[0] = time.monotonic()
        self._thread.start()

    def note_experiment(self, text: str) -> None:
        """Record that the experiment (JSON text) changed: it holds from the next frame written."""
        self._experiments.put(text)

    def stop(self, timeout: float = 10.0, *, drain: bool = True) -> None:
        """Stop recording and join the thread; the file is closed when it returns.

        Parameters
        ----------
        timeout : float
            Seconds to wait for the thread.
        drain : bool
            True: first write every frame the ring had acquired when ``stop`` was
            called (those still in the ring); False: stop after the frame in hand.
        """
        self._stop_at = self.ring.acquired if drain else 0
        self._stop.set()
        self.join(timeout)

    def join(self, timeout: float | None = None) -> bool:
        """Wait until the ring is closed and drained (or stop/error); True once ended."""
        if self._thread.ident is not None:
            self._thread.join(timeout)
        return not self._thread.is_alive()

    def _end_at_limit(self) -> None:
        """A limit ends the recording: frames acquired from now on were not asked for."""
        self._acquired_at_limit = len(self.writer) + self._consumer.status().dropped

    def _run(self) -> None:
        writer = self.writer
        buffer = np.empty(self.ring.frame_shape, self.ring.dtype)
        try:
            while not self._stop.is_set() or self._consumer.position < self._stop_at:
                item = self._consumer.get(timeout=min(0.2, writer.flush_interval_s), out=buffer)
                if item is None:
                    writer.flush_if_due()
                    if time.time() >= self._deadline:  # the time is up and no frame waits
                        self._end_at_limit()
                        break
                    continue
                if not isinstance(item, tuple):  # CLOSED
                    break
                pixels, meta = item
                if self.max_seconds is not None and len(writer) == 0:  # the first frame
                    self._deadline = meta.t_host + self.max_seconds
                if meta.t_host >= self._deadline:  # this frame and the later ones are not asked for
                    self._end_at_limit()
                    break
                while not self._experiments.empty():
                    writer.note_experiment(self._experiments.get())
                if self._carried is not None and meta.file_index >= 0:
                    text = self._carried(meta.file_index)
                    if text is not None and text != self._carried_last:
                        writer.note_experiment(text)
                        self._carried_last = text
                writer.append(pixels, meta.frame_id, meta.t_device, meta.t_host)
                if self.max_frames is not None and len(writer) >= self.max_frames:
                    self._end_at_limit()
                    break
        except RecordingWriteError as exc:  # a full disk, an I/O error: the file is closed below
            self.error = exc
            logger.debug("recorder stopped: %s", exc)
        except Exception as exc:  # a bug: keep the traceback, still close the file
            self.error = exc
            logger.exception("recorder failed on %s", writer.path)
        finally:
            self._span[1] = time.monotonic()
            self._dropped_at_end = self._consumer.status().dropped
            try:
                writer.close()
            except RecordingWriteError as exc:
                self.error = self.error or exc
                logger.debug("closing %s: %s", writer.path, exc)
            logger.info("recorder: %d frames written; %s", len(writer), self.accounting())
