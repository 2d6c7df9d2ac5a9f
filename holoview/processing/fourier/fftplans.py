"""Planned FFTs through pyFFTW, with FFTW wisdom kept in the user cache directory.

FFTW finds a fast algorithm for each transform shape by measuring ("planning"),
which takes about a second at 2048 x 2048. The result, the *wisdom*, is saved to
``wisdom.bin`` in the cache directory (``$HOLOVIEW_CACHE_DIR``, else
``$XDG_CACHE_HOME/holoview``, else ``~/.cache/holoview``) and loaded on first use,
so that a restarted program plans the same shapes in milliseconds. This module is
the only place in :mod:`holoview.processing` that touches a file; a cache that
cannot be read or written only logs a warning.

Plans hold their own aligned buffers and must not run in two threads at once, so
:func:`rfft2_plan` and :func:`ifft2_plan` keep one plan per shape, thread count
*and calling thread*: each thread gets its own, and a caller using one thread at
a time never shares a buffer. :func:`rfft_rows_plan` and :func:`column_fft_plan` are
the two passes of a real 2-D FFT apart, for a caller that needs the spectrum in some
columns only (:mod:`holoview.processing.fourier.half_spectrum`).
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pyfftw

logger = logging.getLogger(__name__)

#: Planner effort used when wisdom does not already cover a shape (a test suite may
#: set ``"FFTW_ESTIMATE"``: plans in microseconds, transforms a little slower).
PLANNER_EFFORT = "FFTW_MEASURE"

#: FFTW threads used when a caller gives none. One: a transform split over threads waits
#: for its slowest thread, and on a machine whose cores are busy (the camera, the recorder,
#: the GUI, other programs) that wait dominates. Measured with ``benchmarks/bench_threads.py``
#: (1024 x 1024, 4 peaks, 2 cores): alone, one thread 10.0 ms a frame median (11.7 worst),
#: two 8.4 ms (30 worst); beside two busy processes, one thread 14.1 ms (p90 26, worst 32),
#: two 20.6 ms (p90 91, worst 132). The issue that asked for this saw 8 ms become 157 ms.
#: ``holoview process`` and the live engine use one for the same reason; a caller that owns
#: the machine may ask for more (``threads=usable_cpus()``).
DEFAULT_THREADS = 1

#: Runs of columns given to :func:`column_fft_plan` start at a multiple of this many
#: columns: 128 bytes of complex64, so every run is aligned as the plan's was.
COLUMN_ALIGN = 16

#: How many plans the per-process cache keeps before dropping the least recently used.
MAX_CACHED_PLANS = 48

_WISDOM_FILE = "wisdom.bin"
_lock = threading.Lock()
_plans: OrderedDict[tuple[object, ...], pyfftw.FFTW] = OrderedDict()
#: The wisdom file imported so far (None: not yet), so each file is read once; and the
#: wisdom adopted from another process (:func:`adopt_wisdom`), if any.
_loaded: dict[str, object] = {"wisdom": None, "adopted": None}


def cache_dir() -> Path:
    """Return the directory holding holoview's caches (it may not exist yet)."""
    explicit = os.environ.get("HOLOVIEW_CACHE_DIR")
    if explicit:
        return Path(explicit)
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "holoview"


def wisdom_path() -> Path:
    """Return the path of the FFTW wisdom file."""
    return cache_dir() / _WISDOM_FILE


def _encode(wisdom: tuple[bytes, ...]) -> bytes:
    parts = [len(wisdom).to_bytes(4, "little")]
    for item in wisdom:
        parts += [len(item).to_bytes(8, "little"), item]
    return b"".join(parts)


def _decode(blob: bytes) -> tuple[bytes, ...]:
    count = int.from_bytes(blob[:4], "little")
    items, pos = [], 4
    for _ in range(count):
        size = int.from_bytes(blob[pos : pos + 8], "little")
        pos += 8
        items.append(blob[pos : pos + size])
        pos += size
    if pos != len(blob) or count > 8:
        raise ValueError("wisdom file is malformed")
    return tuple(items)


