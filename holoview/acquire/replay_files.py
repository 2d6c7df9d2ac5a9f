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

import logging
import math
import os
import re
import struct
import zipfile
from abc import ABC, abstractmethod
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np

from holoview.acquire.frame_times import FrameClock, choose_clock
from holoview.acquire.recording_reader import RecordingReader
from holoview.acquire.source import CameraNotFoundError
from holoview.errors import InputError
from holoview.file_kinds import special_file

logger = logging.getLogger(__name__)

VIDEO_SUFFIXES = (".avi", ".mkv", ".mp4", ".mov")
IMAGE_SUFFIXES = (".tif", ".tiff", ".png")
HDF5_SUFFIXES = (".h5", ".hdf5")
NUMPY_SUFFIXES = (".npy", ".npz")

#: Video codecs (FourCC, lower case) whose grey frames OpenCV hands over raw (16-bit kept);
#: the others (MJPG, H.264, MPEG-4) are decoded to BGR and converted to grey.
RAW_FOURCCS = frozenset({"ffv1", "y800", "grey", "y8  ", "y16 "})


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


def _grey(image: np.ndarray, where: str) -> np.ndarray:
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


class TiffStack(FrameFile):
    """A multi-page TIFF, one frame per page (or a single-page TIFF: one frame)."""

    kind = "tiff"

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        import tifffile

        size = path.stat().st_size
        with _tifffile_messages(path):
            try:
                self._tif = tifffile.TiffFile(path)
            except (tifffile.TiffFileError, ValueError, OSError, struct.error) as exc:
                raise InputError(f"{path}: not a readable TIFF ({exc})") from exc
            try:
                pages = list(self._tif.pages)
                _ = self._tif.series  # parsed here, where tifffile's messages are collected
            except (tifffile.TiffFileError, ValueError, OSError, struct.error) as exc:
                self._tif.close()
                raise InputError(f"{path}: not a readable TIFF ({exc})") from exc
        try:
            if not pages:
                raise InputError(f"{path}: the TIFF holds no images")
            first = pages[0]
            self._check_channels(path)
            self._check_count(path, first, len(pages), size)
            for i, page in enumerate(pages):
                if page.shape != first.shape or page.dtype != first.dtype:
                    raise InputError(
                        f"{path}: page {i} is {page.shape} {page.dtype}, page 0 is "
                        f"{first.shape} {first.dtype}: pages of mixed sizes"
                    )
                end = max(
                    (o + c for o, c in zip(page.dataoffsets, page.databytecounts, strict=False)),
                    default=0,
                )
                if end > size:
                    raise InputError(
                        f"{path}: truncated TIFF: page {i} ends at byte {end}, the file has {size}"
                    )
            if first.dtype is None or np.dtype(first.dtype).kind not in "uif":
                raise InputError(f"{path}: TIFF pixels of type {first.dtype} are not supported")
            self._pages = pages
            sample = self.read(0)
        except BaseException:
            self._tif.close()
            raise
        self._set_format(sample.shape, sample.dtype)

    def _check_count(self, path: Path, first: Any, pages: int, size: int) -> None:
        """Refuse a stack that declares more frames than it has page directories for.

        The count declared is the series' (tifffile's shaped files) or ImageJ's
        ``images``. Where the pages' data run out (an interrupted copy), the line says
        how many whole frames the file holds; a file that holds them all behind one
        directory (ImageJ over 4 GB) is refused too, since frames are read page by page.
        """
        series = self._tif.series[0].shape if self._tif.series else ()
        declared = series[0] if first.ndim == 2 and len(series) == 3 else 1
        if self._tif.is_imagej:
            declared = max(declared, int((self._tif.imagej_metadata or {}).get("images", 1)))
        if declared <= pages:
            return
        start = min(first.dataoffsets, default=0)
        frame_bytes = sum(first.databytecounts)
        whole = min(declared, (size - start) // frame_bytes) if frame_bytes else pages
        if whole >= declared:
            raise InputError(
                f"{path}: {declared} frames behind {pages} page directories (an ImageJ file "
                "over 4 GB?): holoview reads TIFF stacks page by page; save it as an image "
                "sequence or a holoview recording"
            )
        raise InputError(
            f"{path}: truncated TIFF: it declares {declared} frames, the file ends after "
            f"{max(whole, pages)} whole ones ({size} bytes): an interrupted copy? copy it again"
        )

    def _check_channels(self, path: Path) -> None:
        """Refuse a stack of several channels (ImageJ ``TCYX``, OME): its pages interleave."""
        if not self._tif.series:
            return
        series = self._tif.series[0]
        axes = str(getattr(series, "axes", ""))
        if "C" in axes and series.shape[axes.index("C")] > 1:
            channels = series.shape[axes.index("C")]
            raise InputError(
                f"{path}: a TIFF of {channels} channels (axes {axes}, shape {series.shape}): "
                "holoview reads one channel of frames; save each channel as its own stack "
                "(ImageJ: Image > Color > Split Channels)"
            )

    def __len__(self) -> int:
        return len(self._pages)

    def read(self, index: int) -> np.ndarray:
        import tifffile

        try:
            image = self._pages[index].asarray()
        except (tifffile.TiffFileError, ValueError, OSError) as exc:
            raise InputError(f"{self.path}: page {index} is unreadable ({exc})") from exc
        if image.ndim == 3 and image.shape[2] in (3, 4):
            image = np.ascontiguousarray(image[:, :, 2::-1])  # RGB to BGR for _grey
        return np.array(_grey(image, str(self.path)), copy=True)

    def close(self) -> None:
        self._tif.close()


@contextmanager
def _tifffile_messages(path: Path) -> Iterator[list[str]]:
    """Collect what tifffile logs while ``path`` opens, instead of lines on stderr.

    tifffile logs a damaged file's errors ("invalid page offset") and reads on; the
    reader decides what they mean and says it in one line (debug log otherwise).
    """
    log = logging.getLogger("tifffile")
    said: list[str] = []

    class Collect(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            said.append(record.getMessage())

    handler, propagate = Collect(), log.propagate
    log.addHandler(handler)
    log.propagate = False
    try:
        yield said
    finally:
        log.removeHandler(handler)
        log.propagate = propagate
        for message in said:
            logger.debug("%s: tifffile: %s", path, message)


def _png_header(path: Path) -> tuple[tuple[int, int], int, int]:
    """Return ``((rows, cols), bit_depth, colour_type)`` from a PNG's IHDR chunk."""
    with open(path, "rb") as f:
        head = f.read(29)
    if len(head) < 29 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        raise InputError(f"{path}: not a PNG image")
    width, height, depth, colour = struct.unpack(">IIBB", head[16:26])
    return (height, width), depth, colour


def _image_format(path: Path) -> tuple[tuple[int, int], str]:
    """Return ``((rows, cols), dtype name)`` of one image file without decoding it."""
    if path.suffix.lower() == ".png":
        shape, depth, _ = _png_header(path)
        return shape, "uint16" if depth == 16 else "uint8"
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            return (int(page.shape[0]), int(page.shape[1])), str(page.dtype)
    except (tifffile.TiffFileError, ValueError, OSError, IndexError, struct.error) as exc:
        raise InputError(f"{path}: not a readable TIFF ({exc})") from exc


class ImageFolder(FrameFile):
    """A folder of TIFF and PNG images of one size, played in natural name order."""

    kind = "folder"

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        entries = list(path.iterdir())
        names = [p for p in entries if p.is_file()]
        files = sorted(
            (p for p in names if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".")),
            key=lambda p: natural_key(p.name),
        )
        hidden = [p.name for p in names if p.name.startswith(".")]
        if hidden:
            logger.info("%s: %d hidden files skipped (%s, ...)", path, len(hidden), hidden[0])
        special = [
            f"{p.name} ({what})"
            for p in entries
            if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".")
            for what in [special_file(p, folder_ok=False)]
            if what is not None
        ]
        if special:
            logger.warning(
                "%s: %d entries that are not image files skipped: %s",
                path,
                len(special),
                ", ".join(sorted(special, key=natural_key)),
            )
        if not files:
            raise InputError(f"{path}: the folder holds no TIFF or PNG images")
        first_shape, first_dtype = _image_format(files[0])
        for f in files[1:]:
            shape, dtype = _image_format(f)
            if (shape, dtype) != (first_shape, first_dtype):
                raise InputError(
                    f"{path}: images of mixed sizes: {f.name} is {shape} {dtype}, "
                    f"{files[0].name} is {first_shape} {first_dtype}"
                )
        self._files = files
        sample = self.read(0)
        self._set_format(sample.shape, sample.dtype)

    def __len__(self) -> int:
        return len(self._files)

    def check(self, index: int) -> None:
        if not self.path.is_dir():
            raise InputError(
                f"{self.path}: the folder disappeared while it was replayed (at frame {index})"
            )
        if not self._files[index].is_file():
            raise InputError(
                f"{self._files[index]}: the image of frame {index} disappeared while the "
                "folder was replayed"
            )

    def read(self, index: int) -> np.ndarray:
        path = self._files[index]
        if path.suffix.lower() == ".png":
            import cv2

            image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
            if image is None:
                raise InputError(f"{path}: the image is unreadable")
        else:
            import tifffile

            try:
                image = tifffile.imread(path, key=0)
            except (tifffile.TiffFileError, ValueError, OSError) as exc:
                raise InputError(f"{path}: the image is unreadable ({exc})") from exc
            if image.ndim == 3 and image.shape[2] in (3, 4):
                image = np.ascontiguousarray(image[:, :, 2::-1])
        image = _grey(image, str(path))
        if self.frame_shape not in ((0, 0), image.shape):
            raise InputError(f"{path}: the image is {image.shape}, the others {self.frame_shape}")
        return np.array(image, copy=True)


