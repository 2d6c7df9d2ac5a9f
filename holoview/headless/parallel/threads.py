"""The parent's own work on the cores a run was given: tasks in threads, results in order.

The parent of a run works alone before its workers start and after they end (the
matched windows' many frames, the frames spread over the run for the displacements):
cores the user gave (``--jobs``, ``--threads``) that would stand idle. The tasks handed
out here are those whose order does not matter (a frame read and transformed, a group of
frames demodulated); what depends on order takes their results in order, so that the
numbers are those of one thread to the bit. Each thread has its own FFTW plans
(:mod:`holoview.processing.fourier.fftplans`), made from the process's wisdom, and
pyFFTW and numpy's large array operations release the GIL.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable, Generator, Iterable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TypeVar

from holoview.processing.fourier.fftplans import usable_cpus

__all__ = ["AHEAD_PER_THREAD", "in_order", "parent_threads"]

T = TypeVar("T")
R = TypeVar("R")

#: Tasks started ahead of the one whose result is taken, per thread: enough to keep the
#: threads busy while the results are taken, few enough to bound what is held (a
#: 1024 x 1024 frame's half spectrum is 4 MB).
AHEAD_PER_THREAD = 2


def parent_threads(jobs: int | None, threads: int = 1, cores: int | None = None) -> int:
    """The threads a run's parent uses for its own work: the cores the user gave it.

    Parameters
    ----------
    jobs : int or None
        ``--jobs`` (None: every usable core).
    threads : int
        ``--threads`` (FFTW threads per frame).
    cores : int, optional
        Usable cores (default: :func:`~holoview.processing.fourier.fftplans.usable_cpus`).

    Examples
    --------
    >>> parent_threads(1), parent_threads(2, cores=2), parent_threads(8, cores=2)
    (1, 2, 2)
    >>> parent_threads(None, cores=4), parent_threads(1, threads=3, cores=4)
    (4, 3)
    """
    cores = usable_cpus() if cores is None else cores
    given = cores if jobs is None else max(int(jobs), 1)
    return max(1, min(max(given, int(threads)), cores))


def in_order(
    task: Callable[[T], R],
    items: Iterable[T],
    threads: int,
    *,
    stop: threading.Event | None = None,
) -> Generator[R, None, None]:
    """``task(item)`` for each item, ``threads`` at a time, the results in the items' order.

    At most :data:`AHEAD_PER_THREAD` tasks a thread run ahead of the result taken. One
    thread: each task in turn, in the caller's thread. A task's exception is raised when
    its result is taken. When the iterator ends early (closed, a task failed, or
    interrupted: a KeyboardInterrupt while it waits), the tasks not started are
    cancelled, ``stop`` is set (for long tasks to check) and those running are waited for.
    """
    if threads <= 1:
        yield from map(task, items)
        return
    ahead = AHEAD_PER_THREAD * threads
    pending: deque[Future[R]] = deque()
    with ThreadPoolExecutor(threads, thread_name_prefix="holoview-parent") as pool:
        try:
            for item in items:
                pending.append(pool.submit(task, item))
                if len(pending) > ahead:
                    yield pending[0].result()
                    pending.popleft()
            while pending:
                yield pending[0].result()
                pending.popleft()
        finally:
            if pending:  # ended early
                for future in pending:
                    future.cancel()
                if stop is not None:
                    stop.set()
