"""What a headless run keeps of its frames: :class:`RunData`, and how each frame's maps are counted.

A run passes over its frames to measure the series (every frame's carrier values), to
measure the maps' displacements (frames spread over the run) and, with ``--maps``, to
make every frame's maps (:mod:`holoview.headless.frame_passes`, or on many processes
:mod:`holoview.headless.parallel.stitch`); each pass fills its part of one :class:`RunData`,
and :class:`MapRecord` counts the maps of a pass, frame after frame in order, and
hands them to the :class:`MapSink` (``results.h5``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from holoview.engine.map_step import FrameMaps
from holoview.engine.series import PhaseSeries
from holoview.errors import InputError
from holoview.processing.maps.coregister import Displacement
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.matched import Window

__all__ = [
    "FRAME_FLAG_BITS",
    "MAP_PEAK_FLAGS",
    "MapRecord",
    "MapSink",
    "RunData",
    "check_run",
    "flag_bits",
    "new_run_data",
]

#: Per-frame map flags of a peak counted over the demodulated frames.
MAP_PEAK_FLAGS = ("low_amplitude", "overlap")

#: The carrier probe's frame flags, in the order of their bits in :attr:`RunData.frame_bits`.
FRAME_FLAG_BITS = ("nonfinite", "saturated", "damaged")

#: Bit of a frame damaged in transfer, and of one holding NaN or infinite pixels.
DAMAGED_BIT = 1 << FRAME_FLAG_BITS.index("damaged")
NONFINITE_BIT = 1 << FRAME_FLAG_BITS.index("nonfinite")


def flag_bits(flags: frozenset[str]) -> int:
    """A frame's probe flags as the bits of :data:`FRAME_FLAG_BITS`."""
    return sum(1 << b for b, f in enumerate(FRAME_FLAG_BITS) if f in flags)


class MapSink(Protocol):
    """Where each frame's maps go (``results.h5`` in a run)."""

    def write_maps(
        self, position: int, maps: Sequence[np.ndarray], fused: np.ndarray | None
    ) -> None:
        """Store the ``position``-th processed frame's maps (one per peak) and fused map."""


@dataclass
class RunData:
    """What the passes kept: the per-frame series of every peak, the maps' record.

    Attributes
    ----------
    series : PhaseSeries
        Carrier values, their noise, phase steps and flags of every processed frame
        (:mod:`holoview.engine.series`); ``frames``, ``times``, ``values`` and
        ``phase_steps`` read it.
    frame_bits : ndarray of uint8, shape (N,)
        Each frame's probe flags (:data:`FRAME_FLAG_BITS`).
    map_noise_rad : ndarray of float, shape (N, M)
        Per-pixel phase noise of each map, rad, on the frames demodulated (0 for a
        reference frame, NaN where a frame was not demodulated).
    map_flags : list of dict of str to int
        Per peak, demodulated frames flagged ``low_amplitude`` or ``overlap``.
    no_signal : int
        Demodulated frames with no trusted pixel in any peak.
    demodulated : int
        Frames demodulated into maps (and counted: every frame with ``--maps``, else
        those that measured the displacements and the last).
    box_shape : tuple of int
        Shape of every map, ``(by, bx)``.
    radius : float
        The largest window radius used, cycles/pixel (it sets ``box_shape``).
    windows : tuple of Window
        Each peak's window: radius, shape, the rule that chose it and why.
    last_maps : list of (ndarray or None)
        Each peak's map of the last demodulated frame (m, or rad without alpha).
    last_fused : ndarray or None
        The fused map of that frame, m.
    last_frame : int
        Input index of the frame the last maps come from.
    displacements : list of Displacement
        Each peak's measured shift against the first peak, in map pixels (empty
        with one peak, or maps smaller than
        :data:`~holoview.processing.maps.coregister.MIN_MAP_SIDE`).
    map_units : tuple of str
        Each peak's map unit: ``"m"`` (delta-h, the peak has alpha) or ``"rad"``.
    fused_labels : tuple of str
        The peaks whose maps the fused map takes (:meth:`~holoview.engine.series.JointSetup.fused`).
    interrupted : bool
        The run was interrupted (Ctrl-C): the series hold the frames done before.
    maps_dropped : bool
        An interrupted ``--maps`` run stopped before any frame's maps were made: its
        results hold the series of the frames done and no maps.
    notes : list of str
        What the passes noted for the summary.
    read_seconds, demod_seconds, wall_seconds : float
        Time reading the input (on the reader threads), demodulating, and in all, s
        (reading and demodulating summed over the processes).
    workers : str
        Where the frames were measured (``"1 process"``, ``"4 processes"``,
        ``"Dask at ..."``).
    maps_seconds : float
        Of ``demod_seconds``, the time demodulating maps, s.
    worker_seconds, parent_seconds : float
        A parallel run's time in the workers (summed), and in the parent stitching the
        series, measuring the displacements and writing the maps in order (its
        sequential part), s; 0 for a run in one process.
    """

    series: PhaseSeries
    frame_bits: np.ndarray
    map_noise_rad: np.ndarray
    map_flags: list[dict[str, int]]
    box_shape: tuple[int, int]
    radius: float
    windows: tuple[Window, ...] = ()
    last_maps: list[np.ndarray | None] = field(default_factory=list)
    last_fused: np.ndarray | None = None
    last_frame: int = -1
    displacements: list[Displacement] = field(default_factory=list)
    map_units: tuple[str, ...] = ()
    fused_labels: tuple[str, ...] = ()
    interrupted: bool = False
    maps_dropped: bool = False
    notes: list[str] = field(default_factory=list)
    read_seconds: float = 0.0
    demod_seconds: float = 0.0
    wall_seconds: float = 0.0
    no_signal: int = 0
    demodulated: int = 0
    workers: str = "1 process"
    maps_seconds: float = 0.0
    worker_seconds: float = 0.0
    parent_seconds: float = 0.0

    @property
    def frames(self) -> np.ndarray:
        """Input frame indices, shape (N,)."""
        return self.series.frames

    @property
    def times(self) -> np.ndarray:
        """Frame times, s, from 0, shape (N,)."""
        return self.series.times

    @property
    def values(self) -> np.ndarray:
        """Carrier value per frame and peak (counts), shape (N, M); NaN: not measured."""
        return self.series.values

    @property
    def noise_rad(self) -> np.ndarray:
        """Per-pixel phase noise of each map, rad (NaN where not demodulated), shape (N, M)."""
        return self.map_noise_rad[: len(self.series)]

    @property
    def phase_steps(self) -> np.ndarray:
        """Whether each peak's mean phase stepped past the limit at each frame, (N, M)."""
        return self.series.phase_steps

    @property
    def frame_flags(self) -> dict[str, int]:
        """Frames flagged ``nonfinite`` and ``saturated`` (all), ``no_signal`` (demodulated)."""
        return {**self.series.frame_flags, "no_signal": self.no_signal}

    @property
    def peak_flags(self) -> list[dict[str, int]]:
        """Per peak, frames flagged ``phase_step`` (all), ``low_amplitude``, ``overlap``."""
        steps = self.series.step_counts
        return [{"phase_step": int(steps[j]), **f} for j, f in enumerate(self.map_flags)]

    def demodulable(self, position: int) -> bool:
        """Whether the demodulator takes the frame at ``position`` (neither damaged nor NaN)."""
        return not int(self.frame_bits[position]) & (DAMAGED_BIT | NONFINITE_BIT)

    def damaged(self, position: int) -> bool:
        """Whether the frame at ``position`` was damaged in transfer."""
        return bool(int(self.frame_bits[position]) & DAMAGED_BIT)

    def truncate(self, n: int) -> None:
        """Keep the first ``n`` frames (an interrupted run)."""
        self.series.truncate(n)
        self.interrupted = True