def load_wisdom() -> bool:
    """Import the wisdom file of the current cache directory, once per directory.

    Returns
    -------
    bool
        True when wisdom was imported by this call.
    """
    path = wisdom_path()
    if _loaded["wisdom"] == path:
        return False
    _loaded["wisdom"] = path
    try:
        blob = path.read_bytes()
    except FileNotFoundError:
        return False
    except OSError as exc:
        logger.warning("cannot read FFT wisdom %s: %s", path, exc)
        return False
    try:
        pyfftw.import_wisdom(_decode(blob))
    except (ValueError, TypeError) as exc:
        logger.warning("ignoring unusable FFT wisdom %s: %s", path, exc)
        return False
    logger.debug("FFT wisdom loaded from %s", path)
    return True


def save_wisdom() -> bool:
    """Write the wisdom FFTW has gathered so far; a failure only logs a warning.

    Returns
    -------
    bool
        True when the file was written.
    """
    path = wisdom_path()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
        tmp.write_bytes(_encode(pyfftw.export_wisdom()))
        tmp.replace(path)
    except OSError as exc:
        logger.warning("cannot write FFT wisdom to %s: %s", path, exc)
        return False
    return True


#: Plan kinds: (input dtype, output dtype, axes, direction); ``shape`` is the input's.
_KINDS = {
    "rfft2": ("float32", "complex64", (0, 1), "FFTW_FORWARD"),
    "ifft2": ("complex64", "complex64", (0, 1), "FFTW_BACKWARD"),
    "rfft_rows": ("float32", "complex64", (1,), "FFTW_FORWARD"),
    "fft_columns": ("complex64", "complex64", (0,), "FFTW_FORWARD"),
}


