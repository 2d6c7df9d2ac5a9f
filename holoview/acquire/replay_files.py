"""Frame files a replay source plays: holoview recordings, TIFF stacks, image folders, videos.

:func:`open_frame_file` picks the reader by what the path is: a folder (``*.tif``,
``*.tiff``, ``*.png`` in natural order; hidden files such as macOS's ``._NAME``
companions are skipped), ``.h5``/``.hdf5`` (a holoview recording),
``.tif``/``.tiff`` (a multi-page stack), ``.npy``/``.npz`` (a numpy array: 2-D is one
frame, 3-D ``(frames, rows, cols)`` a stack; an ``.npz`` holding one array, or one
named ``frames``), or a video (``.avi``, ``.mkv``, ``.mp4``, ``.mov``; FFV1, also
16-bit grey, and MJPG through OpenCV's FFmpeg backend, whose log lines are silenced).
Every reader checks at open what can be checked without decoding every frame: a
TIFF whose pages run past the end of the file, a TIFF of several channels (ImageJ,
OME), pages or images of different sizes, an array of the wrong shape or type or
shorter than its header says, a recording without frames, a video OpenCV cannot
decode, each is a one-line :class:`~holoview.errors.InputError`. Colour images and
videos are converted to grey with OpenCV's luma weights; grey values stay raw
(16-bit stays 16-bit). Arrays are read a frame at a time (``.npz`` members too), so
memory stays bounded whatever the stack's length.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from holoview.acquire.array_files import NumpyFile
from holoview.acquire.frame_file import HDF5_SUFFIXES, NUMPY_SUFFIXES, VIDEO_SUFFIXES, FrameFile
from holoview.acquire.frame_times import FrameClock
from holoview.acquire.image_files import ImageFolder, TiffStack
from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.source import CameraNotFoundError
from holoview.acquire.video_files import VideoFile
from holoview.errors import InputError
from holoview.file_kinds import special_file


class HDF5File(FrameFile):
    """A holoview recording (see :mod:`holoview.acquire.recording`)."""

    kind = "hdf5"

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self._reader = RecordingReader(path)
        if len(self._reader) == 0 and self._reader.refresh() == 0:
            self._reader.close()
            raise InputError(f"{path}: the recording holds no frames")
        self.pixel_format = self._reader.pixel_format
        self._set_format(self._reader.frame_shape, self._reader.dtype)
        self.setup = dict(self._reader.setup)
        self._load_index()

    def _load_index(self) -> None:
        try:
            self.experiments = self._reader.experiments()
        except InputError as exc:  # the frames still play; the experiment is not carried
            self.experiment_problem = str(exc)
            self.experiments = []
        self._ids = self._reader.frame_ids
        self._times = self._reader.times
        self.rate_hz = self._reader.fps if math.isfinite(self._reader.fps) else None
        self._t_device = self._reader.t_device

    def __len__(self) -> int:
        return len(self._reader)

    def read(self, index: int) -> np.ndarray:
        try:
            return self._reader.frame(index)
        except OSError as exc:
            raise InputError(f"{self.path}: frame {index} is unreadable ({exc})") from exc

    def frame_id(self, index: int) -> int:
        return int(self._ids[index])

    def t_device(self, index: int) -> float:
        return float(self._t_device[index])

    def time_s(self, index: int) -> float:
        dt = float(self._times[index] - self._times[0])
        return dt if math.isfinite(dt) else math.nan

    def clock(self, frames: range) -> FrameClock:
        return self._reader.clock(frames)

    def notes(self) -> list[str]:
        notes = []
        incomplete = self._reader.incomplete()
        if incomplete is not None:
            notes.append(incomplete)
        if self._reader.being_written:
            notes.append(
                f"{self.path} was open for writing when it was read (a recording under way, "
                f"or one whose writer was killed): the {len(self)} frames flushed by then are "
                "read, as a snapshot"
            )
        return notes

    def interval_s(self, index: int) -> float | None:
        """Recorded time between frame ``index - 1`` and ``index``, seconds, where known."""
        if index <= 0 or index >= len(self._times):
            return None
        dt = float(self._times[index] - self._times[index - 1])
        return dt if math.isfinite(dt) and dt >= 0 else None

    def refresh(self) -> int:
        before = len(self._reader)
        if self._reader.refresh() != before:
            self._load_index()
        return len(self._reader)

    def close(self) -> None:
        self._reader.close()


def check_not_results_folder(folder: Path) -> None:
    """Refuse a run's output folder given as frames (it holds ``results.h5``).

    Raises
    ------
    InputError
        ``folder`` holds a ``results.h5``: the message says where its results open.
    """
    if (folder / "results.h5").is_file():
        raise InputError(
            f"{folder} is the output folder of a holoview run (results.h5), not frames: "
            "open the recording it was made from, or its results with holoview waves, "
            "holoview export or holoview.api.open_results"
        )


def open_frame_file(path: str | Path) -> FrameFile:
    """Open the frame file or folder at ``path`` with the reader its kind needs.

    Raises
    ------
    CameraNotFoundError
        Nothing is at ``path``.
    InputError
        The file is of an unknown kind, damaged, truncated, empty, or of mixed sizes.
    """
    p = Path(path).expanduser()
    special = special_file(p)
    if special is not None:  # never opened: a FIFO would wait for a writer
        raise InputError(f"replay: {p}: {special}, not a file or folder of frames")
    if not p.exists():
        raise CameraNotFoundError(f"replay: {p}: no such file or folder")
    if p.is_dir():
        check_not_results_folder(p)  # its report.png would be taken for a frame
        return ImageFolder(p)
    suffix = p.suffix.lower()
    if suffix in HDF5_SUFFIXES:
        return HDF5File(p)
    if suffix in (".tif", ".tiff"):
        return TiffStack(p)
    if suffix in VIDEO_SUFFIXES:
        return VideoFile(p)
    if suffix in NUMPY_SUFFIXES:
        return NumpyFile(p)
    known = ", ".join((*HDF5_SUFFIXES, ".tif", ".tiff", *NUMPY_SUFFIXES, *VIDEO_SUFFIXES))
    raise InputError(
        f"replay: {p}: unknown file type {suffix or '(none)'} (known: {known}, folders)"
    )
