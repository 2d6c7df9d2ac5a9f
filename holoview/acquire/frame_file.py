"""What every frame file a replay plays is: frames of one shape and type, read by index.

:class:`FrameFile` is the interface the replay source and ``holoview process`` read
through (a frame, its id, its times, the clock that times a range, a check before a
frame is read); the suffixes of each kind, natural order for a folder's names, and the
conversion of colour images to grey are shared by the readers
(:mod:`~holoview.acquire.replay_files`, :mod:`~holoview.acquire.image_files`,
:mod:`~holoview.acquire.array_files`, :mod:`~holoview.acquire.video_files`).
"""

from __future__ import annotations

import math
import re
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any

import numpy as np

from holoview.acquire.frame_times import FrameClock, choose_clock
from holoview.errors import InputError

VIDEO_SUFFIXES = (".avi", ".mkv", ".mp4", ".mov")
IMAGE_SUFFIXES = (".tif", ".tiff", ".png")
HDF5_SUFFIXES = (".h5", ".hdf5")
NUMPY_SUFFIXES = (".npy", ".npz")


class FrameFile(ABC):
    """A finite sequence of frames of one shape and dtype, read by index.

    Attributes
    ----------
    path : Path
        The file or folder.
    kind : str
        ``"hdf5"``, ``"tiff"``, ``"folder"``, ``"numpy"`` or ``"video"``.
    frame_shape : tuple of int
        ``(rows, cols)``, pixels.
    dtype : numpy dtype
        The frames' dtype.
    rate_hz : float or None
        The file's own frame rate, frames per second, where it has one.
    pixel_format : str
        GenICam name of the values (``Mono8``/``Mono16`` unless the file says more).
    setup : dict
        The optical setup stored in the file (holoview recordings), else empty.
    experiments : list of (int, str)
        The experiments the file carries, ``(from_frame, JSON text)`` in order
        (holoview recordings), else empty.
    """

    kind = ""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.rate_hz: float | None = None
        self.setup: dict[str, Any] = {}
        self.experiments: list[tuple[int, str]] = []
        #: Why a recording's stored experiment is not carried (damaged), else None.
        self.experiment_problem: str | None = None
        self.frame_shape: tuple[int, int] = (0, 0)
        self.dtype = np.dtype(np.uint16)
        self.pixel_format = ""
        self._size = path.stat().st_size if path.is_file() else 0

    def _set_format(self, shape: tuple[int, ...], dtype: np.dtype) -> None:
        self.frame_shape = (int(shape[0]), int(shape[1]))
        self.dtype = np.dtype(dtype)
        if not self.pixel_format:
            self.pixel_format = {1: "Mono8", 2: "Mono16"}.get(self.dtype.itemsize, "")

    @abstractmethod
    def __len__(self) -> int:
        """Number of frames."""

    @abstractmethod
    def read(self, index: int) -> np.ndarray:
        """Return frame ``index`` as a new ``(rows, cols)`` array; InputError if unreadable."""

    def frame_id(self, index: int) -> int:
        """The frame id stored for frame ``index`` (its index where the file has none)."""
        return index

    def t_device(self, index: int) -> float:
        """The device timestamp of frame ``index``, seconds (NaN where the file has none)."""
        return math.nan

    def time_s(self, index: int) -> float:
        """Time of frame ``index`` since frame 0, seconds (NaN where the file has none)."""
        return self.t_device(index) - self.t_device(0)

    def clock(self, frames: range) -> FrameClock:
        """The clock that times ``frames`` (the rule of :mod:`~holoview.acquire.frame_times`)."""
        times = np.array([self.t_device(i) for i in frames], dtype=np.float64)
        return choose_clock(times, None, frames, camera_name=self.clock_name)

    @property
    def clock_name(self) -> str:
        """What the file's own times are called in notes."""
        return "the file's own times"

    def refresh(self) -> int:
        """See frames appended since opening (live recordings); return the frame count."""
        return len(self)

    def notes(self) -> list[str]:
        """What a reader of results should know about the file's frames (none by default)."""
        return []

    def check(self, index: int) -> None:
        """Check that the file is still whole before frame ``index`` is read.

        A file deleted while open stays readable through its open handle on POSIX, and
        one cut short can give garbage or crash a reader, so both are looked for here.

        Raises
        ------
        InputError
            The file has disappeared, or is shorter than when it was opened (the
            message names the file and the frame).
        """
        try:
            size = self.path.stat().st_size
        except FileNotFoundError:
            raise InputError(
                f"{self.path}: the file disappeared while it was replayed (at frame {index})"
            ) from None
        except OSError as exc:
            raise InputError(f"{self.path}: unreadable at frame {index} ({exc})") from exc
        if size < self._size:
            raise InputError(
                f"{self.path}: the file shrank from {self._size} to {size} bytes while it was "
                f"replayed (at frame {index})"
            )
        self._size = size  # a recording still being written grows

    def close(self) -> None:  # noqa: B027 (most files need nothing)
        """Release the file."""


def natural_key(text: str) -> list[object]:
    """Sort key of natural order: ``run2`` before ``run10``, letters regardless of case."""
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", text)]


def grey(image: np.ndarray, where: str) -> np.ndarray:
    """Return a 2-D grey image: colour (BGR or BGRA) converted with OpenCV's luma weights."""
    if image.ndim == 2:
        return image
    import cv2

    if image.ndim == 3 and image.shape[2] in (3, 4):
        code = cv2.COLOR_BGR2GRAY if image.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        return cv2.cvtColor(image, code)
    if image.ndim == 3 and image.shape[2] == 1:
        return image[:, :, 0]
    raise InputError(f"{where}: images of shape {image.shape} are not supported (grey or colour)")
