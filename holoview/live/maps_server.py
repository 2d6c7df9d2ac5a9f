"""The live maps with their side work, made in a process of their own.

The maps of a 1024^2 frame with six peaks are 17-28 ms of CPU, much of it in numpy and
FFTW, which release the interpreter's lock, and the rest in Python, which does not. In
the window's process they took turns for the lock with the painting and the series:
``benchmarks/bench_gui.py`` (2 cores, AVX2) gave 5-6 maps/s, the maps worker getting
16 % of a core while the window's process, held to one core by the lock, used 99 %. In
a process of their own they take the second core.

:class:`MapsServer` is what that process does with each frame: the
:class:`~holoview.live.maps_pipeline.MapsPipeline` and the side work that feeds it, on
threads beside it as before (peak detection, the display spectrum, the windows' match,
itself in a process, and the displacement estimate; :mod:`holoview.live.side_workers`),
their results taken between frames. The window's process sends a :class:`MapsJob` (the
frame is in shared memory, :class:`~holoview.live.wave_map.FrameSlot`; the commands
posted since the last frame) and gets a :class:`MapsReply` back (the maps, the peaks
for the series, the problems met). :class:`SlotServer` reads the frame from the shared
block for it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, TypeVar

import numpy as np

from holoview.acquire.source import FrameMeta
from holoview.engine.experiment import Experiment
from holoview.engine.map_step import Coregistration
from holoview.errors import HoloviewError
from holoview.live.maps_pipeline import CoregistrationJob, LiveResult, MapsPipeline, spectrum_image
from holoview.live.side_workers import MatchWorker, PeakWorker, SideWorker, coregistration_work
from holoview.live.wave_map import SharedFrames
from holoview.processing.peaks.detection import Peak

__all__ = ["MapsJob", "MapsReply", "MapsServer", "SlotServer"]

#: The type of a side thread's results.
T = TypeVar("T")

#: The frame a reply's result carries: none (the window's process has the pixels).
NO_FRAME = np.empty((0, 0), np.uint16)


@dataclass(frozen=True)
class MapsJob:
    """One frame for the maps: its place in the shared block, its metadata, and the
    commands (``experiment``, ``reset``, ``match``) posted since the last frame, applied
    before it."""

    slot: int
    meta: FrameMeta
    commands: tuple[tuple[str, Any], ...] = ()


@dataclass(frozen=True)
class MapsReply:
    """What the maps send back for a frame.

    Attributes
    ----------
    result : LiveResult or None
        The frame's maps (its ``frame`` empty: the window's process has the pixels);
        None when the frame made none (a problem, in ``messages``).
    peak_set : tuple
        The demodulator's peaks (the series') and the experiment after the frame.
    reference_mode : str or None
        The demodulator's reference mode (None before one is built).
    messages : tuple of str
        Problems met with this frame (a command refused, the side work's errors).
    spectrum_kept : bool
        The result's spectrum is the one sent before, not sent again (its ``spectrum``
        None): the display spectrum comes at most
        :data:`~holoview.live.maps_pipeline.SPECTRUM_HZ` times a second, the maps up to
        the camera's rate, and each spectrum sent is unpickled into a new array that the
        window would take for a new one and draw again.
    """

    result: LiveResult | None
    peak_set: tuple[tuple[Peak, ...], Experiment]
    reference_mode: str | None
    messages: tuple[str, ...]
    spectrum_kept: bool = False


class MapsServer:
    """A :class:`MapsPipeline` on each frame, with its side work on threads beside it.

    Parameters
    ----------
    experiment : Experiment
        The settings to start with (commands change them).
    frame_shape : tuple of int
        ``(rows, cols)`` of the frames.
    saturation : float, optional
        Raw value at which the camera saturates.
    """

    def __init__(
        self, experiment: Experiment, frame_shape: tuple[int, int], saturation: float | None
    ) -> None:
        self.pipeline = MapsPipeline(experiment, frame_shape, saturation=saturation)
        self.pipeline.detect_inline = False
        self.pipeline.side_work_inline = False
        self.peaks = PeakWorker()
        self.spectra: SideWorker[np.ndarray, np.ndarray] = SideWorker(
            "holoview-spectrum", spectrum_image, "the spectrum"
        )
        self.matches = MatchWorker()
        self.coregistration: SideWorker[CoregistrationJob, Coregistration | None] = SideWorker(
            "holoview-coregister",
            coregistration_work(Coregistration(None)),
            "co-registration",
        )
        for side in (self.peaks, self.spectra, self.matches, self.coregistration):
            side.start()
        self._messages: list[str] = []

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the side threads (and the match process)."""
        for side in (self.peaks, self.matches, self.spectra, self.coregistration):
            side.stop(timeout)

    def step(
        self, pixels: np.ndarray, meta: FrameMeta, commands: tuple[tuple[str, Any], ...] = ()
    ) -> MapsReply:
        """Apply ``commands``, then make the maps of ``pixels`` (kept by the side threads:
        not to be modified)."""
        self._messages = []
        for name, value in commands:
            try:
                self.pipeline.apply(name, value)
            except HoloviewError as exc:
                self._messages.append(str(exc))
        result = None
        try:
            result = self._maps(pixels, meta)
        except HoloviewError as exc:
            self._messages.append(str(exc))
        demodulator = self.pipeline.demodulator
        return MapsReply(
            result,
            (self.pipeline.peaks, self.pipeline.experiment),
            None if demodulator is None else demodulator.reference,
            tuple(self._messages),
        )

    def _exchange_peaks(self, pixels: np.ndarray) -> None:
        """Hand the newest detected peaks to the pipeline; start a detection when due."""
        found = self.peaks.take()
        if isinstance(found, str):
            self._messages.append(found)
        elif found is not None:
            self.pipeline.set_peaks(found[0])
            self.pipeline.peaks_done(found[1])
        due = self.pipeline.peaks_due()
        if due and self.peaks.submit((pixels, self.pipeline.experiment.fixed_radius)):
            self.pipeline.peaks_started()

    def _hand_over(self, side: SideWorker[Any, T], use: Callable[[T, float], object]) -> None:
        """Give ``side``'s newest result and its seconds to ``use`` (a frame boundary), or
        keep its error."""
        found = side.take()
        if isinstance(found, str):
            self._messages.append(found)
        elif found is not None:
            use(*found)

    def _maps(self, pixels: np.ndarray, meta: FrameMeta) -> LiveResult:
        self._exchange_peaks(pixels)
        self._hand_over(self.matches, self.pipeline.use_match)
        self._hand_over(self.coregistration, self.pipeline.use_coregistration)
        self._hand_over(self.spectra, self.pipeline.use_spectrum)
        result = self.pipeline.process(pixels, meta)
        # the side work due, each dropped while its thread is busy (due again soon)
        coregistration = self.pipeline.coregistration_job()
        if coregistration is not None:
            self.coregistration.submit(coregistration)
        spectrum = self.pipeline.spectrum_job()
        if spectrum is not None:
            self.spectra.submit(spectrum)
        if not self.matches.busy:  # the measurement due, if any, after the maps are out
            job = self.pipeline.match_job(pixels, copy=False)
            if job is not None:
                self.matches.submit(job)
        return result


class SlotServer:
    """The maps process's work: a :class:`MapsServer` on the frames of a shared block.

    Made in the child (:class:`~holoview.live.worker.DemodWorker`); called with each job
    once the window's process has put the frame in its place.
    """

    def __init__(
        self, frames: SharedFrames, experiment: Experiment, saturation: float | None
    ) -> None:
        self._memory, self._frames = frames.attach()
        self.server = MapsServer(experiment, frames.shape, saturation)
        self._sent_spectrum: np.ndarray | None = None

    def __call__(self, job: MapsJob) -> MapsReply:
        pixels = np.array(self._frames[job.slot])  # the side threads keep it past this frame
        reply = self.server.step(pixels, job.meta, job.commands)
        if reply.result is None:
            return reply
        spectrum = reply.result.spectrum
        kept = spectrum is not None and spectrum is self._sent_spectrum
        self._sent_spectrum = spectrum
        result = replace(reply.result, frame=NO_FRAME, spectrum=None if kept else spectrum)
        return replace(reply, result=result, spectrum_kept=kept)
