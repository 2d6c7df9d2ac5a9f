"""Pixel formats: unpackers checked against bytes built bit by bit from the specifications."""

from __future__ import annotations

import numpy as np
import pytest

from holoview.acquire.pixel_formats import PIXEL_FORMATS, pixel_format, unpack
from holoview.acquire.source import UnsupportedFeatureError
from holoview.errors import InputError

SHAPE = (3, 5)  # 15 pixels: an odd count leaves a partly used last group


def values(bits: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = rng.integers(0, 2**bits, SHAPE, dtype=np.uint16)
    v.flat[0], v.flat[1] = 2**bits - 1, 0x0A5 & (2**bits - 1)  # all ones; a mixed pattern
    return v


def pack_lsb_first(pixels: np.ndarray, bits: int) -> bytes:
    """PFNC ``MonoNp``: values back to back, least significant bit first."""
    stream = 0
    for i, value in enumerate(int(p) for p in pixels.reshape(-1)):
        stream |= value << (i * bits)
    return stream.to_bytes(-(-pixels.size * bits // 8), "little")


def pack_gige_mono12packed(pixels: np.ndarray) -> bytes:
    """GigE Vision ``Mono12Packed``, from the byte table in the standard."""
    flat = [int(p) for p in pixels.reshape(-1)]
    if len(flat) % 2:
        flat.append(0)
    out = bytearray()
    for p0, p1 in zip(flat[::2], flat[1::2], strict=True):
        out += bytes([p0 >> 4, (p0 & 0xF) | ((p1 & 0xF) << 4), p1 >> 4])
    return bytes(out)


def test_mono8_and_16_bit_containers_keep_raw_values() -> None:
    v8 = values(8).astype(np.uint8)
    out = unpack(v8.tobytes(), "Mono8", SHAPE)
    assert out.dtype == np.uint8
    np.testing.assert_array_equal(out, v8)
    for name, bits in (("Mono10", 10), ("Mono12", 12), ("Mono14", 14), ("Mono16", 16)):
        v = values(bits)
        out = unpack(v.astype("<u2").tobytes() + b"\0\0pad", name, SHAPE)
        assert out.dtype == np.uint16
        np.testing.assert_array_equal(out, v)  # not scaled to 16 bits


def test_mono12p_follows_pfnc_bit_order() -> None:
    v = values(12)
    raw = pack_lsb_first(v, 12)
    assert raw[0] == 0xFF and raw[1] & 0x0F == 0x0F  # pixel 0 = 0xFFF, low bits first
    np.testing.assert_array_equal(unpack(raw, "Mono12p", SHAPE), v)


def test_mono12packed_follows_gige_vision_byte_table() -> None:
    v = values(12)
    raw = pack_gige_mono12packed(v)
    np.testing.assert_array_equal(unpack(raw, "Mono12Packed", SHAPE), v)


def test_the_two_12_bit_layouts_are_not_interchangeable() -> None:
    v = values(12)
    v.flat[0] = 0x123
    wrong = unpack(pack_gige_mono12packed(v), "Mono12p", SHAPE)
    assert wrong.flat[0] != 0x123
    assert wrong.flat[1] == v.flat[1]  # pixel 1 sits in the same bits in both


def test_mono10p_four_pixels_in_five_bytes() -> None:
    v = values(10, seed=3)
    np.testing.assert_array_equal(unpack(pack_lsb_first(v, 10), "Mono10p", SHAPE), v)


def test_unpack_accepts_an_ndarray_buffer_and_leaves_it_alone() -> None:
    v = values(12)
    raw = np.frombuffer(pack_lsb_first(v, 12), np.uint8).copy()
    before = raw.copy()
    np.testing.assert_array_equal(unpack(raw, "Mono12p", SHAPE), v)
    np.testing.assert_array_equal(raw, before)


def test_short_buffer_is_a_clear_error() -> None:
    raw = pack_lsb_first(values(12), 12)
    with pytest.raises(InputError, match=r"needs 23 bytes, the buffer has 22"):
        unpack(raw[:-1], "Mono12p", SHAPE)


def test_unknown_format_names_the_supported_ones() -> None:
    with pytest.raises(UnsupportedFeatureError, match=r"BayerRG8.*Mono8"):
        pixel_format("BayerRG8")
    assert {"Mono8", "Mono12Packed", "Mono12p", "Mono16"} <= set(PIXEL_FORMATS)
    assert pixel_format("Mono12p").raw_size((3, 5)) == 23
