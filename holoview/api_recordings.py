"""holoview.api's recordings: frames read lazily as a dask array, times, setup, experiment.

:func:`open_recording` (importable from :mod:`holoview.api`, as :class:`Recording`)
opens any input ``holoview process`` reads (:mod:`holoview.headless.inputs`): a holoview
recording, a TIFF stack, a folder of images, a video or a numpy array. No Qt here.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from types import TracebackType
from typing import Any, Self

import numpy as np
import xarray as xr

from holoview.engine.experiment import Experiment
from holoview.errors import InputError
from holoview.headless.inputs import InputFile

logger = logging.getLogger(__name__)

__all__ = ["Recording", "open_recording"]


class _Frames:
    """A frame file as an array dask can read: ``frames[i:j]`` reads frames i to j-1.

    The file is opened on the first read in each process (pickled, it reopens by path).
    """

    def __init__(self, path: Path, shape: tuple[int, int, int], dtype: np.dtype) -> None:
        self.path = path
        self.shape = shape
        self.dtype = dtype
        self.ndim = 3
        self._file: InputFile | None = None

    def __reduce__(self) -> tuple[Any, ...]:
        return (_Frames, (self.path, self.shape, self.dtype))

    def __getitem__(self, key: Any) -> np.ndarray:
        key = key if isinstance(key, tuple) else (key,)
        indices = range(self.shape[0])[key[0]]
        if self._file is None:
            self._file = InputFile(self.path)
        if isinstance(indices, int):
            return self._file.read(indices)[key[1:]]
        stack = np.empty((len(indices), *self.shape[1:]), self.dtype)
        for k, index in enumerate(indices):
            stack[k] = self._file.read(index)
        return stack[(slice(None), *key[1:])]

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


class Recording:
    """A recording opened for reading: frames (lazy), times, setup and experiment.

    Made by :func:`open_recording`; use it as a context manager, or :meth:`close` it.

    Attributes
    ----------
    path : Path
    kind : str
        ``"hdf5"``, ``"tiff"``, ``"folder"``, ``"numpy"`` or ``"video"``.
    frames : dask.array.Array
        ``(frames, rows, cols)`` in the file's dtype (raw camera counts), one frame per
        chunk; nothing is read until computed (``frames[10].compute()``,
        ``frames.mean(axis=0).compute()``).
    times : ndarray or None
        Each frame's time, s, from 0 at the first: the camera's clock, else the host's
        arrival times, or ``index / fps``; None when the file has no times and no
        ``fps`` was given.
    times_note : str
        Which clock timed the frames and why (the rule of ``holoview process``'s notes),
        or why there are no times.
    setup : dict
        A holoview recording's optical setup (``wavelength_m``, ``pixel_pitch_m``,
        ``n1``, ``n2``, ...); empty for other files.
    experiment : Experiment or None
        The experiment in force at the first frame (labelled peaks, optics, window);
        None when the file carries none.
    experiments : list of (int, Experiment)
        Every experiment stored, with the frame it holds from.
    """

    def __init__(self, path: str | Path, fps: float | None = None) -> None:
        import dask.array as da
        from dask.base import tokenize

        self._input = InputFile(path)
        source = self._input
        self.path = source.path
        self.kind = source.kind
        self.setup = dict(source.setup)
        n = len(source)
        shape = (n, *source.frame_shape)
        self._frames = _Frames(self.path, shape, source.dtype)
        stat = self.path.stat()
        self.frames = da.from_array(
            self._frames,
            chunks=(1, *source.frame_shape),
            lock=True,
            name="holoview-frames-" + tokenize(str(self.path), stat.st_mtime_ns, shape),
            meta=np.empty((0, 0, 0), source.dtype),
        )
        #: How the times were found (the clock rule's note), or why there are none.
        self.times_note = ""
        self.times: np.ndarray | None = None
        if n:
            try:
                found = source.times(range(n), fps)
            except InputError as exc:
                logger.info("%s", exc)
                self.times_note = str(exc)
            else:
                self.times, self.times_note = found.times, found.note
                if found.warning:
                    logger.warning("%s", found.note)
        self.experiments: list[tuple[int, Experiment]] = []
        for start, text in source.experiments:
            where = f"{self.path} experiment (from frame {start})"
            try:
                self.experiments.append((start, Experiment.from_json(text, where)))
            except InputError as exc:
                logger.warning("%s; ignored", exc)
        held = [e for start, e in self.experiments if start <= 0]
        self.experiment = held[-1] if held else None

    def __len__(self) -> int:
        return int(self.frames.shape[0])

    def to_xarray(self) -> xr.DataArray:
        """The frames as a DataArray ``(time, y, x)``: s, and m with a pixel pitch.

        Without times the ``time`` coordinate is absent (the frame index stays);
        without a pixel pitch, ``y`` and ``x`` are in pixels (``units`` ``1``).
        """
        n, rows, cols = self.frames.shape
        pitch = self.setup.get("pixel_pitch_m")
        given = math.nan if pitch is None else float(pitch)
        known = math.isfinite(given) and given > 0
        scale = given if known else 1.0
        axis_units = "m" if known else "1"
        coords: dict[str, Any] = {
            "frame": ("time", np.arange(n), {"units": "1"}),
            "y": ("y", np.arange(rows) * scale, {"units": axis_units}),
            "x": ("x", np.arange(cols) * scale, {"units": axis_units}),
        }
        if self.times is not None:
            coords["time"] = ("time", self.times, {"units": "s"})
        return xr.DataArray(
            self.frames,
            dims=("time", "y", "x"),
            coords=coords,
            name="intensity",
            attrs={"units": "count", "long_name": "camera value (raw counts)"},
        )

    def close(self) -> None:
        """Release the file (the frames cannot be read after)."""
        self._frames.close()
        self._input.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def open_recording(path: str | Path, *, fps: float | None = None) -> Recording:
    """Open a recording for reading: any input ``holoview process`` reads.

    Parameters
    ----------
    path : str or Path
        A holoview recording (``.h5``), a TIFF stack, a folder of TIFF/PNG images, a
        video (``.avi``, ``.mkv``, ``.mp4``, ``.mov``) or a numpy array (``.npy``,
        ``.npz``).
    fps : float, optional
        Frame rate, frames/s: the times are then ``index / fps`` (files without times
        need it for :attr:`Recording.times`).

    Returns
    -------
    Recording

    Raises
    ------
    InputError
        A missing, unreadable or unknown file (one line naming it).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> folder = Path(tempfile.mkdtemp())
    >>> np.save(folder / "stack.npy", np.arange(3 * 4 * 5, dtype=np.uint16).reshape(3, 4, 5))
    >>> with open_recording(folder / "stack.npy", fps=10) as rec:
    ...     print(rec.kind, rec.frames.shape, rec.times, int(rec.frames[2].sum().compute()))
    numpy (3, 4, 5) [0.  0.1 0.2] 990
    """
    return Recording(path, fps)
