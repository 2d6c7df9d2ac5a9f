"""Read frames a few ahead of the processing, on a thread named ``holoview-reader``.

File reading (HDF5 chunks, TIFF pages, video decoding) then overlaps with the
demodulation instead of adding to it, and memory stays bounded by ``depth`` frames
in the queue plus the one being read, whatever the input's length.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from types import TracebackType
from typing import Self

import numpy as np

#: Frames read ahead by default.
DEFAULT_DEPTH = 4

#: How often (s) a blocked reader checks whether it was asked to stop.
_POLL_S = 0.1


class _End:
    """Sentinel: the reader has put its last frame."""


class _Failure:
    """The exception the reader met, carried to the consumer."""

    def __init__(self, error: BaseException) -> None:
        self.error = error


class FrameReader:
    """Iterate ``(index, frame)`` over ``indices``, frames read by a background thread.

    Use as a context manager; leaving it stops and joins the thread, also after an
    error or an interruption in the consumer. An exception raised by ``read``
    reaches the consumer at the frame where it happened.

    Parameters
    ----------
    read : callable
        ``read(index) -> ndarray``; called from the reader thread only.
    indices : sequence of int
        Frames to read, in order.
    depth : int
        Frames read ahead at most (>= 1).

    Attributes
    ----------
    read_seconds : float
        Time spent in ``read``, s (complete once the iteration ends).
    """

    def __init__(
        self,
        read: Callable[[int], np.ndarray],
        indices: Sequence[int],
        depth: int = DEFAULT_DEPTH,
    ) -> None:
        self._read = read
        self._indices = indices
        self._queue: queue.Queue[tuple[int, np.ndarray] | _End | _Failure] = queue.Queue(
            maxsize=max(1, int(depth))
        )
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="holoview-reader", daemon=True)
        self.read_seconds = 0.0

    def _put(self, item: tuple[int, np.ndarray] | _End | _Failure) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=_POLL_S)
                return True
            except queue.Full:
                continue
        return False

    def _run(self) -> None:
        try:
            for index in self._indices:
                if self._stop.is_set():
                    return
                start = time.perf_counter()
                frame = self._read(index)
                self.read_seconds += time.perf_counter() - start
                if not self._put((index, frame)):
                    return
        except Exception as exc:  # handed to the consumer, which re-raises it
            self._put(_Failure(exc))
            return
        self._put(_End())

    def __enter__(self) -> Self:
        self._thread.start()
        return self

    def __iter__(self) -> Iterator[tuple[int, np.ndarray]]:
        while True:
            item = self._queue.get()
            if isinstance(item, _End):
                return
            if isinstance(item, _Failure):
                raise item.error
            yield item

    def close(self) -> None:
        """Stop the reader and join it (frames not yet consumed are dropped)."""
        self._stop.set()
        while self._thread.is_alive():
            try:
                while True:
                    self._queue.get_nowait()
            except queue.Empty:
                pass
            self._thread.join(timeout=_POLL_S)

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
