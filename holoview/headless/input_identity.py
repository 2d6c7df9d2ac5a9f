"""What a run's input is, taken when the run starts and checked until its results are written.

A parallel run's workers open the input by its path, chunk after chunk; a file moved
or copied over that path meanwhile would have its frames stitched to those of the
first (seen: two recordings of the same shape gave a fused rate of -1.04 um/min for
-0.82, a shorter one an ``IndexError``). :class:`InputIdentity` names the content
behind a path cheaply enough to be taken again before every chunk:

- a holoview recording: its ``uuid`` (unique per recording, written when it is
  created), so that a recording still being written, whose size and time change as
  frames are appended, keeps its identity;
- any other file (a TIFF, a numpy array, a video, a recording without a uuid): its
  size, its modification time in whole seconds (file systems shared between hosts
  keep time at different resolutions) and a SHA-256 of its first and last
  :data:`END_BYTES` bytes (the header, and where a copy of another length differs);
- a folder of images: the names, sizes and modification times of its images, hashed.

The parent takes it once (:meth:`InputIdentity.of`), every worker compares what it
finds before each chunk, and the parent compares again before it writes any result
(:meth:`InputIdentity.check`): a difference is an :class:`~holoview.errors.InputError`
naming the file, "replaced during the run".
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from holoview.acquire.frame_file import HDF5_SUFFIXES, IMAGE_SUFFIXES
from holoview.acquire.recording_reader import RecordingReader
from holoview.errors import InputError

#: Bytes hashed at each end of a file.
END_BYTES = 64 * 1024


def _ends_digest(path: Path, size: int) -> str:
    """SHA-256 of the first and the last :data:`END_BYTES` bytes of the file at ``path``."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        digest.update(f.read(END_BYTES))
        if size > END_BYTES:
            f.seek(max(END_BYTES, size - END_BYTES))
            digest.update(f.read(END_BYTES))
    return digest.hexdigest()


def _folder_digest(path: Path) -> tuple[int, str]:
    """The images of a folder (as the replay reads them): their count and a hash of
    their names, sizes and modification times (s)."""
    digest = hashlib.sha256()
    count = 0
    for entry in sorted(os.scandir(path), key=lambda e: e.name):
        if entry.name.startswith(".") or Path(entry.name).suffix.lower() not in IMAGE_SUFFIXES:
            continue
        try:
            stat = entry.stat()
        except OSError:  # a broken link: as it is
            digest.update(f"{entry.name}\0broken\n".encode("utf-8", "surrogateescape"))
            continue
        count += 1
        line = f"{entry.name}\0{stat.st_size}\0{int(stat.st_mtime)}\n"
        digest.update(line.encode("utf-8", "surrogateescape"))
    return count, digest.hexdigest()


@dataclass(frozen=True)
class InputIdentity:
    """The content behind an input's path, in a few values (module documentation).

    Attributes
    ----------
    path : str
        The input's absolute path (links resolved), where the workers open it.
    kind : str
        ``"recording"`` (a holoview recording with a uuid), ``"file"`` or ``"folder"``.
    uuid : str
        A holoview recording's uuid (``""`` for other inputs: the rest identifies them).
    size : int
        Bytes of a file, images in a folder (-1 for a recording with a uuid).
    mtime_s : int
        Modification time of a file, whole seconds since the epoch (-1 for a recording
        with a uuid, and for a folder).
    digest : str
        SHA-256 of a file's two ends, or of a folder's listing (``""`` for a recording
        with a uuid).
    """

    path: str
    kind: str
    uuid: str = ""
    size: int = -1
    mtime_s: int = -1
    digest: str = ""

    @classmethod
    def of(cls, path: str | os.PathLike[str], uuid: str | None = None) -> InputIdentity:
        """The identity of what is at ``path`` now.

        Parameters
        ----------
        path : str or PathLike
            The input.
        uuid : str, optional
            A recording's uuid as read from the handle the caller holds (else it is read
            from the file).

        Raises
        ------
        InputError
            Nothing can be read at ``path`` (the message names it).
        """
        where = Path(path).resolve()
        try:
            if where.is_dir():
                count, digest = _folder_digest(where)
                return cls(str(where), "folder", size=count, digest=digest)
            if where.suffix.lower() in HDF5_SUFFIXES:
                if uuid is None:
                    with RecordingReader(where) as reader:
                        uuid = reader.uuid
                if uuid:
                    return cls(str(where), "recording", uuid=uuid)
            stat = where.stat()
            digest = _ends_digest(where, stat.st_size)
        except OSError as exc:
            raise InputError(f"{path}: cannot be read ({exc.strerror or exc})") from None
        return cls(str(where), "file", size=stat.st_size, mtime_s=int(stat.st_mtime), digest=digest)

    def difference(self, now: InputIdentity) -> str | None:
        """What differs in ``now`` from this identity, in words; None when it is the same."""
        if now.kind != self.kind:
            return f"a {now.kind}, not a {self.kind}"
        if self.kind == "recording":
            return None if now.uuid == self.uuid else f"recording {now.uuid}, not {self.uuid}"
        if now.size != self.size:
            unit = "images" if self.kind == "folder" else "bytes"
            return f"{now.size} {unit}, not {self.size}"
        if now.mtime_s != self.mtime_s:
            return "modified since the run started"
        if now.digest != self.digest:
            return "other images" if self.kind == "folder" else "other content"
        return None

    def check(self, now: InputIdentity | None = None, who: str = "") -> None:
        """Raise unless the input still is what it was when the run started.

        Parameters
        ----------
        now : InputIdentity, optional
            What a worker found (default: taken now).
        who : str
            Who looked (``"a worker on HOST"``), for the message.

        Raises
        ------
        InputError
            ``PATH: replaced during the run (...)``: the input changed, or is gone.
        """
        try:
            now = InputIdentity.of(self.path) if now is None else now
        except InputError as exc:
            raise InputError(f"{self.path}: replaced during the run ({exc})") from None
        changed = self.difference(now)
        if changed is not None:
            seen = f"{who} finds " if who else ""
            raise InputError(f"{self.path}: replaced during the run ({seen}{changed})")
