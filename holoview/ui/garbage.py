"""Python's cyclic garbage collected on the GUI thread, between events.

Qt objects that Python holds in reference cycles (pyqtgraph's plots and items hold
many) are deleted when the cycle is collected, and Python collects whenever enough
objects have been allocated: on whichever thread allocates (a camera, replay or
demodulation thread), and in the middle of whatever that thread is doing, a paint
event of the GUI thread included. A Qt object deleted there frees what a paint in
progress may still use: the test suite crashed so (a paint engine freed under
``QPainter::drawImage`` while an image item painted; 4 runs of 10 of three GUI test
files on 2 workers, none in 22 once collection was moved between events).

:func:`collect_between_events` turns automatic collection off and collects from a
timer of the GUI thread instead, by Python's own rule: a generation when its count
passes its threshold (:func:`gc.get_threshold`), the oldest due first.
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator

from PyQt6.QtCore import QObject, QTimer

#: How often (ms) the GUI thread looks whether a generation is due.
CHECK_MS = 100


def collect_due() -> int | None:
    """Collect the oldest generation whose count has passed its threshold.

    Returns
    -------
    int or None
        The generation collected, or None when none was due.
    """
    counts, thresholds = gc.get_count(), gc.get_threshold()
    for generation in (2, 1, 0):
        if thresholds[generation] and counts[generation] > thresholds[generation]:
            gc.collect(generation)
            return generation
    return None


@contextlib.contextmanager
def collect_between_events(parent: QObject) -> Iterator[QTimer]:
    """Within the block, cyclic garbage is collected only on the GUI thread's timer.

    Parameters
    ----------
    parent : QObject
        Owner of the timer (the application or a window), living on the GUI thread.

    Yields
    ------
    QTimer
        The running timer (named ``holoview-garbage``).

    Automatic collection is turned back on as it was when the block ends, after a
    last full collection.
    """
    was_enabled = gc.isenabled()
    timer = QTimer(parent)
    timer.setObjectName("holoview-garbage")
    timer.timeout.connect(collect_due)
    gc.disable()
    timer.start(CHECK_MS)
    try:
        yield timer
    finally:
        timer.stop()
        timer.deleteLater()
        gc.collect()
        if was_enabled:
            gc.enable()
