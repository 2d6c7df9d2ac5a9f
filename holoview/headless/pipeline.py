"""The streaming loop of a headless run: frames through one Demodulator, series kept.

Per frame, each selected peak gives its complex carrier value (whose phase is the
spatially averaged phase, paper section 4.2) and its phase noise; they are kept for
the whole run (a few numbers per frame and peak). Maps are not kept: with a
:class:`MapSink` each frame's maps go to it at once, so memory stays bounded by
the few frames the :class:`~holoview.headless.reader.FrameReader` reads ahead.

Maps are at the demodulator's box resolution (pixel ``(p, q)`` at frame position
``(p rows / by, q cols / bx)``), float32, NaN where the pixel is not trusted (its
amplitude is below a quarter of the peak's). With known prefactors they are delta-h
in metres; in auto mode (prefactors from the PCA after the run) they are phases in
radians, converted by the sink afterwards. The peaks' displacements against the first
peak are measured over the run (:mod:`holoview.processing.coregister`, on up to
:data:`COREGISTER_FRAMES` frames spread over it), so fused maps, made after the run
(:func:`fuse_frame`), are co-registered.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from holoview.errors import InputError
from holoview.headless.inputs import InputFile, Optics
from holoview.headless.reader import DEFAULT_DEPTH, FrameReader
from holoview.headless.selection import Selection
from holoview.processing.coregister import (
    MIN_MAP_SIDE,
    Displacement,
    DisplacementEstimator,
    fuse_coregistered,
)
from holoview.processing.demodulate import DemodResult, Demodulator

logger = logging.getLogger(__name__)

#: Per-frame peak flags counted over the run.
COUNTED_PEAK_FLAGS = ("phase_step", "low_amplitude", "overlap")

#: Frame-level flags counted over the run.
COUNTED_FRAME_FLAGS = ("nonfinite", "no_signal", "saturated")

#: Frames, spread over a run, whose maps measure the peaks' displacements.
COREGISTER_FRAMES = 200


@dataclass(frozen=True)
class ProcessSettings:
    """How a run demodulates (names as the ``holoview process`` options).

    Attributes
    ----------
    reference : {"relative", "absolute", "synthetic"}
        Reference mode of the maps (the mean-phase series is always relative to the
        first frame).
    window : {"raised-cosine", "top-hat", "tukey"}
    radius : float or None
        Window radius, cycles/pixel (None: automatic from the carriers).
    unwrap : {"auto", "always", "never"}
        Spatial unwrapping of the maps.
    maps : bool
        Write the delta-h maps.
    area_m2 : float or None
        Basin area, m^2, for volume rates.
    threads : int
        FFTW threads per frame. One by default: the reader thread needs a core too,
        and on a loaded two-core machine a two-thread FFT waiting for a busy core
        took 450 ms instead of 10 ms per 1024 x 1024 frame.
    read_ahead : int
        Frames the reader thread reads ahead.
    """

    reference: str = "relative"
    window: str = "raised-cosine"
    radius: float | None = None
    unwrap: str = "auto"
    maps: bool = False
    area_m2: float | None = None
    threads: int = 1
    read_ahead: int = DEFAULT_DEPTH


class MapSink(Protocol):
    """Where each frame's maps go (``results.h5`` in a run)."""

    def write_map(self, position: int, peak: int, values: np.ndarray) -> None:
        """Store peak ``peak``'s map of the ``position``-th processed frame."""


