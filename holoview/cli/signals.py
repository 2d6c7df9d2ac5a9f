"""Stop signals and standard output for the commands: stopped cleanly, never cut short.

``holoview record`` and ``holoview process`` keep what they have done when Ctrl-C
stops them (a ``KeyboardInterrupt``). A service manager stops a program with
SIGTERM, and a closed terminal or SSH session sends SIGHUP: inside
:func:`stop_on_signals` both raise the same interrupt (:class:`Stopped`, which
names the signal). While a command closes its files, :func:`deferred_signals`
notes further stop signals instead of raising them, so that a second Ctrl-C
cannot leave a half-written file. A signal ignored when the command started
(``nohup`` ignores SIGHUP) stays ignored.

Python runs a signal handler between two bytecodes of whatever runs then, and an
exception raised in a finaliser (``__del__``, a weakref callback: the garbage
collector calls them) is printed as "Exception ignored" and dropped: the command
would go on as if never stopped (seen: SIGTERM during ``process --maps``, inside
``WeakValueDictionary``'s callback). numpy's C code calls Python helpers of its own
and turns what they raise into its own errors (seen: SIGTERM during a ``--scheduler``
run, in ``_promote_fields`` under ``np.unique``, became "TypeError: Cannot compare
structured arrays", exit 1). A stop signal that lands in a finaliser or in numpy's
Python code is sent again :data:`RETRY_S` later (from a timer thread: SIGALRM is left
to others, pytest-timeout among them), to whatever handler is then in place.

:func:`emit` prints a command's result; a closed standard output, a closed pipe or a
full disk behind it becomes an :class:`~holoview.errors.OutputError` (one line, exit
status 3) instead of a traceback.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from types import FrameType

from holoview.errors import OutputError, os_error_text

#: The signals that stop a command as Ctrl-C does.
STOP_SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

#: Seconds after which a stop signal that landed in a finaliser is sent again.
RETRY_S = 0.01

_CALLBACK_FILES = frozenset({"weakref.py", "_weakrefset.py"})  # where weakref callbacks run


class Stopped(KeyboardInterrupt):
    """A stop signal (SIGTERM, SIGHUP) turned into the interrupt Ctrl-C raises."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signal_name = signal.Signals(signum).name


def _swallowed_in(frame: FrameType | None) -> bool:
    """Whether an exception raised in ``frame`` could be dropped or replaced.

    ``frame`` runs a finaliser, or numpy's own Python code (which numpy's C code may
    have called).
    """
    if frame is None:
        return False
    code = frame.f_code
    if code.co_name == "__del__" or Path(code.co_filename).name in _CALLBACK_FILES:
        return True
    numpy = sys.modules.get("numpy")  # not imported: not running
    where = getattr(numpy, "__file__", None)
    return where is not None and code.co_filename.startswith(str(Path(where).parent) + os.sep)


def _raise_stopped(signum: int, frame: FrameType | None) -> None:
    if _swallowed_in(frame):
        again = threading.Timer(RETRY_S, os.kill, (os.getpid(), signum))
        again.daemon = True
        again.start()
        return
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Stopped(signum)


def _handled() -> list[signal.Signals]:
    """The stop signals this process may handle (those not ignored at start)."""
    if threading.current_thread() is not threading.main_thread():
        return []
    return [sig for sig in STOP_SIGNALS if signal.getsignal(sig) is not signal.SIG_IGN]


@contextlib.contextmanager
def stop_on_signals() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`Stopped` as Ctrl-C would.

    Ctrl-C raises ``KeyboardInterrupt`` as always; any of the three landing in a
    finaliser is raised a moment later (see the module's notes).
    """
    previous = {sig: signal.signal(sig, _raise_stopped) for sig in _handled()}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def deferred_signals(notice: str | None = None) -> Iterator[list[int]]:
    """Within the block, stop signals are counted in the yielded list instead of raised.

    Parameters
    ----------
    notice : str, optional
        Printed on stderr at the first signal (what is being finished).
    """
    received: list[int] = []

    def note(signum: int, frame: FrameType | None) -> None:
        received.append(signum)
        if notice and len(received) == 1:
            print(notice, file=sys.stderr, flush=True)

    previous = {sig: signal.signal(sig, note) for sig in _handled()}
    try:
        yield received
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _silence_stdout() -> None:
    """Point file descriptor 1 at /dev/null, so Python's final flush cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):  # io.UnsupportedOperation included
        pass  # not a real file (a test's capture): nothing to silence


def emit(text: str) -> None:
    """Print ``text`` on standard output now.

    Raises
    ------
    OutputError
        Standard output is closed (the command was started with it closed, ``>&-``),
        a closed pipe or a full disk.
    """
    if sys.stdout is None:  # Python's stdout when descriptor 1 was closed at start
        raise OutputError("cannot write to standard output: it is closed")
    try:
        print(text, flush=True)
    except OSError as exc:
        _silence_stdout()
        raise OutputError(f"cannot write to standard output: {os_error_text(exc)}") from exc