def _quiet_opencv(cv2: Any) -> None:
    """Keep OpenCV's and FFmpeg's log lines (a warning per frame for MJPG) off stderr."""
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # read when FFmpeg starts
    logging_module = getattr(getattr(cv2, "utils", None), "logging", None)
    if logging_module is not None:
        logging_module.setLogLevel(logging_module.LOG_LEVEL_ERROR)


class NumpyFile(FrameFile):
    """A numpy array: ``.npy``, or the one array (or ``frames``) of an ``.npz``.

    A 2-D array is one frame, a 3-D array ``(frames, rows, cols)`` a stack; integer
    or real values. Frames are read one at a time from the file (a member of an
    ``.npz`` is read as a stream), never the whole array at once.
    """

    kind = "numpy"

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self._zip: zipfile.ZipFile | None = None
        try:
            self._stream, size = self._open_stream(path)
        except (OSError, zipfile.BadZipFile, ValueError) as exc:
            self.close()
            raise InputError(f"{path}: not a readable numpy file ({exc})") from exc
        try:
            shape, dtype = self._read_header(path, size)
        except BaseException:
            self.close()
            raise
        self._count = shape[0] if len(shape) == 3 else 1
        self._stored_dtype = dtype
        self._set_format(shape[-2:], dtype.newbyteorder("="))
        self._frame_bytes = shape[-2] * shape[-1] * dtype.itemsize

    def _open_stream(self, path: Path) -> tuple[IO[bytes], int]:
        """Open the array's bytes; return the stream and its size in bytes."""
        if path.suffix.lower() == ".npy":
            return open(path, "rb"), path.stat().st_size
        self._zip = zipfile.ZipFile(path)
        members = [m for m in self._zip.infolist() if m.filename.endswith(".npy")]
        named = [m for m in members if m.filename == "frames.npy"]
        if len(members) != 1 and not named:
            names = ", ".join(m.filename[:-4] for m in members) or "none"
            raise ValueError(
                f"it holds {len(members)} arrays ({names}): keep one, or name it frames"
            )
        member = (named or members)[0]
        return self._zip.open(member), member.file_size

    def _read_header(self, path: Path, size: int) -> tuple[tuple[int, ...], np.dtype]:
        """Read and check the array's header; return its shape and stored dtype."""
        from numpy.lib import format as npy

        try:
            version = npy.read_magic(self._stream)
            if version == (1, 0):
                shape, fortran, dtype = npy.read_array_header_1_0(self._stream)
            elif version == (2, 0):
                shape, fortran, dtype = npy.read_array_header_2_0(self._stream)
            else:
                raise ValueError(f"npy format version {version} is not supported")
        except (ValueError, OSError, EOFError) as exc:
            raise InputError(f"{path}: not a readable numpy array ({exc})") from exc
        self._offset = self._stream.tell()
        self._fortran = bool(fortran)
        where = f"{path}: the array of shape {shape} and dtype {dtype}"
        if dtype.kind not in "uif" or dtype.fields is not None:
            hint = "; a complex field is not a hologram: give the intensity" * (dtype.kind == "c")
            raise InputError(f"{where} does not hold pixel values (integers or reals{hint})")
        if len(shape) == 3 and shape[-1] in (3, 4) and shape[0] >= 16:
            raise InputError(f"{where} looks like a colour image: give grey frames")
        if len(shape) not in (2, 3) or min(shape) < 1:
            raise InputError(f"{where}: frames are 2-D (rows, cols) or 3-D (frames, rows, cols)")
        if self._fortran and len(shape) == 3:
            raise InputError(f"{where} is in Fortran order: save numpy.ascontiguousarray of it")
        needed = self._offset + math.prod(shape) * dtype.itemsize
        if size < needed:
            raise InputError(
                f"{path}: truncated: the array needs {needed} bytes, the file holds {size}"
            )
        return tuple(int(n) for n in shape), dtype

    def __len__(self) -> int:
        return self._count

    def read(self, index: int) -> np.ndarray:
        if not 0 <= index < self._count:
            raise InputError(f"{self.path}: frame {index} out of range (0..{self._count - 1})")
        try:
            self._stream.seek(self._offset + index * self._frame_bytes)
            data = self._stream.read(self._frame_bytes)
        except (OSError, zipfile.BadZipFile, EOFError) as exc:
            raise InputError(f"{self.path}: frame {index} is unreadable ({exc})") from exc
        if len(data) != self._frame_bytes:
            raise InputError(f"{self.path}: frame {index} is cut short")
        frame = np.frombuffer(data, self._stored_dtype).reshape(
            self.frame_shape, order="F" if self._fortran else "C"
        )
        return frame.astype(self.dtype, order="C", copy=True)

    def close(self) -> None:
        stream = getattr(self, "_stream", None)
        if stream is not None:
            stream.close()
        if self._zip is not None:
            self._zip.close()


