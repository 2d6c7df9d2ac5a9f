"""FrameRing: order, overwrite-oldest accounting, newest-frame consumers, shutdown, overload."""

from __future__ import annotations

import threading
import time
import tracemalloc

import numpy as np
import pytest

from holoview.acquire.ring import CLOSED, FrameRing, RingConsumer
from holoview.acquire.source import FrameMeta
from holoview.errors import HoloviewError, InputError

SHAPE = (8, 12)


def put(ring: FrameRing, seq: int) -> None:
    ring.put(np.full(SHAPE, seq, np.uint16), FrameMeta(seq, float(seq), float(seq)))


def drain(consumer: RingConsumer) -> list[int]:
    ids = []
    while (item := consumer.get(timeout=0)) not in (None, CLOSED):
        pixels, meta = item
        assert (pixels == meta.frame_id).all()
        ids.append(meta.frame_id)
    return ids


def test_every_consumer_reads_all_frames_in_order_within_capacity() -> None:
    ring = FrameRing(8, SHAPE, np.uint16)
    consumer = ring.consumer("recorder", "every")
    for i in range(8):
        put(ring, i)
    assert consumer.status()[:4] == (8, 8, 0, 8)
    assert drain(consumer) == list(range(8))
    status = consumer.status()
    assert (status.acquired, status.unread, status.dropped, status.read) == (8, 0, 0, 8)


def test_overflow_overwrites_oldest_and_counts_exactly() -> None:
    ring = FrameRing(4, SHAPE, np.uint16)
    consumer = ring.consumer("recorder", "every")
    for i in range(10):
        put(ring, i)
    status = consumer.status()
    assert (status.acquired, status.unread, status.dropped, status.capacity) == (10, 4, 6, 4)
    assert drain(consumer) == [6, 7, 8, 9]
    assert consumer.status().dropped == 6
    assert consumer.status().read + consumer.status().dropped == 10


def test_newest_consumer_skips_to_the_newest_and_counts_skips_not_drops() -> None:
    ring = FrameRing(4, SHAPE, np.uint16)
    every = ring.consumer("recorder", "every")
    newest = ring.consumer("processing", "newest")
    for i in range(3):
        put(ring, i)
    pixels, meta = newest.get(timeout=0)
    assert meta.frame_id == 2
    assert (pixels == 2).all()
    assert newest.get(timeout=0) is None
    put(ring, 3)
    assert newest.get(timeout=0)[1].frame_id == 3
    status = newest.status()
    assert (status.skipped, status.dropped, status.read) == (2, 0, 2)
    assert drain(every) == [0, 1, 2, 3]  # cursors are independent


def test_newest_frame_is_a_copy_and_moves_no_cursor() -> None:
    ring = FrameRing(4, SHAPE, np.uint16)
    assert ring.newest() is None
    every = ring.consumer("series", "every")
    for i in range(3):
        put(ring, i)
    seq, pixels, meta = ring.newest()
    assert (seq, meta.frame_id) == (2, 2) and (pixels == 2).all()
    pixels[:] = 99  # the ring's slot is not touched
    assert ring.newest()[1].max() == 2
    assert drain(every) == [0, 1, 2]


def test_consumer_starts_at_the_next_frame() -> None:
    ring = FrameRing(4, SHAPE, np.uint16)
    put(ring, 0)
    late = ring.consumer("late", "every")
    put(ring, 1)
    assert drain(late) == [1]
    assert late.status().acquired == 1


def test_close_is_a_sentinel_after_the_unread_frames() -> None:
    ring = FrameRing(4, SHAPE, np.uint16)
    consumer = ring.consumer("recorder", "every")
    put(ring, 0)
    ring.close()
    assert consumer.get(timeout=0)[1].frame_id == 0
    assert consumer.get(timeout=0) is CLOSED
    with pytest.raises(RuntimeError, match="closed"):
        put(ring, 1)


def test_get_waits_on_a_condition_and_wakes_on_put() -> None:
    ring = FrameRing(4, SHAPE, np.uint16)
    consumer = ring.consumer("c", "newest")
    t0 = time.monotonic()
    assert consumer.get(timeout=0.1) is None
    assert time.monotonic() - t0 >= 0.09
    timer = threading.Timer(0.05, put, (ring, 7))
    timer.start()
    item = consumer.get(timeout=10)
    timer.join()
    assert item[1].frame_id == 7


def test_get_copies_into_a_given_buffer() -> None:
    ring = FrameRing(4, SHAPE, np.uint16)
    consumer = ring.consumer("c", "every")
    put(ring, 3)
    out = np.zeros(SHAPE, np.uint16)
    pixels, _ = consumer.get(timeout=0, out=out)
    assert pixels is out
    assert (out == 3).all()


def test_transport_losses_are_counted_apart_from_overflow() -> None:
    ring = FrameRing(4, SHAPE, np.uint16)
    consumer = ring.consumer("c", "every")
    ring.add_transport_lost(3)
    put(ring, 0)
    status = consumer.status()
    assert (status.transport_lost, status.dropped, status.acquired) == (3, 0, 1)


def test_put_rejects_a_frame_of_another_shape_or_dtype() -> None:
    ring = FrameRing(4, SHAPE, np.uint16)
    with pytest.raises(ValueError, match="does not fit") as raised:
        ring.put(np.zeros((8, 13), np.uint16), FrameMeta(0, 0.0, 0.0))
    # a programming error keeps its traceback: not a user's mistake (exit 2, one line)
    assert not isinstance(raised.value, HoloviewError)
    with pytest.raises(ValueError, match="does not fit"):
        ring.put(np.zeros(SHAPE, np.uint8), FrameMeta(0, 0.0, 0.0))
    with pytest.raises(InputError, match="at least 2"):
        FrameRing(1, SHAPE, np.uint16)


def test_overload_memory_flat_drops_exact_producer_never_waits() -> None:
    """A consumer far slower than the producer: fixed memory, every frame accounted for."""
    shape = (64, 64)
    ring = FrameRing(8, shape, np.uint16)
    slow = ring.consumer("recorder", "every")
    stalled = ring.consumer("stalled", "every")  # never reads at all
    n = 3000
    read_ids: list[int] = []
    torn = []

    def consume() -> None:
        while (item := slow.get(timeout=5)) is not CLOSED:
            assert item is not None
            pixels, meta = item
            if not (pixels == meta.frame_id % 65536).all():
                torn.append(meta.frame_id)
            read_ids.append(meta.frame_id)
            time.sleep(0.001)

    reader = threading.Thread(target=consume, name="test-consumer")
    frames = [np.full(shape, i % 65536, np.uint16) for i in range(4)]
    tracemalloc.start()
    reader.start()
    baseline = tracemalloc.get_traced_memory()[0]
    for i in range(n):
        data = frames[i % 4] if i < 4 else np.full(shape, i % 65536, np.uint16)
        ring.put(data, FrameMeta(i, 0.0, 0.0))
    ring.close()
    reader.join(timeout=30)
    grown = tracemalloc.get_traced_memory()[0] - baseline
    tracemalloc.stop()
    assert not reader.is_alive()
    assert torn == []  # a frame overwritten while being copied is never handed out
    assert read_ids == sorted(read_ids)
    status = slow.status()
    assert status.read == len(read_ids)
    assert status.read + status.dropped == n
    assert status.dropped > 0
    assert stalled.status().dropped == n - ring.capacity
    # what grew is the list of ids read, not frames: far less than one frame per put
    assert grown < n * np.prod(shape) * 2 / 20
