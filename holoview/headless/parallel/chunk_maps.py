"""A run's maps made in the workers, chunk by chunk, equal to one process's.

With ``--maps`` every frame's maps and fused map are made (most of such a run's time),
in the workers, through the run's maps step
(:class:`~holoview.engine.map_step.MapStep`, built from one
:class:`~holoview.headless.frame_passes.MapsSpec`: the same peaks, settings, fused peaks
and displacements, measured before). A frame's maps depend on the frames before it in
three ways only, and each is handed to the worker, so that its maps are those of the
serial pass (:func:`~holoview.headless.frame_passes.maps_pass`) to the last bit:

- the FFTW plans: the worker plans from the parent's wisdom alone
  (:func:`~holoview.processing.fourier.fftplans.adopt_wisdom`): measured plans
  differ from process to process, and with them the last bits of every map;
- the reference fields: the worker first demodulates the frame the serial
  demodulator holds as reference when it reaches the chunk: in ``relative`` mode the
  last frame before the chunk that it demodulated (neither damaged in transfer nor
  non-finite), in ``absolute`` mode the run's first such frame (none with a
  background hologram, none in ``synthetic`` mode);
- the mean phases (:mod:`holoview.processing.maps.mean_phases`: the previous value,
  the reference's, the phase unwrapped in time, which places each map's 2 pi offset
  in the ``absolute`` and ``synthetic`` modes): they follow the series' carrier
  values, so the parent, which holds the run's series, replays them in order up to
  each chunk's start and hands the state on (:class:`MapsWork`). In ``relative`` mode
  the previous frame's value is all the offset needs, and the worker has it: such a
  run makes its maps in the same pass as its series, its workers measuring both.

What comes back is each frame's maps and what a run counts of them
(:class:`ChunkMaps`), for the parent to write in order. Workers on the parent's machine
(:attr:`~holoview.headless.parallel.runners.ChunkRunner.shares_files`) write a chunk's
maps into a file of a folder the parent gives (``MapsWork.spill``, in memory under
``/dev/shm``) rather than pickling them back: the parent maps the file and writes its
maps to ``results.h5`` from there (pickling, the pipe and unpickling cost about 1.5 ms
of CPU a frame of six 180^2 maps between the two processes).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from holoview.engine.frame_core import CarrierCore
from holoview.engine.map_step import FrameMaps, MapStep
from holoview.headless.frame_passes import MapsSpec, frame_maps
from holoview.headless.inputs import InputFile
from holoview.processing.fourier.fftplans import adopt_wisdom
from holoview.processing.fourier.frames import frame_damage
from holoview.processing.maps.demod_results import FRAME_FLAGS, PEAK_RESULT_FLAGS
from holoview.processing.maps.mean_phases import MeanPhaseState

__all__ = [
    "MAPS_CHUNK_BYTES",
    "MAPS_CHUNK_FRAMES",
    "ChunkMaps",
    "MapMaker",
    "MapsWork",
    "chunk_frames",
    "map_bytes",
]

#: Most frames in one chunk of a run with ``--maps``: a chunk's maps are held whole
#: (about 0.9 MB a 1024 x 1024 frame with six peaks), and the parent writes them in order ...
MAPS_CHUNK_FRAMES = 32

#: ... and most bytes of maps in one chunk: maps on the frame's grid (``--maps-grid
#: frame``, 29 MB a 1024 x 1024 frame with six peaks and the fused map) come four frames
#: a chunk (each chunk demodulates its reference frame besides: a fifth more work).
MAPS_CHUNK_BYTES = 128 << 20


def chunk_frames(map_bytes: int) -> int:
    """Most frames in one chunk whose every frame's maps take ``map_bytes`` bytes.

    Examples
    --------
    >>> chunk_frames(180 * 180 * 4 * 7), chunk_frames(1024 * 1024 * 4 * 7)
    (32, 4)
    """
    return max(1, min(MAPS_CHUNK_FRAMES, MAPS_CHUNK_BYTES // max(1, map_bytes)))


def map_bytes(box_shape: tuple[int, int], peaks: int) -> int:
    """Bytes of one frame's maps: ``peaks`` maps of ``box_shape`` and the fused one, float32."""
    return 4 * box_shape[0] * box_shape[1] * (peaks + 1)


def _bits(flags: frozenset[str], names: Sequence[str]) -> int:
    return sum(1 << b for b, name in enumerate(names) if name in flags)


