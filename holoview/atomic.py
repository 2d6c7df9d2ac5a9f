"""Files written whole or not at all: a temporary name beside the target, renamed when complete.

Every results writer of holoview (``process``'s ``results.h5``, ``trends.csv``,
``summary.json`` and ``report.png``, a batch's ``index.csv``, ``simulate``'s recording
and figure, the GUI's exports) writes to a hidden file in the target's folder named
``.STEM.XXXXXXXX.partial.SUFFIX`` (the suffix is kept: some writers choose the format
by it), then flushes it to the disk (``fsync``), renames it to the target and flushes
the folder. A failure or an interruption before the rename removes the temporary
file, so a target is either the complete new file or what was there before, never
half a file. Only a process killed outright (SIGKILL, a power cut) can leave a
temporary file behind, and its name says what it is.

Two kinds of rename:

- replacing (``os.replace``: atomic within a file system), for outputs the user asked
  to replace (``process --overwrite``, the GUI's exports);
- no-replace (:func:`rename_no_replace`), for writers that promise never to overwrite
  (``simulate``, ``process`` without ``--overwrite``, a new ``index.csv``): the check
  that the target is free and the rename are one step, so a file another program
  created at that name while this one was written is never replaced. Where that
  happens the writer raises :class:`TargetExistsError` (an
  :class:`~holoview.errors.OutputError`: exit status 3), which says whether the
  complete temporary file was kept or removed.

Names fit the file system: a temporary or hidden companion name (:func:`hidden_sibling`)
is shortened, keeping it unique, to the folder's longest file name (``NAME_MAX``, 255
bytes on Linux file systems), so any valid target name can be written.

:func:`atomic_path` does this for one file; :class:`OutputSet` for the files of one
run, renamed one after the other once every one of them is complete;
:func:`atomic_folder` for an output that is a folder (``export``'s Zarr stores and
TIFF stacks).

Recordings are not written this way: they stay at their own path, readable while
they are written (:mod:`holoview.acquire.recording`), created exclusively (an existing
file is never opened for writing).
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import hashlib
import logging
import os
import secrets
import shutil
import sys
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import Any, Self

from holoview.errors import OutputError, os_error_text

logger = logging.getLogger(__name__)

#: The marker in the name of every temporary file.
PARTIAL_MARK = ".partial"

#: The longest file name, bytes, where the file system does not say (Linux's NAME_MAX).
NAME_MAX = 255

#: Longest suffix, bytes, a temporary name keeps (longer ones choose no writer's format).
MAX_SUFFIX_BYTES = 32

#: Characters of a hash added to a name that had to be shortened (keeps it unique).
HASH_CHARS = 8


class TargetExistsError(OutputError):
    """A no-replace rename found its target taken: the file was not put in place.

    Attributes
    ----------
    target : Path
        The name that was taken.
    kept : Path or None
        The complete file under its temporary name, when it was kept.
    """

    def __init__(self, message: str, target: Path, kept: Path | None) -> None:
        super().__init__(message)
        self.target = target
        self.kept = kept


def name_max(folder: str | os.PathLike[str]) -> int:
    """The longest file name, bytes, the file system of ``folder`` takes (255 when unknown)."""
    try:
        limit = os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):
        return NAME_MAX
    return limit if limit > 0 else NAME_MAX


def _bytes(text: str) -> int:
    return len(os.fsencode(text))


def cut_to_bytes(text: str, limit: int) -> str:
    """``text`` cut at a character boundary to at most ``limit`` bytes of the file system encoding.

    Examples
    --------
    >>> cut_to_bytes("héllo", 2)
    'h'
    """
    if _bytes(text) <= limit:
        return text
    kept: list[str] = []
    size = 0
    for char in text:
        size += _bytes(char)
        if size > limit:
            break
        kept.append(char)
    return "".join(kept)


def fit_name(name: str, limit: int) -> str:
    """``name`` if it has at most ``limit`` bytes; else cut, with a hash of the whole added.

    Two names that differ anywhere stay apart once shortened (the hash is of the whole
    name), and a name that fits is returned unchanged.

    Examples
    --------
    >>> fit_name("run", 10)
    'run'
    >>> len(fit_name("x" * 300, 255).encode())
    255
    """
    if _bytes(name) <= limit:
        return name
    digest = hashlib.sha256(os.fsencode(name)).hexdigest()[:HASH_CHARS]
    return f"{cut_to_bytes(name, limit - HASH_CHARS - 1)}~{digest}"


def hidden_sibling(target: str | os.PathLike[str], tail: str) -> Path:
    """``.NAME`` + ``tail`` beside ``target``, NAME shortened so that it fits the file system.

    Examples
    --------
    >>> hidden_sibling("out/run.h5", ".reserve").name
    '.run.h5.reserve'
    """
    path = Path(target)
    room = name_max(path.parent) - 1 - _bytes(tail)
    return path.with_name(f".{fit_name(path.name, room)}{tail}")


def temporary_path(target: str | os.PathLike[str]) -> Path:
    """Return an unused hidden name beside ``target`` with the same suffix.

    The name fits the folder's file system for any valid ``target`` (the stem part is
    shortened where needed; a random part keeps it unique). A suffix longer than
    :data:`MAX_SUFFIX_BYTES` is treated as part of the stem.

    Examples
    --------
    >>> temporary_path("out/report.png").name.endswith(".partial.png")
    True
    """
    path = Path(target)
    suffix = path.suffix if _bytes(path.suffix) <= MAX_SUFFIX_BYTES else ""
    stem = path.name[: len(path.name) - len(suffix)]
    return hidden_sibling(
        path.with_name(stem or "_"), f".{secrets.token_hex(4)}{PARTIAL_MARK}{suffix}"
    )


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


#: ``renameat2`` arguments: the current folder as the base of relative paths, and the flag.
_AT_FDCWD = -100
_RENAME_NOREPLACE = 1
#: Errors that mean "this kernel or file system has no such rename": try another way.
_UNSUPPORTED = {errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EPERM}


def _load_renameat2() -> Any:
    if not sys.platform.startswith("linux"):
        return None
    try:
        function = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):  # a C library before glibc 2.28
        return None
    function.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p]
    function.argtypes += [ctypes.c_uint]
    function.restype = ctypes.c_int
    return function


_renameat2 = _load_renameat2()


def _renamed_no_replace(source: Path, target: Path) -> bool:
    """``renameat2(RENAME_NOREPLACE)``: True when renamed, False where not supported."""
    if _renameat2 is None:
        return False
    status = _renameat2(
        _AT_FDCWD, os.fsencode(source), _AT_FDCWD, os.fsencode(target), _RENAME_NOREPLACE
    )
    if status == 0:
        return True
    code = ctypes.get_errno()
    if code in _UNSUPPORTED:
        return False
    raise OSError(code, os.strerror(code), str(source), None, str(target))


def rename_no_replace(source: str | os.PathLike[str], target: str | os.PathLike[str]) -> None:
    """Rename ``source`` to ``target`` unless ``target`` exists, in one step.

    ``renameat2`` with ``RENAME_NOREPLACE`` where the kernel and the file system have
    it (Linux 3.15: ext4, XFS, Btrfs, tmpfs), else a hard link to ``target`` (which
    fails if it exists) and the removal of ``source``; only where neither is possible
    (a file system without hard links) a check and a rename, which leave a moment in
    which a file created by another program could be replaced.

    Raises
    ------
    FileExistsError
        ``target`` exists (even a broken symbolic link); ``source`` is untouched.
    OSError
        The rename failed otherwise.
    """
    source, target = Path(source), Path(target)
    if _renamed_no_replace(source, target):
        return
    try:
        os.link(source, target, follow_symlinks=False)
    except FileExistsError:
        raise
    except OSError as exc:
        if exc.errno not in _UNSUPPORTED | {errno.EMLINK}:
            raise
        logger.debug("no hard links in %s (%s): check, then rename", target.parent, exc)
        if os.path.lexists(target):
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(target)) from exc
        os.rename(source, target)
        return
    os.unlink(source)


def _taken(target: Path, temporary: Path, keep: bool) -> TargetExistsError:
    """The error of a no-replace rename that found ``target`` taken (``temporary`` kept or not)."""
    if keep:
        what = f"the complete file is kept as {temporary}"
    else:
        temporary.unlink(missing_ok=True)
        what = "this file is removed"
    return TargetExistsError(
        f"{target} appeared while it was being written (another program created it); "
        f"it is not replaced, and {what}",
        target,
        temporary if keep else None,
    )


def commit(temporary: Path, target: Path, *, replace: bool = True, keep: bool = False) -> None:
    """Flush ``temporary`` to the disk and rename it to ``target``.

    Parameters
    ----------
    temporary, target : Path
        The complete file and its final name.
    replace : bool
        Replace ``target`` if it exists; False: a no-replace rename.
    keep : bool
        With ``replace`` False: keep ``temporary`` when ``target`` is taken (else it is
        removed).

    Raises
    ------
    TargetExistsError
        ``replace`` is False and ``target`` exists.
    OutputError
        The flush or the rename failed (the temporary file is removed).
    """
    try:
        _sync_file(temporary)
        if replace:
            os.replace(temporary, target)
        else:
            rename_no_replace(temporary, target)
    except FileExistsError as exc:
        raise _taken(target, temporary, keep) from exc
    except OSError as exc:
        temporary.unlink(missing_ok=True)
        raise OutputError(f"cannot write {target}: {os_error_text(exc)}") from exc
    _sync_folder(target.parent)


@contextlib.contextmanager
def atomic_path(
    target: str | os.PathLike[str], *, replace: bool = True, keep: bool = False
) -> Iterator[Path]:
    """Yield a temporary path to write ``target`` to; rename it to ``target`` on success.

    If the block raises (or is interrupted), the temporary file is removed and
    ``target`` stays as it was. ``replace`` and ``keep`` as for :func:`commit`.

    Raises
    ------
    TargetExistsError
        ``replace`` is False and ``target`` exists by the time the file is complete.
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
    commit(temporary, final, replace=replace, keep=keep)


