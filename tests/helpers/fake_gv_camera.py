"""Serve a GigE Vision camera on 127.0.0.1 from this process, with frames from a .npy file.

Usage::

    python fake_gv_camera.py SERIAL FRAMES.npy [--lost-ratio R]

Aravis discovers the camera as ``Aravis-Fake-SERIAL`` and streams over real
GVCP/GVSP sockets on loopback, exactly as a lab camera on a network. Frame
``k`` (Aravis ids start at 1) is ``frames[(k - 1) % len(frames)]`` cropped to
the region the client set, in the pixel format it set (Mono8 or Mono16), so a
client can check every frame it receives. ``--lost-ratio`` makes the camera drop
that fraction of stream packets (it never resends them).

The fill callback goes through ctypes (through PyGObject the callback is freed at
once and the process crashes). The process prints ``ready`` when serving and
serves until stdin closes or it gets SIGTERM or SIGINT; then it restores the
default fill and stops the acquisition before it exits, or GLib aborts.
"""

from __future__ import annotations

import argparse
import ctypes
import signal
import sys
import threading

import gi
import numpy as np

gi.require_version("Aravis", "0.8")
from gi.repository import Aravis  # noqa: E402 (after require_version)

LIB = ctypes.CDLL("libaravis-0.8.so.0")
FILL = ctypes.CFUNCTYPE(
    None, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint32, ctypes.c_uint32, ctypes.c_uint32
)
LIB.arv_fake_camera_set_fill_pattern.argtypes = [ctypes.c_void_p, FILL, ctypes.c_void_p]
LIB.arv_buffer_get_data.restype = ctypes.c_void_p
LIB.arv_buffer_get_data.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_size_t)]
for name in ("arv_buffer_get_image_width", "arv_buffer_get_image_height"):
    getattr(LIB, name).restype = ctypes.c_int
    getattr(LIB, name).argtypes = [ctypes.c_void_p]
LIB.arv_buffer_get_frame_id.restype = ctypes.c_uint64
LIB.arv_buffer_get_frame_id.argtypes = [ctypes.c_void_p]
LIB.arv_fake_camera_write_register.argtypes = [ctypes.c_void_p, ctypes.c_uint32, ctypes.c_uint32]
ctypes.pythonapi.PyCapsule_GetPointer.restype = ctypes.c_void_p
ctypes.pythonapi.PyCapsule_GetPointer.argtypes = [ctypes.py_object, ctypes.c_char_p]

MONO8, MONO16 = 0x01080001, 0x01100007
ACQUISITION_REGISTER = 0x124  # ARV_FAKE_CAMERA_REGISTER_ACQUISITION


def gobject_pointer(obj: object) -> int:
    """The C address of a PyGObject wrapper's GObject."""
    return ctypes.pythonapi.PyCapsule_GetPointer(obj.__gpointer__, None)  # type: ignore[attr-defined]


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("serial")
    parser.add_argument("frames")
    parser.add_argument("--lost-ratio", type=float, default=0.0)
    args = parser.parse_args()
    frames = np.load(args.frames)

    def fill(buffer: int, _data: int, _exposure: int, _gain: int, pixel_format: int) -> None:
        width = LIB.arv_buffer_get_image_width(buffer)
        height = LIB.arv_buffer_get_image_height(buffer)
        frame_id = LIB.arv_buffer_get_frame_id(buffer)
        source = frames[(frame_id - 1) % len(frames)]
        image = np.zeros((height, width), np.uint16)
        rows, cols = min(height, source.shape[0]), min(width, source.shape[1])
        image[:rows, :cols] = source[:rows, :cols]
        raw = (image.astype("<u2") if pixel_format == MONO16 else image.astype(np.uint8)).tobytes()
        size = ctypes.c_size_t(0)
        pointer = LIB.arv_buffer_get_data(buffer, ctypes.byref(size))
        if pointer:
            ctypes.memmove(pointer, raw, len(raw))  # sized from width and height

    callback = FILL(fill)  # kept referenced for the life of the camera
    gv_camera = Aravis.GvFakeCamera.new("127.0.0.1", args.serial)
    if args.lost_ratio > 0:
        gv_camera.set_property("gvsp-lost-ratio", args.lost_ratio)
    fake = gv_camera.get_fake_camera()
    fake_pointer = gobject_pointer(fake)
    LIB.arv_fake_camera_set_fill_pattern(fake_pointer, callback, None)
    if not gv_camera.is_running():
        print("not running", flush=True)
        return 1

    done = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: done.set())
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    print("ready", flush=True)
    while not done.wait(0.2):
        pass
    LIB.arv_fake_camera_write_register(fake_pointer, ACQUISITION_REGISTER, 0)
    LIB.arv_fake_camera_set_fill_pattern(fake_pointer, FILL(0), None)
    del fake
    del gv_camera
    return 0


if __name__ == "__main__":
    sys.exit(main())