def _names(bits: int, names: Sequence[str]) -> frozenset[str]:
    return frozenset(name for b, name in enumerate(names) if bits >> b & 1)


@dataclass(frozen=True)
class ChunkMaps:
    """Each frame's maps of one chunk and what a run counts of them (K frames, M peaks).

    Attributes
    ----------
    demodulated : ndarray of bool, shape (K,)
        The frame went through the demodulator.
    has_maps : ndarray of bool, shape (K,)
        The frame has maps (not damaged, not non-finite).
    has_fused : ndarray of bool, shape (K,)
        The frame has a fused map.
    noise : ndarray of float64, shape (K, M)
        Per-pixel phase noise, rad.
    peak_bits : ndarray of uint8, shape (K, M)
        Each peak's flags, bits of ``PEAK_RESULT_FLAGS``.
    frame_bits : ndarray of uint8, shape (K,)
        The frame's flags, bits of ``FRAME_FLAGS``.
    maps : ndarray of float32, shape (K, M, by, bx), or None
        The maps (NaN where untrusted, and for a frame without maps); None while
        ``spilled`` (:meth:`opened`).
    fused : ndarray of float32 or None, shape (K, by, bx)
        The fused maps, when the run fuses.
    spilled : str or None
        The ``.npy`` file the worker wrote the maps to, shape ``(K, M [+ 1], by, bx)``,
        the fused maps last; the parent deletes it once written.
    """

    demodulated: np.ndarray
    has_maps: np.ndarray
    has_fused: np.ndarray
    noise: np.ndarray
    peak_bits: np.ndarray
    frame_bits: np.ndarray
    maps: np.ndarray | None
    fused: np.ndarray | None
    spilled: str | None = None

    def opened(self) -> ChunkMaps:
        """These maps, those spilled to a file read from it (mapped, not copied)."""
        if self.spilled is None:
            return self
        both = np.load(self.spilled, mmap_mode="r")
        m = self.noise.shape[1]
        fused = both[:, m] if both.shape[1] > m else None
        return replace(self, maps=both[:, :m], fused=fused, spilled=None)

    def frame(self, k: int) -> FrameMaps:
        """The ``k``-th frame's maps, as the maps step gave them (views, not copies)."""
        assert self.maps is not None, "spilled maps: opened() first"
        m = self.maps.shape[1]
        has = bool(self.has_maps[k])
        return FrameMaps(
            demodulated=bool(self.demodulated[k]),
            maps=[self.maps[k, j] for j in range(m)] if has else [],
            fused=self.fused[k] if self.fused is not None and self.has_fused[k] else None,
            noise=tuple(float(v) for v in self.noise[k]) if has else (),
            peak_flags=tuple(_names(int(b), PEAK_RESULT_FLAGS) for b in self.peak_bits[k])
            if has
            else (),
            flags=_names(int(self.frame_bits[k]), FRAME_FLAGS),
        )


@dataclass(frozen=True)
class MapsWork:
    """What a worker needs, besides its chunk's frames, to make their maps.

    Attributes
    ----------
    spec : MapsSpec
        The run's maps step, its displacements measured.
    wisdom : tuple of bytes
        The parent's FFTW wisdom (module documentation).
    fused : bool
        The run fuses maps.
    values : ndarray of complex128 or None, shape (K, M)
        The series' carrier values of the chunk's frames (None: the worker measures
        them, in the same pass).
    frame_bits : ndarray of uint8 or None, shape (K,)
        The series' flags of those frames (``FRAME_FLAG_BITS``), with ``values``.
    state : MeanPhaseState or None
        The mean phases at the chunk's start, with ``values``.
    reference : int or None
        The input index of the frame to demodulate first (the reference fields), with
        ``values``; ``reference_values`` its carrier values.
    reference_values : ndarray or None
    before : tuple of int
        Without ``values`` (relative mode): the input indices of the run's frames before
        the chunk, in order; the last demodulated one is the reference.
    spill : str or None
        A folder on the parent's machine to write the chunk's maps into (module
        documentation); None: they go back pickled.
    """

    spec: MapsSpec
    wisdom: tuple[bytes, ...]
    fused: bool
    values: np.ndarray | None = None
    frame_bits: np.ndarray | None = None
    state: MeanPhaseState | None = None
    reference: int | None = None
    reference_values: np.ndarray | None = None
    before: tuple[int, ...] = ()
    spill: str | None = None

    def maker(
        self,
        source: InputFile,
        frame_shape: tuple[int, int],
        saturation: float | None,
        frames: int,
    ) -> MapMaker:
        """The maps step of this chunk, in the state the serial pass holds at its start."""
        adopt_wisdom(self.wisdom)
        step = self.spec.step(frame_shape, saturation)
        demod = step.core.demodulator
        assert demod is not None
        if self.values is not None:
            if self.reference is not None:
                step.process(source.read(self.reference), self.reference_values, fuse=False)
            if self.state is not None:
                demod.restore_phase_state(self.state)
        elif demod.reference == "relative":
            _previous_frame(step, source, self.before)
        return MapMaker(step, frames, fused=self.fused, spill=self.spill)


