"""Files written whole or not at all: a temporary name beside the target, renamed when complete.

Every results writer of holoview (``process``'s ``results.h5``, ``trends.csv``,
``summary.json`` and ``report.png``, ``simulate``'s recording and figure, the GUI's
exports) writes to a hidden file in the target's folder named
``.STEM.XXXXXXXX.partial.SUFFIX`` (the suffix is kept: some writers choose the format
by it), then flushes it to the disk (``fsync``), renames it over the target
(``os.replace``: atomic within a file system) and flushes the folder. A failure or an
interruption before the rename removes the temporary file, so a target is either the
complete new file or what was there before, never half a file. Only a process killed
outright (SIGKILL, a power cut) can leave a temporary file behind, and its name says
what it is.

:func:`atomic_path` does this for one file; :class:`OutputSet` for the files of one
run, renamed one after the other once every one of them is complete;
:func:`atomic_folder` for an output that is a folder (``export``'s Zarr stores and
TIFF stacks).

Recordings are not written this way: they stay at their own path, readable while
they are written (:mod:`holoview.acquire.recording`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import secrets
import shutil
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import Self

from holoview.errors import OutputError, os_error_text

logger = logging.getLogger(__name__)

#: The marker in the name of every temporary file.
PARTIAL_MARK = ".partial"


def temporary_path(target: str | os.PathLike[str]) -> Path:
    """Return an unused hidden name beside ``target`` with the same suffix.

    Examples
    --------
    >>> temporary_path("out/report.png").name.endswith(".partial.png")
    True
    """
    path = Path(target)
    return path.with_name(f".{path.stem}.{secrets.token_hex(4)}{PARTIAL_MARK}{path.suffix}")


def _sync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _sync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable (a no-op where folders cannot be opened)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError as exc:  # some file systems refuse fsync on a folder; the rename stands
        logger.debug("fsync of folder %s: %s", folder, exc)
    finally:
        os.close(fd)


def commit(temporary: Path, target: Path) -> None:
    """Flush ``temporary`` to the disk and rename it to ``target`` (replacing it).

    Raises
    ------
    OutputError
        The flush or the rename failed (the temporary file is removed).
    """
    try:
        _sync_file(temporary)
        os.replace(temporary, target)
    except OSError as exc:
        temporary.unlink(missing_ok=True)
        raise OutputError(f"cannot write {target}: {os_error_text(exc)}") from exc
    _sync_folder(target.parent)


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path to write ``target`` to; rename it over ``target`` on success.

    If the block raises (or is interrupted), the temporary file is removed and
    ``target`` stays as it was.

    Raises
    ------
    OutputError
        The file could not be flushed or renamed.

    Examples
    --------
    >>> import tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> with atomic_path(folder / "notes.txt") as path:
    ...     _ = path.write_text("done")
    >>> sorted(p.name for p in folder.iterdir())  # the temporary is gone
    ['notes.txt']
    """
    final = Path(target)
    temporary = temporary_path(final)
    try:
        yield temporary
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    if not temporary.exists():
        raise OutputError(f"cannot write {final}: the writer made no file")
    commit(temporary, final)


class OutputSet:
    """The files of one run, written under temporary names and renamed when all are complete.

    Use as a context manager: leaving it by an exception, or without :meth:`commit`,
    removes every temporary file, and the folder keeps what it held before.

    Parameters
    ----------
    folder : Path
        Where the files go (it must exist).
    """

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)
        self._temporary: dict[str, Path] = {}

    def path(self, name: str) -> Path:
        """Return the temporary path to write the output ``name`` (a file name) to."""
        if name not in self._temporary:
            self._temporary[name] = temporary_path(self.folder / name)
        return self._temporary[name]

    def commit(self) -> list[Path]:
        """Flush every file written and rename each to its name; return the final paths.

        An output whose temporary file was never created is skipped.

        Raises
        ------
        OutputError
            A flush or rename failed; files not yet renamed are removed.
        """
        written = {name: p for name, p in self._temporary.items() if p.exists()}
        try:
            for temporary in written.values():
                _sync_file(temporary)
            for name, temporary in written.items():
                os.replace(temporary, self.folder / name)
        except OSError as exc:
            self.discard()
            raise OutputError(f"cannot write into {self.folder}: {os_error_text(exc)}") from exc
        self._temporary.clear()
        _sync_folder(self.folder)
        return [self.folder / name for name in written]

    def discard(self) -> None:
        """Remove every temporary file (the outputs keep what they held before)."""
        for temporary in self._temporary.values():
            temporary.unlink(missing_ok=True)
        self._temporary.clear()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.discard()


@contextlib.contextmanager
def atomic_folder(target: str | os.PathLike[str], *, replace: bool = False) -> Iterator[Path]:
    """Yield a temporary folder to fill; rename it to ``target`` when the block completes.

    For outputs that are folders (a Zarr store, a set of TIFF stacks). If the block
    raises (or is interrupted), the temporary folder is removed and ``target`` stays as
    it was. With ``replace``, an existing ``target`` is moved aside, the new folder
    renamed in, and the old one removed: between the two renames ``target`` is briefly
    absent (folders cannot be swapped in one step), never half-written.

    Raises
    ------
    OutputError
        ``target`` exists and ``replace`` is False, or a rename failed.
    """
    final = Path(target)
    if final.exists() and not replace:
        raise OutputError(f"cannot write {final}: it exists")
    temporary = temporary_path(final)
    try:
        temporary.mkdir()
    except OSError as exc:
        raise OutputError(f"cannot write {final}: {os_error_text(exc)}") from exc
    try:
        yield temporary
    except BaseException:
        shutil.rmtree(temporary, ignore_errors=True)
        raise
    old = temporary_path(final) if final.exists() else None
    try:
        for path in sorted(temporary.rglob("*")):
            if path.is_file():
                _sync_file(path)
        _sync_folder(temporary)
        if old is not None:
            os.replace(final, old)
        os.replace(temporary, final)
    except OSError as exc:
        if old is not None and old.exists() and not final.exists():
            os.replace(old, final)
        shutil.rmtree(temporary, ignore_errors=True)
        raise OutputError(f"cannot write {final}: {os_error_text(exc)}") from exc
    _sync_folder(final.parent)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