@dataclass
class RunData:
    """What the loop kept: per-frame series of every peak, and the last frame's maps.

    Attributes
    ----------
    frames : ndarray of int64, shape (N,)
        Input frame indices.
    times : ndarray of float64, shape (N,)
        Frame times, s, from 0.
    values : ndarray of complex128, shape (N, M)
        Carrier value per frame and peak (counts), demodulated on the selected twin;
        NaN for a frame that could not be demodulated.
    noise_rad : ndarray of float64, shape (N, M)
        Per-pixel phase noise of each map, rad (0 for a reference frame).
    phase_steps : ndarray of bool, shape (N, M)
        Whether the peak's mean phase stepped past 0.8 pi at that frame (its map is
        then left out of the fused map).
    frame_flags : dict of str to int
        Frames flagged ``nonfinite``, ``no_signal``, ``saturated``.
    peak_flags : list of dict of str to int
        Per peak, frames flagged ``phase_step``, ``low_amplitude``, ``overlap``.
    box_shape : tuple of int
        Shape of every map, ``(by, bx)``.
    radius : float
        Window radius used, cycles/pixel.
    last_maps : list of (ndarray or None)
        Each peak's map of the last demodulated frame (m, or rad in auto mode).
    last_frame : int
        Input index of the frame the last maps come from.
    displacements : list of Displacement
        Each peak's measured shift against the first peak, in map pixels (empty
        with one peak, or maps smaller than
        :data:`~holoview.processing.coregister.MIN_MAP_SIDE`).
    maps_in_metres : bool
        Whether the maps are delta-h in m (every peak had alpha), else phases in rad.
    interrupted : bool
        The run was interrupted (Ctrl-C): the series hold the frames done before.
    read_seconds, demod_seconds, write_seconds, wall_seconds : float
        Time reading the input (on the reader thread), demodulating, writing maps,
        and in all, s.
    """

    frames: np.ndarray
    times: np.ndarray
    values: np.ndarray
    noise_rad: np.ndarray
    phase_steps: np.ndarray
    frame_flags: dict[str, int]
    peak_flags: list[dict[str, int]]
    box_shape: tuple[int, int]
    radius: float
    last_maps: list[np.ndarray | None] = field(default_factory=list)
    last_frame: int = -1
    displacements: list[Displacement] = field(default_factory=list)
    maps_in_metres: bool = False
    interrupted: bool = False
    read_seconds: float = 0.0
    demod_seconds: float = 0.0
    write_seconds: float = 0.0
    wall_seconds: float = 0.0


def fuse_frame(
    data: RunData,
    position: int,
    maps: Sequence[np.ndarray | None],
    scales: Sequence[float | None],
) -> np.ndarray | None:
    """Return the fused delta-h map (m) of the ``position``-th frame, co-registered.

    Parameters
    ----------
    data : RunData
        The run (noise, phase steps and displacements).
    position : int
        The frame's position in the run.
    maps : sequence of (ndarray or None)
        Each peak's delta-h map of that frame, m (None: not in metres).
    scales : sequence of (float or None)
        Metres per radian of each peak to fuse (None: left out).

    Returns
    -------
    ndarray of float32 or None
        None with fewer than two peaks to fuse. Peaks whose mean phase stepped at this
        frame are left out, unless every one did.
    """
    chosen = [j for j, s in enumerate(scales) if s is not None and maps[j] is not None]
    steady = [j for j in chosen if not data.phase_steps[position, j]]
    chosen = steady or chosen
    if len(chosen) < 2:
        return None
    shifts = None
    if data.displacements:
        shifts = [data.displacements[j].shift for j in chosen]
    return fuse_coregistered(
        [maps[j] for j in chosen],  # type: ignore[misc]
        [data.noise_rad[position, j] * abs(scales[j]) for j in chosen],  # type: ignore[arg-type]
        shifts,
    )