def _identity(path: Path) -> tuple[int, int]:
    status = os.stat(path, follow_symlinks=False)
    return status.st_dev, status.st_ino


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

    def commit(self, *, replace: bool = True) -> list[Path]:
        """Flush every file written and rename each to its name; return the final paths.

        An output whose temporary file was never created is skipped.

        Parameters
        ----------
        replace : bool
            Replace files of those names; False: no-replace renames, and when one
            name is taken, none of this set's files stays in place.

        Raises
        ------
        TargetExistsError
            ``replace`` is False and a name is taken (every temporary file is removed).
        OutputError
            A flush or rename failed; files not yet renamed are removed.
        """
        written = {name: p for name, p in self._temporary.items() if p.exists()}
        placed: list[tuple[Path, tuple[int, int]]] = []
        try:
            for temporary in written.values():
                _sync_file(temporary)
            for name, temporary in written.items():
                final = self.folder / name
                if replace:
                    os.replace(temporary, final)
                    continue
                identity = _identity(temporary)
                rename_no_replace(temporary, final)
                placed.append((final, identity))
        except FileExistsError as exc:
            self._take_back(placed)
            self.discard()
            raise TargetExistsError(
                f"{exc.filename} appeared while this run was writing into {self.folder} "
                "(another program created it); it is not replaced, and this run's files "
                "are removed",
                Path(exc.filename),
                None,
            ) from exc
        except OSError as exc:
            self._take_back(placed)
            self.discard()
            raise OutputError(f"cannot write into {self.folder}: {os_error_text(exc)}") from exc
        self._temporary.clear()
        _sync_folder(self.folder)
        return [self.folder / name for name in written]

    @staticmethod
    def _take_back(placed: list[tuple[Path, tuple[int, int]]]) -> None:
        """Remove the files this commit put in place (each only if it is still this run's)."""
        for final, identity in placed:
            with contextlib.suppress(OSError):
                if _identity(final) == identity:
                    final.unlink()

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
    TargetExistsError
        ``replace`` is False and ``target`` appeared while the folder was written.
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
        elif replace:
            os.replace(temporary, final)
        else:  # nothing there when this began: nothing that appeared since is replaced
            rename_no_replace(temporary, final)
    except FileExistsError as exc:
        shutil.rmtree(temporary, ignore_errors=True)
        raise TargetExistsError(
            f"{final} appeared while it was being written (another program created it); "
            "it is not replaced, and this folder is removed",
            final,
            None,
        ) from exc
    except OSError as exc:
        if old is not None and old.exists() and not final.exists():
            os.replace(old, final)
        shutil.rmtree(temporary, ignore_errors=True)
        raise OutputError(f"cannot write {final}: {os_error_text(exc)}") from exc
    _sync_folder(final.parent)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
