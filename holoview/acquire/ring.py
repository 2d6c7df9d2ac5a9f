"""FrameRing: a preallocated, overwrite-oldest frame buffer with per-consumer cursors.

One producer (the camera thread) puts frames; any number of consumers read them,
each at its own pace, in one of two modes:

- ``"every"`` (the recorder): every frame in order; a frame overwritten before the
  consumer read it is counted in its ``dropped``;
- ``"newest"`` (the maps): the newest frame not read yet; the frames passed over are
  counted in ``skipped``, which is by design, not a loss.

A display reads the newest frame without a cursor (:meth:`FrameRing.newest`).

The producer never waits for a consumer. It reserves a slot under a lock, copies
the frame into it outside the lock, and publishes it under the lock; a consumer
picks a frame under the lock, copies it out outside the lock, and checks under the
lock that the producer has not reserved that slot again meanwhile (a seqlock). A
copy that was overwritten is discarded and counted as dropped, never handed out.
Nobody busy-polls: consumers wait on a condition with a timeout. :meth:`FrameRing.close`
is the shutdown sentinel: once the unread frames are read, :meth:`RingConsumer.get`
returns :data:`CLOSED`.

Losses are counted in two places: the ring's consumers count ring overflow, and
the producer reports transport losses (frames the camera or network lost before
the host saw them) with :meth:`FrameRing.add_transport_lost`; :class:`RingStatus`
carries both, apart.
"""

from __future__ import annotations

import threading
import time
from enum import Enum
from typing import Final, Literal, NamedTuple

import numpy as np

from holoview.acquire.source import FrameMeta
from holoview.errors import InputError


class _Closed(Enum):
    """The type of :data:`CLOSED` (an enum of one, so that ``item is CLOSED`` narrows)."""

    CLOSED = "CLOSED"

    def __repr__(self) -> str:
        return "CLOSED"


#: Returned by :meth:`RingConsumer.get` once the ring is closed and drained.
CLOSED: Final = _Closed.CLOSED


class RingStatus(NamedTuple):
    """Frame accounting for one consumer (pyLabLib's ``TFramesStatus``, plus transport).

    Attributes
    ----------
    acquired : int
        Frames put into the ring since it was made.
    unread : int
        Frames in the ring this consumer has not read yet and still can.
    dropped : int
        Frames overwritten before this consumer read them (ring overflow).
    capacity : int
        Frames the ring holds.
    skipped : int
        Frames a ``"newest"`` consumer passed over by design (0 for ``"every"``).
    transport_lost : int
        Frames the camera or transport lost before they reached the ring.
    read : int
        Frames this consumer has read.
    """

    acquired: int
    unread: int
    dropped: int
    capacity: int
    skipped: int = 0
    transport_lost: int = 0
    read: int = 0