def _trusted(result_map: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return np.where(mask, result_map, np.float32(np.nan)).astype(np.float32, copy=False)


def frame_maps(result: DemodResult) -> list[np.ndarray]:
    """Return one frame's maps, NaN where untrusted: delta-h in m with alpha, else phase in rad."""
    return [_trusted(r.delta_h if r.delta_h is not None else r.phase, r.mask) for r in result.peaks]


def make_demodulator(
    shape: tuple[int, int],
    selection: Selection,
    optics: Optics,
    settings: ProcessSettings,
    saturation: float | None = None,
) -> Demodulator:
    """Return the demodulator of a run (InputError for a radius or mode that cannot work)."""
    return Demodulator(
        shape,
        selection.peaks,
        window=settings.window,
        radius=settings.radius,
        reference=settings.reference,
        unwrap=settings.unwrap,
        wavelength=optics.wavelength_m,
        saturation=saturation,
        threads=settings.threads,
    )


def demodulate_frames(
    source: InputFile,
    frames: range,
    times: np.ndarray,
    demodulator: Demodulator,
    *,
    sink: MapSink | None = None,
    read_ahead: int = DEFAULT_DEPTH,
    progress: Callable[[int], None] | None = None,
) -> RunData:
    """Stream ``frames`` of ``source`` through ``demodulator``; keep the series.

    Parameters
    ----------
    source : InputFile
        The input (read from a ``holoview-reader`` thread during the call).
    frames : range
        Input frame indices to process.
    times : ndarray, shape (len(frames),)
        Their times, s.
    demodulator : Demodulator
        Built for the selected peaks (its reference starts at the first frame).
    sink : MapSink, optional
        Receives every frame's maps (and fused map when every peak has alpha).
    read_ahead : int
        Frames read ahead.
    progress : callable, optional
        Called with the number of frames done, after each frame.

    Returns
    -------
    RunData
        After an interruption (KeyboardInterrupt) with at least one frame done, the
        series of the frames done and ``interrupted`` set; with none done, the
        interruption is raised again.
    """
    n, m = len(frames), len(demodulator.peaks)
    values = np.full((n, m), np.nan + 0j, dtype=np.complex128)
    noise = np.full((n, m), np.nan)
    estimator = None
    if m >= 2 and min(demodulator.box_shape) >= MIN_MAP_SIDE:
        estimator = DisplacementEstimator(demodulator.box_shape, m)
    every = max(1, n // COREGISTER_FRAMES)
    frame_flags = dict.fromkeys(COUNTED_FRAME_FLAGS, 0)
    peak_flags = [dict.fromkeys(COUNTED_PEAK_FLAGS, 0) for _ in range(m)]
    with_alpha = all(p.alpha is not None for p in demodulator.peaks)
    data = RunData(
        frames=np.asarray(frames, dtype=np.int64),
        times=np.asarray(times, dtype=np.float64),
        values=values,
        noise_rad=noise,
        phase_steps=np.zeros((n, m), dtype=bool),
        frame_flags=frame_flags,
        peak_flags=peak_flags,
        box_shape=demodulator.box_shape,
        radius=demodulator.radius,
        last_maps=[None] * m,
        maps_in_metres=with_alpha,
    )
    start = time.perf_counter()
    last: DemodResult | None = None
    done = 0
    reader = FrameReader(source.read, frames, depth=read_ahead)
    try:
        with reader:
            for position, (index, frame) in enumerate(reader):
                t0 = time.perf_counter()
                result = demodulator.process(frame)
                measure = estimator is not None and position % every == 0
                wanted = result.peaks and (measure or sink is not None)
                maps = frame_maps(result) if wanted else []
                if maps and measure:
                    estimator.add(maps)  # type: ignore[union-attr]
                t1 = time.perf_counter()
                data.demod_seconds += t1 - t0
                _record(data, position, result)
                if result.peaks:
                    last, data.last_frame = result, index
                    if sink is not None:
                        for j, values_map in enumerate(maps):
                            sink.write_map(position, j, values_map)
                data.write_seconds += time.perf_counter() - t1
                done = position + 1
                if progress is not None:
                    progress(done)
    except KeyboardInterrupt:
        if done == 0:
            raise
        logger.warning("interrupted after %d of %d frames: results of those", done, n)
        data.interrupted = True
        data.frames, data.times = data.frames[:done], data.times[:done]
        data.values, data.noise_rad = data.values[:done], data.noise_rad[:done]
        data.phase_steps = data.phase_steps[:done]
    if last is not None:
        data.last_maps = list(frame_maps(last))
    if estimator is not None:
        data.displacements = estimator.displacements()
    data.read_seconds = reader.read_seconds
    data.wall_seconds = time.perf_counter() - start
    if not np.any(np.isfinite(data.values)):
        raise InputError("no frame could be demodulated (every frame is NaN or infinite)")
    return data


def _record(data: RunData, position: int, result: DemodResult) -> None:
    for flag in result.flags:
        if flag in data.frame_flags:
            data.frame_flags[flag] += 1
    for j, r in enumerate(result.peaks):
        data.values[position, j] = r.carrier_value
        data.noise_rad[position, j] = r.noise
        data.phase_steps[position, j] = "phase_step" in r.flags
        for flag in r.flags:
            if flag in data.peak_flags[j]:
                data.peak_flags[j][flag] += 1
