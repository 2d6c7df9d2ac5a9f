"""The height maps of a ``results.h5`` for the wave analyses, read a block of frames at a time.

The maps are ``/maps/<label>``, as the maps step writes them (``holoview process
--maps``; results.h5 2.x, layout in :mod:`holoview.headless.results.results_layout`),
read through h5py by dataset name; a 1.0 file (``unit``, ``/trends/time_s``) reads the
same. Each needs:

- heights (``units`` ``m``): a peak without alpha keeps phases and is refused;
- its pixel size (attribute ``pixel_size_m``, (dy, dx) in m), or one given;
- the frame times (the maps' ``time`` dimension scale, else ``/trends/time_s``), or a
  frame rate given (then the frames are taken as evenly spaced).

Positions (a centre) are from the first map pixel's centre, x along the columns and y
down the rows: the maps' own ``x`` and ``y`` coordinates, which start at 0.

The wavenumber cut-off of the maps is the demodulation window's radius
(``radius_cpp``, cycles per frame pixel; the fused map's smallest):
``k_cut = 2 pi radius_cpp / pitch`` with the frame's pitch ``pixel_size_m / pixel_step_px``;
without those attributes, the map
grid's Nyquist wavenumber. Maps of the relative reference (height steps between
frames) are summed over time into heights (a pixel untrusted once stays NaN after).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, Self

import h5py
import numpy as np

from holoview.acquire.durability import open_hdf5_for_reading
from holoview.errors import InputError
from holoview.processing.waves.clock import FrameClock, frame_clock

logger = logging.getLogger(__name__)

__all__ = ["CHECKPOINT", "HEIGHT_UNITS", "WIDER", "WaveMaps", "open_wave_maps", "results_path"]

#: Frames between the kept running sums of relative maps.
CHECKPOINT = 256

#: The units of maps of heights (none said: heights, as results.h5 1.0 wrote them).
HEIGHT_UNITS = (None, "m")

#: A map whose cut-off is more than this many times another's is named where the other's
#: band is too short for the dispersion fit.
WIDER = 1.25


@dataclass
class WaveMaps:
    """One label's maps, their pixel size, times and cut-off (module docstring).

    Attributes
    ----------
    path : Path
    label : str
    shape : (int, int)
        Map shape.
    pixel_size : (float, float)
        ``(dy, dx)``, m.
    clock : FrameClock
        The times of the frames analysed (from the first of them, s).
    first, stop : int
        Frame indices analysed in the file, ``[first, stop)``.
    time_origin : float
        The file's time of frame ``first``, s (times here start at 0 there).
    k_cut : float
        rad/m.
    k_cut_source : str
        Where ``k_cut`` comes from.
    wider : (str, float) or None
        Another map of the file whose cut-off (rad/m) is more than :data:`WIDER` times
        this one's, the widest (the fused map's is its narrowest peak's: a single peak
        may reach further), for a message where this map's band is too short.
    reference : str
        The maps' reference mode.
    """

    path: Path
    label: str
    shape: tuple[int, int]
    pixel_size: tuple[float, float]
    clock: FrameClock
    first: int
    stop: int
    time_origin: float
    k_cut: float
    k_cut_source: str
    wider: tuple[str, float] | None
    reference: str
    _file: h5py.File
    _dataset: h5py.Dataset
    _sums: dict[int, np.ndarray] = field(default_factory=dict)

    @property
    def frames(self) -> int:
        """Frames analysed."""
        return self.stop - self.first

    @property
    def relative(self) -> bool:
        """True when the file holds height steps between frames."""
        return self.reference == "relative"

    def blocks(self, size: int = 64) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Yield ``(times (n,), maps (n, rows, cols) float32 m)`` in order, ``size`` at a time."""
        for a in range(0, self.frames, size):
            b = min(a + size, self.frames)
            yield self.clock.times[a:b], self.read(a, b)

    def read(self, start: int, stop: int) -> np.ndarray:
        """Return maps ``[start, stop)`` of those analysed, float32, m.

        Height steps (relative maps) are summed from the file's first frame; the sums
        at every :data:`CHECKPOINT` frames are kept (a float32 map each), so reading in
        order, or back by less than that, re-reads little.
        """
        a, b = self.first + start, self.first + stop
        if not self.relative:
            return np.asarray(self._dataset[a:b], dtype=np.float32)
        base = (a // CHECKPOINT) * CHECKPOINT
        while base not in self._sums:
            base -= CHECKPOINT
        total = self._sums[base].astype(np.float64)
        out = np.empty((b - a, *self.shape), np.float32)
        for lo in range(base, b, CHECKPOINT):
            hi = min(lo + CHECKPOINT, b)
            summed = np.cumsum(self._dataset[lo:hi], axis=0, dtype=np.float64) + total
            total = summed[-1]
            if hi % CHECKPOINT == 0 and hi not in self._sums:
                self._sums[hi] = total.astype(np.float32)
            keep_lo, keep_hi = max(lo, a), hi
            if keep_lo < keep_hi:
                out[keep_lo - a : keep_hi - a] = summed[keep_lo - lo : keep_hi - lo]
        return out

    def close(self) -> None:
        """Close the file."""
        self._file.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _times(file: h5py.File, dataset: h5py.Dataset) -> np.ndarray | None:
    """The maps' ``time`` dimension scale (2.x), else ``/trends/time_s`` (1.0), s."""
    for scale in dataset.dims[0].values() if len(dataset.dims) else ():
        name = scale.name.rsplit("/", 1)[-1]
        if name in ("time", "time_s"):
            return np.asarray(scale[:], dtype=np.float64)
    if "trends/time_s" in file:
        return np.asarray(file["trends/time_s"][:], dtype=np.float64)
    return None


def _attr(attrs: Any, name: str) -> Any:
    value = attrs.get(name)
    return value.decode() if isinstance(value, bytes) else value


def results_path(path: str | Path) -> Path:
    """``path``, or the ``results.h5`` in it when it is a run's output folder."""
    given = Path(path)
    return given / "results.h5" if given.is_dir() else given


def open_wave_maps(
    path: str | Path,
    label: str = "fused",
    *,
    time_range: tuple[float | None, float | None] | None = None,
    pixel_size: float | None = None,
    fps: float | None = None,
) -> WaveMaps:
    """Open the maps of ``label`` in a ``results.h5`` (module docstring).

    Parameters
    ----------
    path : str or Path
        A ``results.h5`` written by ``holoview process --maps`` (or its folder).
    label : str
        ``fused`` or a peak's label.
    time_range : (float or None, float or None), optional
        Analyse the frames with ``t0 <= t < t1`` (s, the file's times).
    pixel_size : float, optional
        Pixel size on the surface, m, for maps that do not carry one (or to replace it).
    fps : float, optional
        Frame rate, frames/s, for a file without frame times (or to replace them).

    Raises
    ------
    InputError
        Not an HDF5 file, no maps, no such label, phase maps, no pixel size, no
        times, or fewer than two frames in the time range.
    """
    file_path = results_path(path)
    if not file_path.is_file():
        raise InputError(f"{file_path}: no such file")
    file = open_hdf5_for_reading(file_path)  # a truncated copy said as such
    try:
        return _open(file, file_path, label, time_range, pixel_size=pixel_size, fps=fps)
    except BaseException:
        file.close()
        raise


def _open(
    file: h5py.File,
    path: Path,
    label: str,
    time_range: tuple[float | None, float | None] | None,
    *,
    pixel_size: float | None,
    fps: float | None,
) -> WaveMaps:
    if "maps" not in file or not isinstance(file["maps"], h5py.Group):
        raise InputError(f"{path} holds no maps (write them with holoview process --maps)")
    # the (frames, rows, cols) stacks; the coordinates (time, frame, y, x) are 1-D
    labels = sorted(
        k for k, v in file["maps"].items() if isinstance(v, h5py.Dataset) and v.ndim == 3
    )
    if label not in labels:
        raise InputError(f"{path} has no maps of {label!r}; it has {', '.join(labels) or 'none'}")
    dataset = file["maps"][label]
    if dataset.ndim != 3:
        raise InputError(f"{path}: maps/{label} is not a (frames, rows, cols) stack")
    attrs = dataset.attrs
    unit = _unit(attrs)
    if unit not in HEIGHT_UNITS:
        raise InputError(
            f"{path}: maps/{label} holds {_attr(attrs, 'quantity') or unit} ({unit}), not "
            "heights (m): its peak has no alpha"
        )
    if pixel_size is not None:
        size = (float(pixel_size), float(pixel_size))
    elif "pixel_size_m" in attrs:
        values = np.atleast_1d(np.asarray(attrs["pixel_size_m"], dtype=np.float64))
        size = (float(values[0]), float(values[-1]))
    else:
        raise InputError(
            f"{path}: maps/{label} carry no pixel size (pixel_size_m); give it with --pixel-size-um"
        )
    if not all(math.isfinite(v) and v > 0 for v in size):
        raise InputError(f"{path}: maps/{label} have a bad pixel size {size} m")
    n_frames = int(dataset.shape[0])
    found = _times(file, dataset)
    if found is not None and fps is not None:
        gaps = frame_clock(found).gaps if found.size > 1 else 0
        raise InputError(
            f"{path}: the maps carry their own frame times (maps/time, {gaps} "
            f"gap{'' if gaps == 1 else 's'}): --fps is for maps without them (it would space "
            "them evenly, closing any gap); leave it out"
        )
    if fps is not None:
        times = np.arange(n_frames) / float(fps)
    elif found is None:
        raise InputError(
            f"{path} carries no frame times (maps/time); give the frame rate with --fps"
        )
    else:
        times = found
    if times.size != n_frames:
        raise InputError(f"{path}: {times.size} frame times for {n_frames} maps of {label}")
    first, stop = 0, n_frames
    if time_range is not None:
        t0, t1 = time_range
        if t0 is not None:
            first = int(np.searchsorted(times, t0, side="left"))
        if t1 is not None:
            stop = int(np.searchsorted(times, t1, side="left"))
    if stop - first < 2:
        raise InputError(
            f"{path}: {max(stop - first, 0)} frames of {label} in the time range "
            f"{time_range}; the maps span {times[0]:.4g} to {times[-1]:.4g} s"
        )
    clock = frame_clock(times[first:stop] - times[first])
    k_cut, source = _k_cut(attrs, size)
    others = {
        name: _k_cut(file["maps"][name].attrs, size)[0]
        for name in labels
        if name != label
        and file["maps"][name].ndim == 3
        and _unit(file["maps"][name].attrs) in HEIGHT_UNITS
    }
    widest = max(others, key=lambda name: others[name], default=None)
    wider = None
    if widest is not None and others[widest] > WIDER * k_cut:
        wider = (widest, others[widest])
    reference = _attr(attrs, "reference") or "absolute"
    sums = {0: np.zeros((int(dataset.shape[1]), int(dataset.shape[2])), np.float32)}
    if reference == "relative":
        logger.info("maps/%s hold height steps between frames: summed over time", label)
    return WaveMaps(
        path=path,
        label=label,
        shape=(int(dataset.shape[1]), int(dataset.shape[2])),
        pixel_size=size,
        clock=clock,
        first=first,
        stop=stop,
        time_origin=float(times[first]),
        k_cut=k_cut,
        k_cut_source=source,
        wider=wider,
        reference=str(reference),
        _file=file,
        _dataset=dataset,
        _sums=sums,
    )


def _unit(attrs: h5py.AttributeManager) -> str | None:
    """A map's unit: ``units`` in results.h5 2.x, ``unit`` in 1.0."""
    unit: str | None = _attr(attrs, "units") or _attr(attrs, "unit")
    return unit


def _k_cut(attrs: h5py.AttributeManager, size: tuple[float, float]) -> tuple[float, str]:
    """A map's wavenumber cut-off (rad/m) and where it comes from (module docstring)."""
    step = np.atleast_1d(np.asarray(attrs.get("pixel_step_px", [np.nan]), dtype=np.float64))
    radius = _cut_off_radius(attrs.get("radius_cpp"))
    nyquist = min(math.pi / size[0], math.pi / size[1])
    if radius is not None and np.all(np.isfinite(step)):
        pitch = size[1] / float(step[-1])
        return min(2.0 * math.pi * radius / pitch, nyquist), "the demodulation window (radius_cpp)"
    return nyquist, "the map grid's Nyquist wavenumber"


def _cut_off_radius(value: object) -> float | None:
    """The window radius that bounds a map's waves, cycles/pixel; None where unknown.

    A peak's map carries its own radius; the fused map one per peak it fuses, whose
    smallest bounds the band every peak passes (beyond it only some contribute).
    """
    if value is None:
        return None
    radii = np.atleast_1d(np.asarray(value, dtype=np.float64))
    radii = radii[np.isfinite(radii) & (radii > 0)]
    return float(radii.min()) if radii.size else None