def _previous_frame(step: MapStep, source: InputFile, before: Sequence[int]) -> None:
    """Demodulate the last frame of ``before`` the serial pass demodulated (relative mode)."""
    probe = CarrierCore(source.frame_shape, source.saturation)
    demod = step.core.demodulator
    assert demod is not None
    probe.configure(demod.peaks)
    for index in reversed(before):
        frame = source.read(index)
        if frame_damage(np.asarray(frame)) is not None:
            continue
        measured = probe.measure(frame)
        assert measured is not None
        if "nonfinite" in measured.flags:
            continue
        step.process(frame, measured.values, fuse=False)
        return


class MapMaker:
    """Make one chunk's maps, frame after frame, into :class:`ChunkMaps` arrays.

    Parameters
    ----------
    step : MapStep
        In the state the serial pass holds at the chunk's start.
    frames : int
        Frames in the chunk.
    fused : bool
        Keep the fused maps.
    spill : str, optional
        A folder to write the maps into, a ``.npy`` file of the chunk's (else in memory).
    """

    def __init__(
        self, step: MapStep, frames: int, *, fused: bool, spill: str | None = None
    ) -> None:
        demod = step.core.demodulator
        assert demod is not None
        self.step = step
        m = len(demod.peaks)
        by, bx = demod.box_shape
        self._spill = spill
        # the maps and the fused maps in one array: one file when spilled
        both = np.full((frames, m + 1 if fused else m, by, bx), np.nan, np.float32)
        self._both = both
        self._maps = both[:, :m]
        self._fused = both[:, m] if fused else None
        self._demodulated = np.zeros(frames, bool)
        self._has_maps = np.zeros(frames, bool)
        self._has_fused = np.zeros(frames, bool)
        self._noise = np.full((frames, m), np.nan)
        self._peak_bits = np.zeros((frames, m), np.uint8)
        self._frame_bits = np.zeros(frames, np.uint8)

    def add(self, k: int, frame: np.ndarray, values: np.ndarray, bits: int) -> None:
        """Make the ``k``-th frame's maps (its carrier values and probe flag bits given)."""
        maps = frame_maps(self.step, frame, values, bits)
        self._demodulated[k] = maps.demodulated
        self._frame_bits[k] = _bits(maps.flags, FRAME_FLAGS)
        if not maps.maps:
            return
        self._has_maps[k] = True
        self._maps[k] = np.stack(maps.maps)
        if self._fused is not None and maps.fused is not None:
            self._fused[k] = maps.fused
            self._has_fused[k] = True
        self._noise[k] = maps.noise
        self._peak_bits[k] = [_bits(f, PEAK_RESULT_FLAGS) for f in maps.peak_flags]

    def _spilled(self) -> str | None:
        """Write the maps into a file of the spill folder; its name (None: not written).

        A plain write, not a mapping of the file: a full disk is an OSError here (the
        maps then go back pickled), where a mapped page would kill the process.
        """
        if self._spill is None:
            return None
        path = None
        try:
            handle, path = tempfile.mkstemp(suffix=".npy", dir=self._spill)
            with os.fdopen(handle, "wb") as f:
                np.save(f, self._both)
        except OSError:
            if path is not None:
                with contextlib.suppress(OSError):
                    os.unlink(path)
            return None
        return path

    def result(self) -> ChunkMaps:
        """The chunk's maps (spilled: the file's name, the maps in it alone)."""
        path = self._spilled()
        spilled = path is not None
        return ChunkMaps(
            demodulated=self._demodulated,
            has_maps=self._has_maps,
            has_fused=self._has_fused,
            noise=self._noise,
            peak_bits=self._peak_bits,
            frame_bits=self._frame_bits,
            maps=None if spilled else self._maps,
            fused=None if spilled else self._fused,
            spilled=path,
        )