class VideoFile(FrameFile):
    """A video file decoded by OpenCV's FFmpeg backend (FFV1 grey 8/16-bit kept raw)."""

    kind = "video"

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        import cv2

        _quiet_opencv(cv2)
        self._cv2 = cv2
        self._capture = self._open_capture(raw=True)
        fourcc = int(self._capture.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little")
        self._raw = fourcc.decode("latin-1").lower() in RAW_FOURCCS
        if not self._raw:
            self._capture.release()
            self._capture = self._open_capture(raw=False)
        ok, frame = self._capture.read()
        if self._raw and ok and frame is not None and frame.ndim != 2:
            self._capture.release()
            self._raw = False
            self._capture = self._open_capture(raw=False)
            ok, frame = self._capture.read()
        if not ok or frame is None:
            self._capture.release()
            raise InputError(f"{path}: the video holds no frame OpenCV can decode")
        frame = self._convert(frame)
        self._set_format(frame.shape, frame.dtype)
        self._position = 1
        count = int(self._capture.get(cv2.CAP_PROP_FRAME_COUNT))
        self._count = count if count > 0 else self._count_by_reading()
        fps = float(self._capture.get(cv2.CAP_PROP_FPS))
        self.rate_hz = fps if math.isfinite(fps) and fps > 0 else None

    def _open_capture(self, *, raw: bool) -> Any:
        cv2 = self._cv2
        capture = cv2.VideoCapture(str(self.path), cv2.CAP_FFMPEG)
        if not capture.isOpened():
            capture.release()
            raise InputError(
                f"{self.path}: OpenCV cannot open the video (unknown codec or damaged)"
            )
        if raw and not capture.set(cv2.CAP_PROP_CONVERT_RGB, 0):
            logger.debug("%s: the backend ignores CONVERT_RGB=0", self.path)
        return capture

    def _convert(self, frame: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(_grey(frame, str(self.path)))

    def _count_by_reading(self) -> int:
        n = 1
        while self._capture.grab():
            n += 1
        self._seek(0)
        return n

    def _seek(self, index: int) -> None:
        self._capture.set(self._cv2.CAP_PROP_POS_FRAMES, index)
        self._position = index

    def __len__(self) -> int:
        return self._count

    def read(self, index: int) -> np.ndarray:
        if index != self._position:
            self._seek(index)
        ok, frame = self._capture.read()
        if not ok or frame is None:
            raise InputError(f"{self.path}: frame {index} cannot be decoded")
        self._position = index + 1
        frame = self._convert(frame)
        if frame.shape != self.frame_shape or frame.dtype != self.dtype:
            raise InputError(f"{self.path}: frame {index} is {frame.shape} {frame.dtype}")
        return frame

    def t_device(self, index: int) -> float:
        return index / self.rate_hz if self.rate_hz else math.nan

    @property
    def clock_name(self) -> str:
        return f"the video's frame rate ({self.rate_hz or math.nan:g} frames/s)"

    def close(self) -> None:
        self._capture.release()


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
