"""The Waves panel's map of one frame, made in a process of its own.

The waves worker (:mod:`holoview.live.wave_worker`) must map every camera frame, and a
map is some 7 ms of CPU at 1024^2 (``benchmarks/bench_wave_map.py``). Made on a thread of
the window's process it took 45-54 ms a map for 11 ms of CPU (``benchmarks/bench_gui.py
--waves RB1``, 2 cores): the rest was waiting for the interpreter's lock, which the
window, the series and the maps worker hold in turns. So the map is made in a child
process (:class:`~holoview.live.child_work.ChildWork`) with the state it needs
(:class:`WaveMapper`: the engine's per-frame core, its reference and mean phases, the
window held), and the frames reach it through shared memory (:class:`FrameSlot`): the
thread copies each frame into the slot and sends a few hundred bytes (sending the frame
down the pipe cost 6.5 ms of the thread's CPU and 12 ms of wall time per 1024^2 frame;
the slot 0.7 and 1.5 ms).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from multiprocessing import shared_memory

import numpy as np

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FrameCore
from holoview.engine.map_step import MapStep
from holoview.errors import InputError
from holoview.live.wave_window import FUSED
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.radii import peak_radii

__all__ = [
    "COREGISTER_S",
    "HOLD_BINS",
    "FrameSlot",
    "SharedFrames",
    "SlotMapper",
    "WaveJob",
    "WaveMap",
    "WaveMapper",
]

#: FFT bins a chosen peak's detected carrier may move before its map is demodulated at
#: the new carrier (a new demodulator: the window starts again).
HOLD_BINS = 2.0
#: Seconds between two frames added to the fused map's displacement estimate: every frame
#: (at 0.5 s a full-speed replay's 300 frames gave the estimate a handful of frames, the
#: fused maps moved between them, and sigma came out 14 % low in half the runs).
COREGISTER_S = 0.0


@dataclass(frozen=True)
class WaveJob:
    """What the map of the frame in the slot needs besides the frame.

    Attributes
    ----------
    peaks : tuple of Peak
        The maps worker's peaks (labels, carriers, prefactors).
    experiment : Experiment
        The experiment they were labelled with.
    label : str
        The map: a peak's label or :data:`~holoview.live.wave_window.FUSED`.
    restart : bool
        The frames do not follow on from the last one mapped (a replay's jump, a new
        stride): the reference and the phase steps start again.
    slot : int
        Where the frame is in the :class:`FrameSlot`.
    """

    peaks: tuple[Peak, ...]
    experiment: Experiment
    label: str
    restart: bool = False
    slot: int = 0


@dataclass(frozen=True)
class WaveMap:
    """One frame's map and what the history needs with it.

    Attributes
    ----------
    height : ndarray of float32
        The map, m (NaN where untrusted).
    pixel_size : (float, float) or None
        The map's pixel, m (None without the camera's pixel pitch).
    k_cut : float
        The window's cut-off, rad/m (inf without the pixel pitch).
    rebuilt : bool
        The demodulator is new (its first frame, or new peaks): its reference starts
        again, and the time of this map includes planning its FFTs.
    reference : str
        The experiment's reference mode (``"relative"``: the maps are steps to be summed).
    cpu_seconds : float
        CPU time the map took where it was made, s.
    """

    height: np.ndarray
    pixel_size: tuple[float, float] | None
    k_cut: float
    rebuilt: bool
    reference: str
    cpu_seconds: float


def _chosen(peaks: tuple[Peak, ...], label: str) -> list[Peak]:
    """The peaks whose maps make the map ``label`` (InputError when there is none)."""
    if label == FUSED:  # every peak, as the maps worker's fused map (the engine chooses)
        if sum(1 for p in peaks if p.label and p.alpha is not None) < 2:
            raise InputError(
                "no fused map: fewer than two labelled peaks have a height prefactor; "
                "label peaks in the Spectrum or choose one peak's map"
            )
        return [p for p in peaks if p.label]
    found = [p for p in peaks if p.label == label]
    if not found:
        raise InputError(
            f"no peak labelled {label}: label it in the Spectrum or choose another map"
        )
    if found[0].alpha is None:
        raise InputError(f"{label} has no height prefactor: its map is a phase, not a height")
    return found


class WaveMapper:
    """One chosen map of each frame given, with the state that carries from frame to frame.

    Parameters
    ----------
    frame_shape : (int, int)
        Frames' ``(rows, cols)``, pixels.
    saturation : float, optional
        Raw value at which the camera saturates.
    """

    def __init__(self, frame_shape: tuple[int, int], saturation: float | None = None) -> None:
        self.frame_shape = frame_shape
        self.saturation = saturation
        self._core: FrameCore | None = None
        self._step: MapStep | None = None
        self._radius: tuple[tuple[object, ...], float] | None = None
        #: The fused map's peaks by label, and the labels given that they came with.
        self._fused: tuple[dict[str | None, Peak], object] | None = None
        self._held_peaks: list[Peak] | None = None
        self._coregistered_at = -math.inf

    @property
    def radius(self) -> float | None:
        """The window radius of the maps, cycles/pixel (None before the first map)."""
        return None if self._radius is None else self._radius[1]

    def map(self, pixels: np.ndarray, job: WaveJob) -> WaveMap:
        """The chosen map of ``pixels``.

        Raises
        ------
        InputError
            No such map (no peak of that label, no prefactor, fewer than two for the
            fused map) or none from this frame (its flags named).
        """
        cpu = time.thread_time()
        if job.restart and self._core is not None:
            self._core.break_sequence()
        label, peaks = job.label, job.peaks
        chosen = _chosen(peaks, label)
        if label == FUSED:
            chosen = self._fused_peaks(chosen, job.experiment.peaks)
        chosen = self._held(chosen)
        experiment = replace(
            job.experiment, radius=self._window_radius(label, chosen, peaks, job.experiment)
        )
        if self._core is None or self._step is None:
            self._core = FrameCore(self.frame_shape, experiment, chosen, saturation=self.saturation)
            self._step = MapStep(self._core)
        before = self._core.demodulator
        self._core.configure(experiment, chosen)
        fused = label == FUSED
        now = time.monotonic()
        estimate = fused and now - self._coregistered_at >= COREGISTER_S
        maps = self._step.process(pixels, estimate=estimate, fuse=fused)
        demod = maps.result
        if demod is None or not maps.maps:
            raise InputError(f"no map of {label} from this frame ({', '.join(maps.flags)})")
        if estimate:
            self._coregistered_at = now
        height = maps.fused if fused else maps.maps[0]
        if height is None:
            raise InputError("no fused map: fewer than two peaks give a height on this frame")
        rows, cols = self.frame_shape
        by, bx = demod.box_shape
        pitch = experiment.pixel_pitch_m
        pixel_size = None if pitch is None else (pitch * rows / by, pitch * cols / bx)
        demodulator = self._core.demodulator
        radius = demod.radius if demodulator is None else min(demodulator.radii)
        return WaveMap(
            height=height,
            pixel_size=pixel_size,
            k_cut=math.inf if pitch is None else 2.0 * math.pi * radius / pitch,
            rebuilt=before is None or demodulator is not before,
            reference=experiment.reference,
            cpu_seconds=time.thread_time() - cpu,
        )

    def _fused_peaks(self, chosen: list[Peak], given: object) -> list[Peak]:
        """The fused map's peaks: those of its first frame, in the order of their labels,
        until the labels given change.

        A family the model adds later is left out, and one a detection misses (on a wavy
        surface a weak family is found on some frames, not on others) is kept at its last
        carrier: either would rebuild the demodulator and start the window again.
        """
        current = {p.label: p for p in chosen}
        fused = self._fused
        held = fused[0] if fused is not None and fused[1] == given else current
        kept = {name: current.get(name, peak) for name, peak in held.items()}
        self._fused = (kept, given)
        return [kept[name] for name in sorted(kept, key=str)]

    def _held(self, chosen: list[Peak]) -> list[Peak]:
        """The chosen peaks as first demodulated, while their labels and prefactors stay and
        no carrier has moved by more than :data:`HOLD_BINS` FFT bins.

        The maps worker snaps the carriers to each detection, which on a wavy surface
        wanders by a bin; a demodulator rebuilt for that would restart the window. A
        carrier held a bin off tilts every map by the same plane, which no step between
        frames and no frequency but zero sees.
        """
        held = self._held_peaks
        rows, cols = self.frame_shape
        if (
            held is not None
            and [(p.label, p.alpha) for p in held] == [(p.label, p.alpha) for p in chosen]
            and all(
                abs(p.carrier[0] - q.carrier[0]) * cols <= HOLD_BINS
                and abs(p.carrier[1] - q.carrier[1]) * rows <= HOLD_BINS
                for p, q in zip(held, chosen, strict=True)
            )
        ):
            return held
        self._held_peaks = chosen
        return chosen

    def _window_radius(
        self, label: str, chosen: list[Peak], peaks: tuple[Peak, ...], experiment: Experiment
    ) -> float:
        """The window radius of the maps, cycles/pixel, held while the map and labels stay.

        The experiment's radius where it sets a number; else (automatic, ``"bound"`` or
        ``"matched"``) the widest that reaches no other
        demodulated carrier (labelled or placed by the model), their twins or zero
        frequency (:func:`~holoview.processing.peaks.radii.peak_radii` without the
        detected neighbours; the smallest of the chosen peaks' for the fused map). The
        detected peaks are left out: on a wavy surface detection finds the waves'
        sidebands around every carrier, which are surface content to pass, and the
        maps worker's automatic radius shrinks to their spacing.
        """
        if isinstance(experiment.radius, (int, float)):
            return float(experiment.radius)
        key = (label, tuple(p.label for p in chosen))
        if self._radius is None or self._radius[0] != key:
            carriers = np.array([p.carrier for p in peaks], dtype=np.float64)
            radii = peak_radii(self.frame_shape, carriers, None, np.zeros((0, 2)))
            wanted = {p.label for p in chosen}
            self._radius = (
                key,
                min(r for p, r in zip(peaks, radii, strict=True) if p.label in wanted),
            )
        return self._radius[1]


class FrameSlot:
    """Frames in shared memory: written by the window's process, read by the child.

    Parameters
    ----------
    shape : (int, int)
        The frames' shape.
    dtype : numpy dtype
        The frames' type.
    count : int
        Frames it holds (one per job under way).

    Notes
    -----
    The block is named by the operating system (``/dev/shm`` on Linux) and removed by
    :meth:`close`; if the window's process is killed first, Python's resource tracker
    removes it.
    """

    def __init__(self, shape: tuple[int, int], dtype: np.typing.DTypeLike, count: int = 1) -> None:
        self.shape = shape
        self.dtype = np.dtype(dtype)
        self.count = count
        size = max(1, count * int(np.prod(shape)) * self.dtype.itemsize)
        self._memory: shared_memory.SharedMemory | None = shared_memory.SharedMemory(
            create=True, size=size
        )
        self.name = self._memory.name
        self._frames: np.ndarray | None = np.ndarray(
            (count, *shape), self.dtype, buffer=self._memory.buf
        )

    @property
    def shared(self) -> SharedFrames:
        """What a child needs to attach the block (picklable)."""
        return SharedFrames(self.name, self.count, self.shape, self.dtype.str)

    def put(self, slot: int, pixels: np.ndarray) -> None:
        """Copy a frame into place ``slot``."""
        np.copyto(self.frame(slot), pixels)

    def frame(self, slot: int) -> np.ndarray:
        """Place ``slot`` itself (a reader may copy a frame straight into it)."""
        assert self._frames is not None, "the slot is closed"
        frame: np.ndarray = self._frames[slot]
        return frame

    def child_work(self, saturation: float | None) -> Callable[[], SlotMapper]:
        """The ``make`` of a :class:`~holoview.live.child_work.ChildWork` mapping its frames."""
        return functools.partial(SlotMapper, self.shared, saturation)

    def close(self) -> None:
        """Release and remove the block (the child's view stays valid until it ends)."""
        memory, self._memory = self._memory, None
        self._frames = None
        if memory is not None:
            memory.close()
            memory.unlink()


@dataclass(frozen=True)
class SharedFrames:
    """A :class:`FrameSlot`'s block as a child attaches it: its name, frames, shape, type."""

    name: str
    count: int
    shape: tuple[int, int]
    dtype: str

    def attach(self) -> tuple[shared_memory.SharedMemory, np.ndarray]:
        """The block (keep it while the view is used) and a view of its frames."""
        memory = shared_memory.SharedMemory(name=self.name)
        frames = np.ndarray((self.count, *self.shape), np.dtype(self.dtype), buffer=memory.buf)
        return memory, frames


class SlotMapper:
    """The child's work: a :class:`WaveMapper` of the frames in a shared block.

    Made in the child (:meth:`FrameSlot.child_work`); called with each job once the
    window's process has put the frame in the slot.
    """

    def __init__(self, frames: SharedFrames, saturation: float | None) -> None:
        self._memory, self._frames = frames.attach()
        self.mapper = WaveMapper(frames.shape, saturation)

    def __call__(self, job: WaveJob) -> WaveMap:
        return self.mapper.map(self._frames[job.slot], job)