class FrameRing:
    """A fixed-size ring of frames of one shape and dtype, preallocated.

    Parameters
    ----------
    capacity : int
        Number of frames held (at least 2); memory is ``capacity * rows * cols *
        itemsize`` bytes, allocated once.
    frame_shape : tuple of int
        ``(rows, cols)``, pixels.
    dtype : numpy dtype
        The frames' dtype.
    """

    def __init__(self, capacity: int, frame_shape: tuple[int, int], dtype: np.typing.DTypeLike):
        if int(capacity) < 2:
            raise InputError(f"ring capacity must be at least 2 frames, got {capacity}")
        self.capacity = int(capacity)
        self.frame_shape = (int(frame_shape[0]), int(frame_shape[1]))
        self.dtype = np.dtype(dtype)
        self._data = np.zeros((self.capacity, *self.frame_shape), self.dtype)
        self._meta: list[FrameMeta | None] = [None] * self.capacity
        self._cond = threading.Condition()
        self._published = 0  # frames whose copy is complete
        self._reserved = 0  # frames whose slot has been claimed (published or being written)
        self._closed = False
        self._transport_lost = 0
        self._consumers: list[RingConsumer] = []

    @property
    def nbytes(self) -> int:
        """Bytes of frame memory the ring holds (fixed)."""
        return int(self._data.nbytes)

    @property
    def acquired(self) -> int:
        """Frames put so far."""
        return self._published

    @property
    def transport_lost(self) -> int:
        """Frames reported lost before they reached the ring."""
        return self._transport_lost

    @property
    def closed(self) -> bool:
        """True once :meth:`close` was called."""
        return self._closed

    def put(self, data: np.ndarray, meta: FrameMeta) -> None:
        """Copy a frame into the ring, overwriting the oldest; never waits for a consumer.

        Raises
        ------
        ValueError
            The frame's shape or dtype is not the ring's (the producer must check).
        RuntimeError
            The ring is closed.
        """
        if data.shape != self.frame_shape or data.dtype != self.dtype:
            raise ValueError(
                f"frame {data.shape} {data.dtype} does not fit a ring of "
                f"{self.frame_shape} {self.dtype}"
            )
        with self._cond:
            if self._closed:
                raise RuntimeError("the frame ring is closed")
            seq = self._reserved
            self._reserved = seq + 1
        slot = seq % self.capacity
        np.copyto(self._data[slot], data)
        self._meta[slot] = meta
        with self._cond:
            self._published = seq + 1
            self._cond.notify_all()

    def newest(self) -> tuple[int, np.ndarray, FrameMeta] | None:
        """Return ``(seq, pixels, meta)`` of the newest complete frame, or None.

        For a display that shows the camera at its own rate: the pixels are a copy,
        and no consumer's cursor moves. None before the first frame, or when the
        frame was overwritten while it was being copied (the next call gets a newer).
        """
        with self._cond:
            seq = self._published - 1
            if seq < 0:
                return None
            slot = seq % self.capacity
            meta = self._meta[slot]
        pixels = self._data[slot].copy()
        with self._cond:
            if meta is None or seq < self._reserved - self.capacity:
                return None
        return seq, pixels, meta

    def add_transport_lost(self, n: int) -> None:
        """Count ``n`` more frames lost by the camera or transport before the ring."""
        if n > 0:
            with self._cond:
                self._transport_lost += int(n)

    def close(self) -> None:
        """Mark the end of the stream; consumers get :data:`CLOSED` once drained."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def consumer(self, name: str, mode: Literal["every", "newest"] = "newest") -> RingConsumer:
        """Return a new consumer that starts with the next frame put.

        Parameters
        ----------
        name : str
            For logs and status displays (``"recorder"``, ``"processing"``).
        mode : {"every", "newest"}
            ``"every"``: every frame in order (drops counted); ``"newest"``: the newest.
        """
        if mode not in ("every", "newest"):
            raise ValueError(f"consumer mode must be 'every' or 'newest', got {mode!r}")
        with self._cond:
            consumer = RingConsumer(self, name, mode, start=self._published)
            self._consumers.append(consumer)
        return consumer

    def consumers(self) -> list[RingConsumer]:
        """The consumers made so far."""
        with self._cond:
            return list(self._consumers)


class RingConsumer:
    """One reader of a :class:`FrameRing` with its own cursor; make it with ``ring.consumer``."""

    def __init__(self, ring: FrameRing, name: str, mode: str, start: int) -> None:
        self.ring = ring
        self.name = name
        self.mode = mode
        self._next = start
        self._start = start
        self._read = 0
        self._dropped = 0
        self._skipped = 0

    @property
    def position(self) -> int:
        """Sequence number (count of frames put into the ring) of the next frame to read."""
        return self._next

    def status(self) -> RingStatus:
        """Return this consumer's :class:`RingStatus`."""
        ring = self.ring
        with ring._cond:
            oldest = max(0, ring._reserved - ring.capacity)
            unread = max(0, ring._published - max(self._next, oldest))
            overwritten = max(0, oldest - self._next)  # lost already, counted on the next get
            return RingStatus(
                acquired=ring._published - self._start,
                unread=unread,
                dropped=self._dropped + (overwritten if self.mode == "every" else 0),
                capacity=ring.capacity,
                skipped=self._skipped,
                transport_lost=ring._transport_lost,
                read=self._read,
            )

    def get(
        self, timeout: float | None = 1.0, out: np.ndarray | None = None
    ) -> tuple[np.ndarray, FrameMeta] | _Closed | None:
        """Return ``(pixels, meta)`` of the next frame for this consumer.

        Parameters
        ----------
        timeout : float, optional
            Seconds to wait for a frame; None waits until one comes or the ring closes.
        out : ndarray, optional
            Where to copy the pixels (reused buffers avoid an allocation per frame).

        Returns
        -------
        tuple, CLOSED or None
            The frame (a copy the consumer owns), :data:`CLOSED` when the ring is closed
            and this consumer has read what remains, or None on timeout.
        """
        ring = self.ring
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            with ring._cond:
                while self._next >= ring._published:
                    if ring._closed:
                        return CLOSED
                    remaining = None if deadline is None else deadline - time.monotonic()
                    if remaining is not None and remaining <= 0:
                        return None
                    ring._cond.wait(remaining)
                oldest = max(0, ring._reserved - ring.capacity)
                if self.mode == "newest":
                    seq = max(self._next, ring._published - 1, oldest)
                    self._skipped += seq - self._next
                else:
                    seq = max(self._next, oldest)
                    self._dropped += seq - self._next
                self._next = seq + 1
                slot = seq % ring.capacity
                meta = ring._meta[slot]
            pixels = ring._data[slot].copy() if out is None else out
            if out is not None:
                np.copyto(out, ring._data[slot])
            with ring._cond:
                intact = seq >= ring._reserved - ring.capacity
                if not intact:
                    self._dropped += 1
            if intact and meta is not None:
                self._read += 1
                return pixels, meta
