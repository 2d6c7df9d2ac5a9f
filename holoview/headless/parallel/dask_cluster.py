"""Reaching a Dask cluster: a scheduler's address checked, or a local cluster started.

Two ways Dask itself leaves a user waiting, or with a traceback, are closed here:

- :func:`check_scheduler`: whatever listens at ``--scheduler ADDRESS`` is asked for
  Dask's handshake within :data:`CONNECT_TIMEOUT_S`, under a deadline of this
  module's own. Dask's client waits forever on a server that answers in another
  protocol (an HTTP server's reply read as the length of a message of exabytes), and
  raises a ``TypeError`` for a ``tls://`` address without TLS settings; both are one
  :class:`~holoview.errors.InputError` here.
- :class:`LocalDask`: a :class:`distributed.LocalCluster` started on an event loop of
  its own, so that a stop signal during its start (several seconds for a few worker
  processes) stops it at once: the start is cancelled and every worker process it
  spawned is ended, where Dask's own constructor would go on starting them behind the
  interruption and fail an assertion at exit.

Dask is imported only inside these functions.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import multiprocessing
import threading
from typing import Any

from holoview.errors import InputError

logger = logging.getLogger(__name__)

#: Seconds to wait for a scheduler to answer before giving up.
CONNECT_TIMEOUT_S = 5.0

#: Seconds a local cluster is given to close its workers before they are killed.
CLOSE_TIMEOUT_S = 5.0


async def _handshake(address: str) -> None:
    """Connect to ``address`` as Dask's client does (its TLS settings included), and close."""
    from distributed.comm import connect
    from distributed.security import Security

    args = Security().get_connection_args("client")
    comm = await asyncio.wait_for(
        connect(address, timeout=CONNECT_TIMEOUT_S, **args), CONNECT_TIMEOUT_S
    )
    await comm.close()


def check_scheduler(address: str) -> None:
    """Raise unless a Dask server answers at ``address`` within :data:`CONNECT_TIMEOUT_S`.

    Raises
    ------
    InputError
        Nothing answers, something else answers (an HTTP server), the address is not
        one Dask knows, or a ``tls://`` address has no TLS settings (one line naming the
        address).
    """
    where = f"--scheduler {address}"
    try:
        asyncio.run(_handshake(address))
    except (TimeoutError, OSError) as exc:
        detail = str(exc) or f"no answer within {CONNECT_TIMEOUT_S:g} s"
        raise InputError(f"{where}: no Dask scheduler answers there ({detail})") from None
    except TypeError as exc:
        if address.startswith("tls://"):
            raise InputError(
                f"{where}: a tls:// address needs Dask's TLS settings (distributed.comm.tls "
                "in the Dask configuration: the CA file, the client's certificate and key)"
            ) from None
        raise InputError(f"{where}: not a Dask scheduler's address ({exc})") from None
    except ValueError as exc:
        raise InputError(f"{where}: not a Dask scheduler's address ({exc})") from None
    except Exception as exc:  # another protocol answered: Dask fails on its reply in any way
        raise InputError(
            f"{where}: what answers there is not a Dask scheduler ({type(exc).__name__})"
        ) from None


def log_quietly(loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
    """Log at debug level what fails on one of Dask's loops once nobody waits for it.

    A start interrupted leaves Dask's tasks failing ("Nanny failed to start") after the
    interruption has been reported; a client closed mid-run leaves its batched sender's
    wait failing with a timeout on a stopped loop, reported by asyncio ("Future
    exception was never retrieved") when the future is collected, at exit, after the
    run's last line.
    """
    logger.debug("on a Dask event loop: %s", context.get("message"))


class LocalDask:
    """A :class:`distributed.LocalCluster` of ``workers`` processes, on a loop of its own.

    Parameters
    ----------
    workers : int
        Worker processes (one thread each).

    Attributes
    ----------
    address : str
        The scheduler's address.

    Raises
    ------
    KeyboardInterrupt
        A stop signal during the start: the cluster is closed and its processes ended
        before it is raised again.
    """

    def __init__(self, workers: int) -> None:
        self.address = ""
        self._cluster: Any = None
        self._before = set(multiprocessing.active_children())
        self._loop = asyncio.new_event_loop()
        self._loop.set_exception_handler(log_quietly)
        self._thread = threading.Thread(
            target=self._loop.run_forever, name="holoview-dask-cluster", daemon=True
        )
        self._thread.start()
        start = asyncio.run_coroutine_threadsafe(self._start(workers), self._loop)
        try:
            start.result()
        except BaseException:
            start.cancel()
            self._end_processes()  # a cluster stopped while it starts does not close them
            self.close()
            raise

    async def _start(self, workers: int) -> None:
        import distributed

        self._cluster = distributed.LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            # the workers' own logs: an interrupted run's shutdown has them complain of
            # the scheduler gone before them; what fails in a chunk comes back anyway
            silence_logs=logging.INFO if logger.isEnabledFor(logging.DEBUG) else logging.CRITICAL,
            # its HTTP server (health, metrics) on a free port, not on 8787
            scheduler_kwargs={"dashboard_address": ":0"},
            asynchronous=True,
        )
        # closed by close(), on its loop: Dask's own close at exit would wait 10 s for
        # this loop, stopped by then, after a start interrupted
        self._cluster.shutdown_on_close = False
        await self._cluster
        self.address = str(self._cluster.scheduler_address)

    async def _close(self) -> None:
        try:
            await self._cluster.close(timeout=CLOSE_TIMEOUT_S)
        except Exception as exc:  # a cluster stopped while it started fails Dask's checks
            logger.debug("closing the local Dask cluster: %r", exc)

    def _end_processes(self) -> None:
        """Kill the worker processes this cluster started that still run."""
        left = set(multiprocessing.active_children()) - self._before
        for process in left:
            process.kill()
        for process in left:
            process.join(CLOSE_TIMEOUT_S)

    def close(self) -> None:
        """Close the cluster; end every worker process it started that is still running."""
        if not self._thread.is_alive():
            return
        try:
            if self._cluster is not None:
                closing = asyncio.run_coroutine_threadsafe(self._close(), self._loop)
                with contextlib.suppress(TimeoutError):
                    closing.result(2 * CLOSE_TIMEOUT_S)
        finally:
            self._end_processes()
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(CLOSE_TIMEOUT_S)