def _build(
    kind: str, shape: tuple[int, ...], threads: int, effort: str
) -> tuple[pyfftw.FFTW, bool]:
    source_dtype, target_dtype, axes, direction = _KINDS[kind]
    if kind == "fft_columns":
        # in place over the first ``width`` columns of a (rows, cols) array: the strides
        # and alignment of a run of columns of a half spectrum
        rows, cols, width = shape
        scratch = pyfftw.empty_aligned((rows, cols), dtype=source_dtype)
        source = target = scratch[:, :width]
    else:
        source = pyfftw.empty_aligned(shape, dtype=source_dtype)
        out_shape = (shape[0], shape[1] // 2 + 1) if kind.startswith("rfft") else shape
        target = pyfftw.empty_aligned(out_shape, dtype=target_dtype)
    common = {"axes": axes, "direction": direction, "threads": threads}
    try:
        plan = pyfftw.FFTW(source, target, flags=("FFTW_WISDOM_ONLY",), **common)
        return plan, False
    except RuntimeError:
        plan = pyfftw.FFTW(source, target, flags=(effort,), **common)
        return plan, True


def _plan(kind: str, shape: tuple[int, ...], threads: int, effort: str) -> pyfftw.FFTW:
    key = (kind, shape, threads, effort, threading.get_ident())
    with _lock:
        plan = _plans.get(key)
        if plan is not None:
            _plans.move_to_end(key)
            return plan
        load_wisdom()
        started = time.perf_counter()
        plan, planned = _build(kind, shape, threads, effort)
        if planned:
            logger.info(
                "planned %s %s (threads=%d) in %.3f s",
                kind,
                shape,
                threads,
                time.perf_counter() - started,
            )
            save_wisdom()
        _plans[key] = plan
        while len(_plans) > MAX_CACHED_PLANS:
            _plans.popitem(last=False)
        return plan


def rfft2_plan(
    shape: tuple[int, int], *, threads: int = 1, effort: str | None = None
) -> pyfftw.FFTW:
    """Return the calling thread's plan of a float32 -> complex64 2-D real FFT.

    Fill ``plan.input_array`` (shape ``shape``) and call ``plan()``; the result
    (shape ``(rows, cols // 2 + 1)``, unnormalised, numpy's sign) is
    ``plan.output_array``, overwritten by the next call.

    Parameters
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)`` in pixels.
    threads : int
        FFTW threads used inside the transform.
    effort : str, optional
        FFTW planner flag used when the wisdom does not cover this transform; by
        default :data:`PLANNER_EFFORT`.
    """
    return _plan("rfft2", (int(shape[0]), int(shape[1])), int(threads), effort or PLANNER_EFFORT)


def ifft2_plan(
    shape: tuple[int, int], *, threads: int = 1, effort: str | None = None
) -> pyfftw.FFTW:
    """Return the calling thread's plan of a complex64 2-D inverse FFT.

    Fill ``plan.input_array`` and call ``plan()`` (normalised by 1 / size) or
    ``plan.execute()`` (unnormalised, one pass less); the result is ``plan.output_array``.
    """
    return _plan("ifft2", (int(shape[0]), int(shape[1])), int(threads), effort or PLANNER_EFFORT)


def rfft_rows_plan(
    shape: tuple[int, int], *, threads: int = 1, effort: str | None = None
) -> pyfftw.FFTW:
    """Return the calling thread's plan of the first pass of a 2-D real FFT: each row's.

    Fill ``plan.input_array`` (float32, shape ``shape``), point the output where it
    should go (``plan.update_arrays(plan.input_array, out)``, ``out`` complex64 of shape
    ``(rows, cols // 2 + 1)``, C-ordered rows aligned as :func:`pyfftw.empty_aligned`
    aligns) and call ``plan.execute()``: ``out`` holds the real FFT of every row. An FFT
    along the columns (:func:`column_fft_plan`) of the columns one needs completes the
    2-D half spectrum there, with numpy's sign, unnormalised.
    """
    return _plan(
        "rfft_rows", (int(shape[0]), int(shape[1])), int(threads), effort or PLANNER_EFFORT
    )


def column_fft_plan(
    shape: tuple[int, int], width: int, *, threads: int = 1, effort: str | None = None
) -> pyfftw.FFTW:
    """Return the calling thread's plan of an in-place forward FFT along a run of columns.

    The plan transforms ``width`` consecutive columns of a C-ordered complex64 array of
    shape ``shape`` (rows, cols), each along its rows. Point it at the run with
    ``plan.update_arrays(run, run)`` (``run = array[:, start:start + width]``, the
    array aligned as :func:`pyfftw.empty_aligned` aligns it and ``start`` a multiple
    of :data:`COLUMN_ALIGN`), then call ``plan.execute()``.
    """
    key = (int(shape[0]), int(shape[1]), int(width))
    return _plan("fft_columns", key, int(threads), effort or PLANNER_EFFORT)


def usable_cpus() -> int:
    """Return the CPUs this process may run on (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def current_wisdom() -> tuple[bytes, ...]:
    """The wisdom this process plans from now (FFTW's, exported): to hand to another process."""
    with _lock:
        load_wisdom()
        return tuple(pyfftw.export_wisdom())


def adopt_wisdom(wisdom: tuple[bytes, ...]) -> None:
    """Plan from ``wisdom`` (another process's :func:`current_wisdom`) alone from now on.

    Its plans are then the other process's, transform for transform, and so are the
    numbers they give: a worker's maps equal the parent's to the last bit. The wisdom
    file is not read any more in this process, and the plans cached are dropped; a
    second call with the same wisdom does nothing.
    """
    with _lock:
        if _loaded.get("adopted") == wisdom:
            return
        pyfftw.forget_wisdom()
        pyfftw.import_wisdom(wisdom)
        _loaded["adopted"] = wisdom
        _loaded["wisdom"] = wisdom_path()  # the file's wisdom is not mixed in
        _plans.clear()


def clear_plans() -> None:
    """Forget every cached plan (the wisdom stays loaded)."""
    with _lock:
        _plans.clear()


def forget_loaded_wisdom() -> None:
    """Make the next plan re-read the wisdom file (for tests that change the cache directory)."""
    with _lock:
        _loaded["wisdom"] = None


def fft_friendly(n: int) -> int:
    """Return the smallest even integer >= ``n`` whose prime factors are 2, 3 and 5 only."""
    m = max(2, int(np.ceil(n)))
    while True:
        if m % 2 == 0:
            k = m
            for p in (2, 3, 5):
                while k % p == 0:
                    k //= p
            if k == 1:
                return m
        m += 1
