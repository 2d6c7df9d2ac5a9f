"""Monochrome GenICam pixel formats: raw bytes from a camera to arrays, values kept raw.

Mono8 becomes ``uint8``; Mono10, Mono12, Mono14 and Mono16 arrive in 16-bit
little-endian containers and stay unscaled in ``uint16`` (a Mono12 value is
0..4095). Three packed formats are unpacked to ``uint16``:

- ``Mono12Packed`` (GigE Vision 2.0, section "Mono12Packed"): two pixels in three
  bytes, byte 0 = pixel 0 bits 11..4, byte 1 = pixel 0 bits 3..0 in its low nibble
  and pixel 1 bits 3..0 in its high nibble, byte 2 = pixel 1 bits 11..4.
- ``Mono12p`` (PFNC, Pixel Format Naming Convention 2.x): the 12-bit values packed
  back to back, least significant bit first; byte 0 = pixel 0 bits 7..0, byte 1 =
  pixel 0 bits 11..8 in its low nibble and pixel 1 bits 3..0 in its high nibble,
  byte 2 = pixel 1 bits 11..4.
- ``Mono10p`` (PFNC): four 10-bit pixels in five bytes, least significant bit first.

The two 12-bit layouts differ only in where pixel 0's bits go, which is exactly
why they are easy to confuse: a frame decoded with the wrong one looks noisy but
plausible.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from holoview.acquire.source import UnsupportedFeatureError
from holoview.errors import InputError


@dataclass(frozen=True, slots=True)
class PixelFormat:
    """What a pixel format holds.

    Attributes
    ----------
    name : str
        GenICam name (``"Mono12p"``).
    dtype : numpy dtype
        Dtype of the unpacked array.
    bits : int
        Significant bits per value.
    packed_bits : int
        Bits each pixel takes in the raw buffer.
    """

    name: str
    dtype: np.dtype
    bits: int
    packed_bits: int

    def raw_size(self, shape: tuple[int, int]) -> int:
        """Bytes a frame of ``shape`` (rows, cols) takes in this format."""
        return -(-shape[0] * shape[1] * self.packed_bits // 8)


_U8, _U16 = np.dtype(np.uint8), np.dtype(np.uint16)

#: The pixel formats holoview unpacks, by GenICam name.
PIXEL_FORMATS: dict[str, PixelFormat] = {
    f.name: f
    for f in (
        PixelFormat("Mono8", _U8, 8, 8),
        PixelFormat("Mono10", _U16, 10, 16),
        PixelFormat("Mono12", _U16, 12, 16),
        PixelFormat("Mono14", _U16, 14, 16),
        PixelFormat("Mono16", _U16, 16, 16),
        PixelFormat("Mono10p", _U16, 10, 10),
        PixelFormat("Mono12Packed", _U16, 12, 12),
        PixelFormat("Mono12p", _U16, 12, 12),
    )
}


def pixel_format(name: str) -> PixelFormat:
    """Return the :class:`PixelFormat` called ``name``.

    Raises
    ------
    UnsupportedFeatureError
        holoview does not unpack that format (colour or Bayer formats, for instance).
    """
    try:
        return PIXEL_FORMATS[name]
    except KeyError:
        raise UnsupportedFeatureError(
            f"pixel format {name!r} is not supported (holoview reads {', '.join(PIXEL_FORMATS)})"
        ) from None


def unpack(
    raw: bytes | bytearray | memoryview | np.ndarray, name: str, shape: tuple[int, int]
) -> np.ndarray:
    """Return the frame of ``shape`` held in ``raw`` bytes of pixel format ``name``.

    Parameters
    ----------
    raw : bytes-like or ndarray
        The camera's buffer; extra bytes after the frame (padding) are ignored.
    name : str
        GenICam pixel format name, one of :data:`PIXEL_FORMATS`.
    shape : tuple of int
        ``(rows, cols)`` of the frame, pixels.

    Returns
    -------
    ndarray
        A new ``(rows, cols)`` array of the format's dtype with the raw values.

    Raises
    ------
    InputError
        The buffer is shorter than a frame (truncated or corrupt).
    UnsupportedFeatureError
        The format is not one holoview unpacks.
    """
    fmt = pixel_format(name)
    rows, cols = int(shape[0]), int(shape[1])
    n = rows * cols
    buffer = np.frombuffer(raw, np.uint8) if not isinstance(raw, np.ndarray) else raw.view(np.uint8)
    buffer = buffer.reshape(-1)
    need = fmt.raw_size((rows, cols))
    if buffer.size < need:
        raise InputError(
            f"{name} frame of {rows} x {cols} needs {need} bytes, the buffer has {buffer.size}"
        )
    if fmt.packed_bits == 8:
        return buffer[:n].copy().reshape(rows, cols)
    if fmt.packed_bits == 16:
        return buffer[: 2 * n].view("<u2").astype(np.uint16).reshape(rows, cols)
    if fmt.packed_bits == 12:
        return _unpack12(buffer, n, gige=(name == "Mono12Packed")).reshape(rows, cols)
    return _unpack10p(buffer, n).reshape(rows, cols)


def _groups(buffer: np.ndarray, n_pixels: int, pixels: int, nbytes: int) -> np.ndarray:
    """Return ``(groups, nbytes)`` uint16 of the bytes holding ``n_pixels``, zero-padded."""
    groups = -(-n_pixels // pixels)
    data = np.zeros(groups * nbytes, np.uint16)
    used = min(buffer.size, groups * nbytes)
    data[:used] = buffer[:used]
    return data.reshape(groups, nbytes)


def _unpack12(buffer: np.ndarray, n: int, *, gige: bool) -> np.ndarray:
    b = _groups(buffer, n, 2, 3)
    out = np.empty((b.shape[0], 2), np.uint16)
    if gige:  # GigE Vision Mono12Packed: byte 0 holds the high bits of pixel 0
        out[:, 0] = (b[:, 0] << 4) | (b[:, 1] & 0x0F)
    else:  # PFNC Mono12p: least significant bits first
        out[:, 0] = b[:, 0] | ((b[:, 1] & 0x0F) << 8)
    out[:, 1] = (b[:, 2] << 4) | (b[:, 1] >> 4)
    return out.reshape(-1)[:n]


def _unpack10p(buffer: np.ndarray, n: int) -> np.ndarray:
    b = _groups(buffer, n, 4, 5)
    out = np.empty((b.shape[0], 4), np.uint16)
    out[:, 0] = b[:, 0] | ((b[:, 1] & 0x03) << 8)
    out[:, 1] = (b[:, 1] >> 2) | ((b[:, 2] & 0x0F) << 6)
    out[:, 2] = (b[:, 2] >> 4) | ((b[:, 3] & 0x3F) << 4)
    out[:, 3] = (b[:, 3] >> 6) | (b[:, 4] << 2)
    return out.reshape(-1)[:n]
