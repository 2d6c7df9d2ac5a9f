"""Where chunks are measured: processes on this machine, or the workers of a Dask cluster.

A :class:`ChunkRunner` takes :class:`~holoview.headless.parallel.chunks.ChunkTask` objects and
hands back their :class:`~holoview.headless.parallel.chunks.ChunkResult` as they complete, in any
order (the stitching puts them in order), giving out :func:`in_flight` chunks at a time:

- :class:`ProcessRunner` (``--jobs N``): a pool of ``N`` processes forked from a
  ``forkserver`` that imported holoview once (nothing of the parent's FFTW plans, HDF5
  handles or threads is inherited, and the import, a second or two of CPU, is not
  repeated per worker), all started when the pool is made, so that they start while
  the parent prepares the run. Their BLAS runs one thread each
  (:data:`SINGLE_THREADED`): one worker per core, not a BLAS thread pool per worker
  spinning on cores the other workers need.
  The workers ignore Ctrl-C, which the terminal sends to the whole process group: the
  parent decides, and when it is interrupted or fails it sends its workers SIGTERM (with
  ``--maps`` it lets the chunks under way finish instead: a worker stopped while sending
  a chunk's maps would leave the pool waiting for the rest). A parent that dies without
  a word (SIGKILL, out of memory) cannot: each worker watches it (:func:`_follow_parent`)
  and ends within moments of it, and then the forkserver and the resource tracker, which
  wait for the last of their users, end too. (A parent-death signal would not do: the
  workers' parent is the forkserver, which lives as long as a worker does.)
- :class:`DaskRunner` (``--scheduler ADDRESS``, or ``local`` for a
  :class:`distributed.LocalCluster` of ``--jobs`` worker processes, started so that a
  stop signal stops its start: :mod:`holoview.headless.parallel.dask_cluster`): the same tasks as
  Dask futures. The workers open the input by its path (it must be on storage they
  share, with holoview installed in their environment); a worker lost mid-run has its
  chunks measured again by Dask on another (``distributed.scheduler.allowed-failures``
  times), and the result is the same, since a chunk's values depend on its frames alone.

:func:`open_runner` picks one from the options. Dask is imported only when asked for.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import multiprocessing
import os
import select
import signal
import sys
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from types import TracebackType
from typing import Any, Self

from holoview.errors import HoloviewError, InputError
from holoview.headless.parallel.chunks import ChunkResult, ChunkTask, measure_chunk
from holoview.headless.parallel.dask_cluster import (
    CONNECT_TIMEOUT_S,
    LocalDask,
    check_scheduler,
    log_quietly,
)

logger = logging.getLogger(__name__)

#: Seconds a remote cluster is given to have at least one worker.
WORKERS_TIMEOUT_S = 30.0

#: The environment of the local workers: one thread each for BLAS and OpenMP.
SINGLE_THREADED = {
    "OPENBLAS_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}

#: What the forkserver imports once for every local worker.
PRELOAD = ["holoview.headless.parallel.chunks"]

#: The warnings option the resource tracker starts with (:func:`_start_resource_tracker`).
TRACKER_QUIET = "ignore::UserWarning:multiprocessing.resource_tracker"

#: Seconds between two looks at the parent where the system cannot wait on it (no pidfd).
PARENT_POLL_S = 0.2


def in_flight(workers: int) -> int:
    """Chunks given out at once to ``workers``: one each and one waiting each.

    A chunk is given out when a result is taken, so that results (a chunk's maps can be
    tens of MB) do not pile up faster than the run uses them.
    """
    return 2 * max(1, workers)


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, dead but not yet reaped, does not)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[0] != b"Z"
    except OSError:
        pass  # no /proc: ask the kernel
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # another user's process: it runs
    return True


def _watch_parent(pid: int, pidfd: int | None) -> None:
    """Wait until process ``pid`` ends, then end this process at once."""
    if pidfd is not None:
        select.select([pidfd], [], [])  # readable once the process has ended
    else:
        while _alive(pid):
            time.sleep(PARENT_POLL_S)
    os._exit(1)  # the parent is gone: nothing to hand the results to, nothing to clean


def _follow_parent(pid: int) -> None:
    """End this worker when process ``pid`` (the run's parent) ends, however it ends.

    A thread waits on a pidfd of the parent (Linux 5.3 and later), or polls every
    :data:`PARENT_POLL_S` s where there is none.
    """
    pidfd: int | None = None
    try:
        pidfd = os.pidfd_open(pid)
    except ProcessLookupError:
        os._exit(1)  # gone already
    except (OSError, AttributeError):
        pidfd = None  # no pidfd_open here: poll
    if pidfd is None and not _alive(pid):
        os._exit(1)
    watcher = threading.Thread(
        target=_watch_parent, args=(pid, pidfd), name="holoview-parent-watch", daemon=True
    )
    watcher.start()


def _worker_start(parent: int) -> None:
    """In each local worker: leave Ctrl-C to the parent; end when the parent ends."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _follow_parent(parent)


@contextlib.contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """Within the block, ``values`` set in ``os.environ`` (where the user set none)."""
    added = {k: v for k, v in values.items() if k not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for key in added:
            os.environ.pop(key, None)


def _ready() -> int:
    """A worker's first task: started, and holoview imported (unpickling this imported it)."""
    return os.getpid()


class ChunkRunner(ABC):
    """Measures chunks somewhere; a context manager (an error or interruption aborts it).

    Attributes
    ----------
    workers : int
        Processes measuring chunks at once.
    name : str
        Where, in words (``"4 processes"``, ``"Dask at tcp://..."``).
    shares_files : bool
        The workers run on this machine and see its files (``/dev/shm`` among them): a
        chunk's maps can come back through a file rather than pickled.
    """

    workers: int = 1
    name: str = ""
    shares_files: bool = False

    @abstractmethod
    def run(self, tasks: Sequence[ChunkTask]) -> Iterator[ChunkResult]:
        """Measure ``tasks``; yield each result as it completes (the rest cancelled on close).

        Raises
        ------
        InputError
            A worker cannot read the input (the message names it).
        HoloviewError
            The workers were lost for good.
        """

    @abstractmethod
    def abort(self) -> None:
        """Stop the work now (an interruption): workers are stopped, not waited for."""

    @abstractmethod
    def close(self) -> None:
        """Release the workers once the work is done."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc is not None:
            self.abort()
        self.close()


class ProcessRunner(ChunkRunner):
    """``jobs`` worker processes on this machine (module documentation).

    Parameters
    ----------
    jobs : int
        Worker processes, at least 1.
    """

    def __init__(self, jobs: int) -> None:
        self.workers = int(jobs)
        self.name = f"{self.workers} processes"
        self.shares_files = True
        self._maps = False  # the chunks carry maps (see abort)
        _start_resource_tracker()
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(PRELOAD)
        self._executor = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=context,
            initializer=_worker_start,
            initargs=(os.getpid(),),
        )
        # every worker (and the forkserver, on first use) starts now, on a thread: the
        # forkserver's import of holoview would otherwise hold this one for a second
        self._starting = threading.Thread(
            target=self._start, name="holoview-workers-start", daemon=True
        )
        self._starting.start()

    def _start(self) -> None:
        with _environment(SINGLE_THREADED):
            for _ in range(self.workers):
                self._executor.submit(_ready)

    def run(self, tasks: Sequence[ChunkTask]) -> Iterator[ChunkResult]:
        self._starting.join()
        self._maps = any(task.maps is not None for task in tasks)
        queue = iter(tasks)
        pending: set[Future[ChunkResult]] = {
            self._executor.submit(measure_chunk, task)
            for task in itertools.islice(queue, in_flight(self.workers))
        }
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    yield future.result()
                    task = next(queue, None)
                    if task is not None:
                        pending.add(self._executor.submit(measure_chunk, task))
        except BrokenProcessPool as exc:
            raise HoloviewError(
                "a worker process ended abruptly (killed, or out of memory?): run again, "
                "with fewer --jobs"
            ) from exc
        finally:
            for future in pending:
                future.cancel()

    def abort(self) -> None:
        self._starting.join()
        if self._maps:
            # a worker stopped while it sends a chunk's maps (tens of MB through the pool's
            # pipe) would leave the pool's reader waiting forever for the rest: the chunks
            # being demodulated (a second or so) are let finish, the others cancelled
            self._executor.shutdown(wait=True, cancel_futures=True)
            return
        # Python 3.14 has terminate_workers(); before, the pool's processes are only
        # reachable through its _processes mapping.
        terminate = getattr(self._executor, "terminate_workers", None)
        if terminate is not None:
            terminate(signal.SIGTERM)
            return
        processes: dict[int, Any] = getattr(self._executor, "_processes", None) or {}
        for process in list(processes.values()):
            with contextlib.suppress(OSError, ValueError, AttributeError):
                process.terminate()
        self._executor.shutdown(wait=False, cancel_futures=True)

    def close(self) -> None:
        self._starting.join()
        self._executor.shutdown(wait=True, cancel_futures=True)


def _start_resource_tracker() -> None:
    """Start multiprocessing's resource tracker, which the pool's queues use, with its
    warnings off.

    A run refused as its pool starts (an input replaced under it) has ended, once in
    several hundred, with the tracker printing that a semaphore of the pool had leaked
    and then that unlinking it failed, as it was unlinked already: CPython's own
    bookkeeping of a pool whose workers were stopped, three lines of noise after
    holoview's one. The tracker takes the interpreter's ``-W`` options when it starts
    (a tracker already running keeps its own).
    """
    from multiprocessing import resource_tracker

    added = TRACKER_QUIET not in sys.warnoptions
    if added:
        sys.warnoptions.append(TRACKER_QUIET)
    try:
        resource_tracker.ensure_running()
    finally:
        if added:
            sys.warnoptions.remove(TRACKER_QUIET)


class DaskRunner(ChunkRunner):
    """Chunks as Dask futures on a cluster (module documentation).

    Parameters
    ----------
    scheduler : str
        The scheduler's address (``tcp://host:8786``, ``host:8786``), or ``"local"``
        for a :class:`distributed.LocalCluster` of ``jobs`` worker processes.
    jobs : int
        Worker processes of a local cluster (a remote cluster has its own).

    Raises
    ------
    InputError
        No scheduler answers at the address within
        :data:`~holoview.headless.parallel.dask_cluster.CONNECT_TIMEOUT_S` (or something else
        answers), or it has no worker within :data:`WORKERS_TIMEOUT_S`.
    KeyboardInterrupt
        A stop signal while the local cluster starts (its processes are ended first).
    """

    def __init__(self, scheduler: str, jobs: int = 1) -> None:
        import distributed

        self._cluster: LocalDask | None = None
        self._client: Any = None
        self._futures: list[Any] = []
        try:
            if scheduler == "local":
                self._cluster = LocalDask(max(1, int(jobs)))
                address = self._cluster.address
            else:
                check_scheduler(scheduler)
                address = scheduler
            try:
                self._client = distributed.Client(address, timeout=CONNECT_TIMEOUT_S)
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError(
                    f"--scheduler {scheduler}: no Dask scheduler answers there ({exc})"
                ) from None
            # the client's loop runs on a thread of Dask's: what its close leaves failing
            # is said at debug level, not as an asyncio error after the run's last line
            self._client.loop.asyncio_loop.set_exception_handler(log_quietly)
            try:
                self._client.wait_for_workers(1, timeout=WORKERS_TIMEOUT_S)
            except (OSError, TimeoutError) as exc:
                raise InputError(
                    f"--scheduler {scheduler}: the scheduler has no worker ({exc})"
                ) from None
        except BaseException:  # an error, or a stop signal while the cluster starts
            self.close()
            raise
        self.workers = max(1, len(self._client.scheduler_info().get("workers", {})))
        self.name = f"Dask at {address} ({self.workers} workers)"

    @property
    def client(self) -> Any:
        """The :class:`distributed.Client` (tests find its workers through it)."""
        return self._client

    def run(self, tasks: Sequence[ChunkTask]) -> Iterator[ChunkResult]:
        import distributed

        client = self._client  # an interruption closes the runner before this ends
        queue = iter(tasks)
        futures = client.map(
            measure_chunk, list(itertools.islice(queue, in_flight(self.workers))), pure=False
        )
        self._futures = futures  # cancelled by abort()
        try:
            # the results fetched on the client's loop: an interruption lands in this
            # thread's wait for them, never inside a call of Dask's own (whose cleanup
            # then fails, printing a traceback)
            completed = distributed.as_completed(futures, with_results=True)
            for future, result in completed:
                if future.status == "cancelled":
                    raise HoloviewError(f"the Dask cluster dropped the work ({result})")
                yield result
                task = next(queue, None)
                if task is not None:
                    futures.append(client.submit(measure_chunk, task, pure=False))
                    completed.add(futures[-1])
        except distributed.client.FutureCancelledError as exc:
            raise HoloviewError(f"the Dask cluster dropped the work ({exc})") from None
        except distributed.scheduler.KilledWorker as exc:
            raise HoloviewError(
                f"Dask workers kept dying on a chunk of frames ({exc}): out of memory?"
            ) from None
        finally:
            if client.status == "running":  # not closed by abort()
                client.cancel(futures)

    def abort(self) -> None:
        client = self._client
        if client is not None and client.status == "running":
            # first: a result being fetched when the client closes fails on Dask's loop,
            # which prints the traceback
            with contextlib.suppress(Exception):
                client.cancel(self._futures)
        self.close()

    def close(self) -> None:
        client, self._client = self._client, None
        if client is not None:
            client.close()
        cluster, self._cluster = self._cluster, None
        if cluster is not None:
            cluster.close()


def open_runner(jobs: int, scheduler: str | None = None) -> ChunkRunner:
    """The runner for ``--jobs`` and ``--scheduler`` (a Dask one when a scheduler is given).

    Parameters
    ----------
    jobs : int
        Local worker processes, as :func:`~holoview.headless.parallel.chunks.plan_jobs` settled
        them (at least 1).
    scheduler : str, optional
        A Dask scheduler's address, or ``"local"``.

    Raises
    ------
    InputError
        A scheduler that does not answer.
    """
    if scheduler is not None:
        if not scheduler.strip():
            raise InputError("--scheduler: give an address (host:port) or 'local'")
        return DaskRunner(scheduler.strip(), jobs)
    return ProcessRunner(jobs)
