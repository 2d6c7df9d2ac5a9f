"""The read-ahead thread of a headless run: order, errors, early exit, bounded queue."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.headless.reader import FrameReader


def test_frames_come_in_order_and_reading_is_timed() -> None:
    reader = FrameReader(lambda i: np.full((4, 4), i), range(3, 40, 3), depth=2)
    with reader:
        got = [(index, int(frame[0, 0])) for index, frame in reader]
    assert got == [(i, i) for i in range(3, 40, 3)]
    assert reader.read_seconds > 0


def test_a_read_error_reaches_the_consumer_at_its_frame() -> None:
    def read(index: int) -> np.ndarray:
        if index == 5:
            raise InputError("frame 5 is unreadable")
        return np.zeros((2, 2))

    seen = []
    with pytest.raises(InputError, match="frame 5"), FrameReader(read, range(10)) as reader:
        seen.extend(index for index, _ in reader)
    assert seen == [0, 1, 2, 3, 4]


def test_leaving_early_stops_and_joins_the_reader() -> None:
    reads = []
    release = threading.Event()

    def read(index: int) -> np.ndarray:
        reads.append(index)
        if index == 2:
            release.set()
        return np.zeros((2, 2))

    with FrameReader(read, range(1000), depth=2) as reader:
        for index, _ in reader:
            if index == 0:
                assert release.wait(2.0)
                break
    # at most the queue's depth plus the one in hand were read ahead of the consumer
    assert len(reads) <= 5
    assert not any(t.name == "holoview-reader" for t in threading.enumerate())
