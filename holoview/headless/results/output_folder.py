"""The output folder of ``holoview process``: what it may replace, when, and for whom.

Policy
------
- A folder that already holds the results of a run (any of ``trends.csv``,
  ``summary.json``, ``results.h5``, ``report.png``) is refused, one line and exit
  status 2, unless ``--overwrite`` is given; then the command says, before it starts,
  which files it will replace and whose run they are (the earlier ``summary.json``'s
  input and time). Other files in the folder are never touched.
- An output that is one of the run's inputs (the recording, an experiment or
  background file; also through a link), or that would be written directly into a
  folder read as input, is refused (:func:`holoview.paths.check_apart`), with or
  without ``--overwrite``.
- One run at a time: a run holds an advisory lock (``flock``) on ``.holoview.lock`` in
  the folder (created for it if missing) from its start to its end. A second run into
  the same folder stops at once, one line naming the folder and the other run's
  process id, exit status 2. The kernel releases the lock when its process ends, however
  it ends: a lock file left by a killed run blocks nothing. The lock file is removed
  when the run ends, and so is the folder if this run created it and leaves it empty.
- Every output is written under a hidden temporary name in the folder
  (:mod:`holoview.atomic`) and renamed only when the run is complete, one after the
  other. A run that fails (an unreadable frame, a full disk, a bug) or is stopped
  before it ends (Ctrl-C, SIGTERM, SIGHUP) removes its temporary files and leaves the
  folder as it was.
- What the folder holds is checked again, under the lock, when the files are put in
  place: results that another program wrote there meanwhile are replaced only with
  ``--overwrite``. Without it the renames are no-replace renames: if a name was taken,
  none of this run's files stays, and the command says so (exit status 3).
- A run interrupted after some frames writes the results of the frames done, marked
  as such (``summary.json``: ``input.interrupted``; ``results.h5``: the root attribute
  ``interrupted``; the report's title), exit status 130, but only into a folder that
  holds no results when it ends: partial results never replace complete ones. Into a
  folder that does, the results there are kept and the partial ones are dropped, and
  the command says so.
- With ``--overwrite``, earlier outputs this run does not write again are removed
  once its own are in place, so that the folder never mixes two runs.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import logging
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from types import TracebackType
from typing import Self

from holoview.atomic import OutputSet, TargetExistsError
from holoview.errors import InputError, os_error_text
from holoview.paths import check_apart

logger = logging.getLogger(__name__)

#: The lock file of an output folder (held by the run writing there).
LOCK_NAME = ".holoview.lock"


def _earlier_run(folder: Path, names: Sequence[str]) -> str:
    """``", from the run of TIME on INPUT"`` as the earlier summary says (or ``""``)."""
    summary = folder / "summary.json"
    if "summary.json" not in names or not summary.is_file():
        return ""
    try:
        document = json.loads(summary.read_text(encoding="utf-8"))
        when = document.get("created_utc") or "?"
        source = Path(str(document.get("input", {}).get("path", "?"))).name
    except (OSError, ValueError, AttributeError):
        return ""
    return f", from the run of {when} on {source}"


def make_folder(folder: Path, what: str = "--out") -> list[Path]:
    """Create ``folder`` and its missing parents; return those created, outermost first.

    Raises
    ------
    InputError
        A folder cannot be created (a file in the way, no permission, a read-only disk).
    """
    missing: list[Path] = []
    for parent in (folder, *folder.parents):
        if parent.is_dir():
            break
        missing.append(parent)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(
            f"{what} {folder}: cannot create the folder ({os_error_text(exc)})"
        ) from exc
    return missing[::-1]


def remove_if_empty(created: Iterable[Path]) -> None:
    """Remove the folders in ``created`` (outermost first) that are empty, innermost first."""
    for folder in reversed(list(created)):
        try:
            folder.rmdir()
        except OSError:  # not empty (another program wrote there), or gone: keep it
            return


class FolderLock:
    """An advisory lock on ``FOLDER/.holoview.lock`` for one run (module policy).

    Parameters
    ----------
    folder : Path
        An existing folder.
    what : str
        The option that named it, for messages.
    """

    def __init__(self, folder: Path, what: str = "--out") -> None:
        self.folder = folder
        self.path = folder / LOCK_NAME
        self.what = what
        self._fd: int | None = None

    def _holder(self, fd: int) -> str:
        try:
            text = os.pread(fd, 32, 0).decode("ascii", errors="replace").strip()
        except OSError:
            text = ""
        return f"pid {text}" if text.isdigit() else "its process id not yet written"

    def acquire(self) -> None:
        """Take the lock, or raise.

        Raises
        ------
        InputError
            Another process holds it (the message names its pid), or the lock file
            cannot be created.
        """
        for _ in range(5):  # a lock file or a new folder removed meanwhile: try again
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            except FileNotFoundError:  # a run refused here removed the folder it found new
                with contextlib.suppress(OSError):
                    self.folder.mkdir(parents=True, exist_ok=True)
                continue
            except OSError as exc:
                raise InputError(
                    f"{self.what} {self.folder}: cannot write there ({os_error_text(exc)})"
                ) from exc
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = self._holder(fd)
                os.close(fd)
                raise InputError(
                    f"{self.what} {self.folder} is in use by another holoview run ({holder}); "
                    "wait for it to end, or choose another folder"
                ) from None
            except OSError as exc:  # a file system without locks (some network drives)
                logger.warning(
                    "%s: cannot lock the folder (%s); another run could write there at the "
                    "same time (the final renames still replace nothing unasked)",
                    self.folder,
                    os_error_text(exc),
                )
            # a run that ended meanwhile removed the file this one locked: lock the new one
            try:
                current = os.stat(self.path, follow_symlinks=False)
            except FileNotFoundError:
                os.close(fd)
                continue
            mine = os.fstat(fd)
            if (current.st_dev, current.st_ino) != (mine.st_dev, mine.st_ino):
                os.close(fd)
                continue
            break
        else:
            raise InputError(f"{self.what} {self.folder}: its lock file keeps disappearing")
        self._fd = fd
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
        except OSError as exc:  # a full disk: the lock holds all the same
            logger.debug("cannot write the pid into %s: %s", self.path, exc)

    def release(self) -> None:
        """Remove the lock file and let the lock go (again: nothing)."""
        if self._fd is None:
            return
        with contextlib.suppress(OSError):
            self.path.unlink()
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> Self:
        self.acquire()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.release()


class OutputFolder(OutputSet):
    """The output folder of one run, its policy checked at construction (module docs).

    Entering it as a context manager creates the folder if missing, takes its lock
    and checks it again; leaving it removes the temporary files, lets the lock go,
    and removes the folder if this run created it and left it empty.

    Parameters
    ----------
    folder : Path
        The folder.
    names : sequence of str
        The file names a run writes there.
    overwrite : bool
        Replace the results of an earlier run.
    inputs : iterable of Path
        The files and folders the run reads (no output may be one of them).

    Raises
    ------
    InputError
        The folder is a file, an output is an input, or the folder holds an earlier
        run's results and ``overwrite`` is False.

    Attributes
    ----------
    earlier : list of str
        The outputs already in the folder (replaced when this run completes).
    """

    def __init__(
        self,
        folder: Path,
        names: Sequence[str],
        *,
        overwrite: bool,
        inputs: Iterable[Path] = (),
    ) -> None:
        super().__init__(folder)
        self.names = tuple(names)
        self.overwrite = overwrite
        if folder.exists() and not folder.is_dir():
            raise InputError(f"--out {folder} is a file, not a folder")
        check_apart([folder / name for name in self.names], inputs)
        self._lock = FolderLock(folder)
        self._created: list[Path] = []
        self.earlier = self._check(say=True)

    def _check(self, *, say: bool) -> list[str]:
        """The outputs in the folder now; InputError for any without ``overwrite``."""
        earlier = [name for name in self.names if (self.folder / name).exists()]
        if earlier:
            what = f"{', '.join(earlier)}{_earlier_run(self.folder, earlier)}"
            if not self.overwrite:
                raise InputError(
                    f"--out {self.folder} holds the results of an earlier run ({what}); give "
                    "--overwrite to replace them when this run completes, or another folder"
                )
            if say:
                logger.warning("%s: replacing %s when this run completes", self.folder, what)
        return earlier

    def __enter__(self) -> Self:
        self._created = make_folder(self.folder)
        try:
            self._lock.acquire()
            self.earlier = self._check(say=False)
        except BaseException:
            remove_if_empty(self._created)
            raise
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        try:
            self.discard()
        finally:
            self._lock.release()
            remove_if_empty(self._created)

    def finish(self, *, interrupted: bool) -> list[Path]:
        """Put the run's files in place; return them (empty: the results there kept).

        Parameters
        ----------
        interrupted : bool
            The run was stopped early: its partial results replace no results (also
            none written there meanwhile).

        Raises
        ------
        TargetExistsError
            Without ``overwrite``: results appeared in the folder during the run
            (this run's files are removed).
        OutputError
            A file could not be flushed or renamed (nothing more is replaced).
        """
        present = [name for name in self.names if (self.folder / name).exists()]
        if interrupted and present:
            logger.info("interrupted: the results in %s are kept", self.folder)
            self.discard()
            return []
        appeared = [name for name in present if name not in self.earlier]
        if appeared and not self.overwrite:  # also names this run does not write: no mix
            self.discard()
            raise TargetExistsError(
                f"{', '.join(appeared)} appeared while this run was writing into "
                f"{self.folder} (another program wrote it); not replaced, and this run's "
                "files are removed",
                self.folder / appeared[0],
                None,
            )
        written = self.commit(replace=self.overwrite)
        if self.overwrite:
            for name in set(self.earlier) | set(present):
                stale = self.folder / name
                if stale not in written:
                    stale.unlink(missing_ok=True)
        return written
