"""Frames from images: a multi-page TIFF stack, or a folder of TIFF or PNG images.

Both are checked at open as far as can be without decoding every image: pages past
the end of the file, several channels (ImageJ, OME), images of different sizes are one
line each (:class:`~holoview.errors.InputError`).
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from holoview.acquire.frame_file import IMAGE_SUFFIXES, FrameFile, grey, natural_key
from holoview.errors import InputError
from holoview.file_kinds import special_file

logger = logging.getLogger(__name__)


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
        return np.array(grey(image, str(self.path)), copy=True)

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
        image = grey(image, str(path))
        if self.frame_shape not in ((0, 0), image.shape):
            raise InputError(f"{path}: the image is {image.shape}, the others {self.frame_shape}")
        return np.array(image, copy=True)