def new_run_data(
    peaks: Sequence[Peak],
    box_shape: tuple[int, int],
    radius: float,
    n: int,
    windows: Sequence[Window] = (),
) -> RunData:
    """An empty record of a run of ``n`` frames of ``peaks`` (their maps ``box_shape``).

    ``windows``: each peak's window (its largest radius is ``radius``).
    """
    m = len(peaks)
    series = PhaseSeries([p.label or f"P{j}" for j, p in enumerate(peaks)], n)
    return RunData(
        series=series,
        frame_bits=np.zeros(n, np.uint8),
        map_noise_rad=np.full((n, m), np.nan),
        map_flags=[dict.fromkeys(MAP_PEAK_FLAGS, 0) for _ in range(m)],
        box_shape=box_shape,
        radius=radius,
        windows=tuple(windows),
        last_maps=[None] * m,
        map_units=tuple("m" if p.alpha is not None else "rad" for p in peaks),
    )


def check_run(data: RunData) -> RunData:
    """Return ``data``; InputError when no frame could be measured."""
    if not np.any(np.isfinite(data.values)):
        raise InputError("no frame could be demodulated (every frame is NaN or infinite)")
    return data


class MapRecord:
    """Count each frame's maps of a pass into a run's record, in order; hand them to a sink.

    Parameters
    ----------
    data : RunData
        The run's record: its map noise, flags, counts and last maps are this pass's.
    sink : MapSink, optional
        Receives every frame's maps (a damaged or non-finite frame's are NaN).
    fused : bool
        The pass fuses maps: the sink gets a fused map of every frame.
    """

    def __init__(self, data: RunData, sink: MapSink | None = None, *, fused: bool = False) -> None:
        self._data = data
        self._sink = sink
        self._fused = fused
        m = len(data.map_flags)
        self._blank = [np.full(data.box_shape, np.nan, np.float32) for _ in range(m)]
        data.demodulated = data.no_signal = 0
        data.map_noise_rad[:] = np.nan
        for counts in data.map_flags:
            counts.update(dict.fromkeys(MAP_PEAK_FLAGS, 0))

    def record(self, position: int, index: int, frame: FrameMaps) -> None:
        """Count the ``position``-th frame's maps (input ``index``) and write them."""
        data = self._data
        if frame.demodulated:
            data.demodulated += 1
            if "no_signal" in frame.flags:
                data.no_signal += 1
            for j, (noise, flags) in enumerate(zip(frame.noise, frame.peak_flags, strict=True)):
                data.map_noise_rad[position, j] = noise
                for flag in flags:
                    if flag in data.map_flags[j]:
                        data.map_flags[j][flag] += 1
        if frame.maps:
            data.last_maps = list(frame.maps)
            data.last_fused = frame.fused
            data.last_frame = index
        if self._sink is not None:
            fused = None
            if self._fused:
                fused = frame.fused if frame.fused is not None else self._blank[0]
            self._sink.write_maps(position, frame.maps or self._blank, fused)
