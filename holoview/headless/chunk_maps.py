"""A run's maps demodulated in the workers, chunk by chunk, equal to one process's.

With ``--maps`` every frame is demodulated into maps (most of such a run's time). A
frame's maps depend on the frames before it in two ways only, and both are restored
here so that a worker's maps are those of the serial loop
(:func:`~holoview.headless.pipeline.demodulate_frames`):

- the reference: a worker given a chunk first demodulates the frame the serial
  demodulator would hold as reference when it reaches the chunk
  (:func:`prepare_reference`): in ``relative`` mode the last frame before the chunk
  that was demodulated (neither damaged in transfer nor non-finite), in ``absolute``
  mode the run's first such frame (none with a background hologram, none in
  ``synthetic`` mode). A frame's damage is its own, so the worker can tell;
- the maps' 2 pi offset in the ``absolute`` and ``synthetic`` modes, set by the mean
  phase unwrapped in time since the run's first frame (a cumulative sum): a worker
  unwraps from its chunk's start, a whole number of turns off per peak. The parent
  replays the serial demodulator's sum from the workers' carrier values, in order,
  and moves each map by the turns it is off (:class:`TurnFix`). In ``relative`` mode
  the offset is set by the phase step from the previous frame, which the worker has.
"""

from __future__ import annotations

import cmath
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from holoview.engine.experiment import Experiment
from holoview.engine.frame_core import FrameCore
from holoview.headless.inputs import InputFile
from holoview.headless.pipeline import FrameMaps
from holoview.processing.fourier.fastmath import TWO_PI
from holoview.processing.fourier.frames import frame_damage
from holoview.processing.peaks.detection import Peak
from holoview.processing.peaks.matched import Window

#: Most frames in one chunk of a run with ``--maps``: a chunk's maps travel back whole
#: (about 0.8 MB a 1024 x 1024 frame with six peaks), and the parent writes them in order.
MAPS_CHUNK_FRAMES = 32


@dataclass(frozen=True)
class MapsSpec:
    """What a worker needs to build the run's demodulator (:class:`FrameCore`).

    Attributes
    ----------
    experiment : Experiment
        Window, radius, reference, unwrapping and wavelength.
    peaks : tuple of Peak
        The peaks demodulated.
    neighbours : tuple of (fx, fy)
        Every detected peak's carrier, cycles/pixel (the automatic windows reach none).
    threads : int
        FFTW threads per frame.
    background : ndarray or None
        The background hologram of absolute phases, counts.
    windows : tuple of Window
        Each peak's window, as the parent chose it (matched to the run's first frame).
    """

    experiment: Experiment
    peaks: tuple[Peak, ...]
    neighbours: tuple[tuple[float, float], ...]
    threads: int
    background: np.ndarray | None
    windows: tuple[Window, ...]

    @classmethod
    def of(cls, core: FrameCore) -> MapsSpec:
        """The spec of a run's core (built)."""
        demodulator = core.build()
        assert demodulator is not None
        return cls(
            experiment=core.experiment,
            peaks=core.peaks,
            neighbours=core.neighbours,
            threads=core.threads,
            background=core.background,
            windows=demodulator.windows,
        )

    def core(self, frame_shape: tuple[int, int], saturation: float | None) -> FrameCore:
        """A new core, its demodulator built: the run's, with its own FFTW plans."""
        core = FrameCore(
            frame_shape,
            self.experiment,
            self.peaks,
            saturation=saturation,
            threads=self.threads,
            background=self.background,
            neighbours=self.neighbours,
            windows=self.windows,
        )
        core.build()
        return core


def prepare_reference(core: FrameCore, source: InputFile, before: Sequence[int]) -> None:
    """Give ``core`` the reference the serial run holds after the frames ``before``.

    Parameters
    ----------
    core : FrameCore
        Built, no frame demodulated yet.
    source : InputFile
        The input.
    before : sequence of int
        Input indices of the run's frames before the chunk, in order.
    """
    demodulator = core.build()
    assert demodulator is not None
    if demodulator.reference == "synthetic" or demodulator.background is not None:
        return
    order = before if demodulator.reference == "absolute" else reversed(before)
    for index in order:
        frame = source.read(index)
        if frame_damage(np.asarray(frame)) is not None:
            continue
        result = core.process(frame)
        if result is not None and "nonfinite" not in result.flags:
            return


class TurnFix:
    """The serial run's time-unwrapped mean phases, replayed in order; maps moved to them.

    Parameters
    ----------
    reference : str
        The demodulator's reference mode (``relative`` maps need no move).
    peaks : int
        Peaks demodulated.
    """

    def __init__(self, reference: str, peaks: int) -> None:
        self._moves = reference != "relative"
        self._previous: list[complex | None] = [None] * peaks
        self._unwrapped = [0.0] * peaks

    def apply(self, frame: FrameMaps) -> None:
        """Move ``frame``'s maps (in place) by the whole turns its worker was off.

        ``frame`` is the next demodulated frame of the run, in order.
        """
        for j, value in enumerate(frame.values):
            previous = self._previous[j]
            if previous is None:
                self._unwrapped[j] = frame.unwrapped[j]  # as the first worker started
            else:
                self._unwrapped[j] += cmath.phase(value * previous.conjugate())
            self._previous[j] = value
            if not self._moves or not frame.maps:
                continue
            turns = round((self._unwrapped[j] - frame.unwrapped[j]) / TWO_PI)
            if turns:
                frame.maps[j] += np.float32(TWO_PI * turns) * np.float32(frame.scales[j])
