"""The live Waves panel's numbers: the last N maps of one chosen map and their analyses, Qt-free.

A :class:`WaveHistory` keeps the newest maps of one label (a peak's height map or the
fused map, metres, NaN where untrusted) with their true frame times, at most
``length`` of them (bounded memory: each map is kept by reference, never copied). A
frame lost on the way (the ring overwrote it) is a gap: the times say so and no
segment spans it (:mod:`holoview.processing.waves.clock`); a replay's jump starts the
history again (:meth:`WaveHistory.clear`). Maps of the relative reference (height
steps between frames) are summed into heights within each run of frames, as
``holoview waves`` does for a file.

:func:`analyse_window` takes a :meth:`WaveHistory.snapshot` and runs the analyses of
:mod:`holoview.processing.waves` on it, the same functions ``holoview waves`` runs:

- the omega-k spectrum (:class:`~holoview.processing.waves.omega_k.OmegaKAccumulator`,
  Welch over the segments of the window that span no gap);
- the dispersion fit of sigma, d and U with their standard errors
  (:func:`~holoview.processing.waves.dispersion.fit_dispersion`; a parameter the user
  holds keeps the value given);
- with a centre, the (m, f) spectrum around it
  (:class:`~holoview.processing.waves.azimuthal.AzimuthalAccumulator`).

Each analysis that cannot be made leaves its part None and one line saying why
(:class:`LiveWaves`), never a number without its error.
"""

from __future__ import annotations

import collections
import logging
import time
from dataclasses import dataclass, field

import numpy as np

from holoview.errors import InputError
from holoview.processing.waves.azimuthal import AzimuthalAccumulator, MFSpectrum, polar_grid
from holoview.processing.waves.clock import GAP_TOLERANCE
from holoview.processing.waves.dispersion import DispersionFit, Fluid, fit_dispersion
from holoview.processing.waves.omega_k import OmegaKAccumulator, OmegaKSpectrum

logger = logging.getLogger(__name__)

__all__ = [
    "FUSED",
    "LiveWaves",
    "WaveHistory",
    "WaveSettings",
    "WaveWindow",
    "analyse_window",
]

#: The label of the fused map.
FUSED = "fused"


@dataclass(frozen=True)
class WaveSettings:
    """What the Waves panel analyses and how (SI units).

    Attributes
    ----------
    label : str
        The map: a labelled peak's, or :data:`FUSED`.
    length : int
        Maps kept (the window analysed), at least ``segment``.
    segment : int
        Frames per Welch segment (the frequency step is ``rate / segment``).
    fluid : Fluid
        Density, gravity and the starting (or held) surface tension.
    depth : float
        Starting (or held) depth, m.
    flow : (float, float)
        Starting (or held) flow ``(Ux, Uy)``, m/s.
    hold : tuple of str
        Parameters held (``sigma``, ``depth``, ``flow``).
    centre : (float, float) or None
        Centre of the (m, f) spectrum, ``(x, y)`` in m from the first map pixel's centre.
    m_max : int
        Largest ``|m|`` of the (m, f) spectrum.
    """

    label: str = FUSED
    length: int = 256
    segment: int = 64
    fluid: Fluid = field(default_factory=Fluid)
    depth: float = 5e-3
    flow: tuple[float, float] = (0.0, 0.0)
    hold: tuple[str, ...] = ()
    centre: tuple[float, float] | None = None
    m_max: int = 8

    def __post_init__(self) -> None:
        if self.segment < 8:
            raise InputError(f"a segment needs at least 8 frames, got {self.segment}")
        if self.length < self.segment:
            raise InputError(
                f"the window ({self.length} frames) is shorter than a segment ({self.segment})"
            )


@dataclass(frozen=True)
class WaveWindow:
    """The maps of the window, oldest first, as :meth:`WaveHistory.snapshot` hands them.

    Attributes
    ----------
    label : str
    maps : tuple of ndarray
        Heights, m, NaN where untrusted, each (rows, cols); shared, never modified.
    times : ndarray of float
        Their frame times, s.
    pixel_size : (float, float) or None
        ``(dy, dx)`` of the maps, m (None: the pixel pitch is not known).
    k_cut : float or None
        The maps' cut-off wavenumber (the demodulation window's radius), rad/m.
    interval : float
        Nominal time between maps, s (``stride`` camera frames).
    stride : int
        Camera frames per map (1: every frame).
    gaps : int
        Gaps in the window (lost frames between two maps).
    """

    label: str
    maps: tuple[np.ndarray, ...]
    times: np.ndarray
    pixel_size: tuple[float, float] | None
    k_cut: float | None
    interval: float
    stride: int
    gaps: int

    @property
    def rate(self) -> float:
        """Maps per second (the nominal rate of the window), Hz."""
        return 1.0 / self.interval if self.interval > 0 else 0.0


class WaveHistory:
    """The newest maps of one label with their times, at most ``length`` (module docstring).

    Used by one thread at a time (the waves worker holds it under its lock).

    Parameters
    ----------
    length : int
        Maps kept.
    """

    def __init__(self, length: int) -> None:
        self.length = int(length)
        self._maps: collections.deque[np.ndarray] = collections.deque(maxlen=self.length)
        self._times: collections.deque[float] = collections.deque(maxlen=self.length)
        self._ids: collections.deque[int] = collections.deque(maxlen=self.length)
        self._sum: np.ndarray | None = None
        self.label = ""
        self.pixel_size: tuple[float, float] | None = None
        self.k_cut: float | None = None
        self.stride = 1
        #: Maps added since the history was made (lost ones not counted).
        self.pushed = 0
        #: Camera frames missing between two maps of one stride (gaps), since made.
        self.lost = 0

    def __len__(self) -> int:
        return len(self._maps)

    def clear(self) -> None:
        """Forget every map (a new label, stride or map grid)."""
        self._maps.clear()
        self._times.clear()
        self._ids.clear()
        self._sum = None

    def resize(self, length: int) -> None:
        """Keep at most ``length`` maps from now on (the newest kept)."""
        if int(length) == self.length:
            return
        self.length = int(length)
        self._maps = collections.deque(self._maps, maxlen=self.length)
        self._times = collections.deque(self._times, maxlen=self.length)
        self._ids = collections.deque(self._ids, maxlen=self.length)

    def push(
        self, height_m: np.ndarray, time_s: float, frame_id: int, *, relative: bool = False
    ) -> None:
        """Add one map (m, NaN where untrusted) of camera frame ``frame_id`` at ``time_s`` (s).

        ``relative``: the map is the height step since the previous map of the run; it is
        summed (a pixel untrusted once stays NaN until the run restarts).
        """
        if self._maps and self._maps[-1].shape != height_m.shape:
            logger.info("waves: maps of another shape, %s; the window starts again", height_m.shape)
            self.clear()
        if self._ids and frame_id - self._ids[-1] > self.stride:
            self.lost += frame_id - self._ids[-1] - self.stride
            self._sum = None
        if self._times and time_s <= self._times[-1]:  # a replay looped: a new record
            logger.info("waves: the frames' clock went back; the window starts again")
            self.clear()
        if relative:
            if self._sum is None or self._sum.shape != height_m.shape:
                self._sum = np.zeros(height_m.shape, np.float32)
            self._sum = self._sum + height_m
            height_m = self._sum
        self._maps.append(height_m)
        self._times.append(float(time_s))
        self._ids.append(int(frame_id))
        self.pushed += 1

    def snapshot(self) -> WaveWindow | None:
        """The maps kept now, oldest first; None when there are fewer than two."""
        if len(self._maps) < 2:
            return None
        times = np.fromiter(self._times, np.float64, len(self._times))
        ids = np.fromiter(self._ids, np.int64, len(self._ids))
        steps = np.diff(ids)
        interval = (
            float(np.median(np.diff(times)[steps == self.stride]))
            if np.any(steps == self.stride)
            else float(np.median(np.diff(times)))
        )
        return WaveWindow(
            label=self.label,
            maps=tuple(self._maps),
            times=times,
            pixel_size=self.pixel_size,
            k_cut=self.k_cut,
            interval=interval,
            stride=self.stride,
            gaps=int(np.count_nonzero(steps > self.stride)),
        )


@dataclass(frozen=True)
class LiveWaves:
    """What the Waves panel draws: the window's spectra and fits, or why not.

    Attributes
    ----------
    seq : int
        Counts the analyses.
    label : str
        The map analysed.
    frames : int
        Maps in the window.
    rate : float
        Maps per second, Hz (the frequency axis ends at half of it).
    camera_rate : float
        The camera's frames per second, Hz (0: not known).
    stride : int
        Camera frames per map (1: every frame kept).
    gaps : int
        Gaps in the window.
    latest : ndarray or None
        The newest map (m), for the field view.
    pixel_size : (float, float) or None
        ``(dy, dx)``, m.
    spectrum : OmegaKSpectrum or None
    fit : DispersionFit or None
    mf : MFSpectrum or None
    centre : (float, float) or None
        The centre of ``mf``, m.
    problems : tuple of str
        One line per analysis that could not be made (the spectrum's first).
    seconds : float
        Time the analysis took, s.
    map_seconds : float
        The waves worker's time per map (median of the last 16), s, from handing a frame
        to the map's process to taking the previous frame's map back: a map's time where
        the map's process limits the rate, less where it waits for frames (a full-speed
        replay paced by another worker); 0 before it is known. Beside the camera's frame
        interval it says why ``stride`` is what it is.
    map_cpu_seconds : float
        CPU time one map takes in the map's process (median of the last 16), s; 0 before
        it is known. Where ``map_seconds`` is longer, the map waited for a core.
    """

    seq: int
    label: str
    frames: int
    rate: float
    camera_rate: float
    stride: int
    gaps: int
    latest: np.ndarray | None
    pixel_size: tuple[float, float] | None
    spectrum: OmegaKSpectrum | None = None
    fit: DispersionFit | None = None
    mf: MFSpectrum | None = None
    centre: tuple[float, float] | None = None
    problems: tuple[str, ...] = ()
    seconds: float = 0.0
    map_seconds: float = 0.0
    map_cpu_seconds: float = 0.0

    @property
    def nyquist(self) -> float:
        """Highest frequency of the spectra, Hz (half the map rate)."""
        return 0.5 * self.rate


def _all_nan(maps: tuple[np.ndarray, ...]) -> bool:
    return not any(np.isfinite(m).any() for m in maps[-8:])


def _spectrum(window: WaveWindow, settings: WaveSettings) -> OmegaKSpectrum:
    """The Welch omega-k spectrum of the window (InputError saying why there is none)."""
    if window.pixel_size is None:
        raise InputError(
            "no omega-k spectrum: the pixel size is not known (give the pixel pitch in the "
            "Source panel's optics)"
        )
    if _all_nan(window.maps):
        raise InputError(f"no omega-k spectrum: the {window.label} maps are all NaN (untrusted)")
    accumulator = OmegaKAccumulator(
        window.maps[-1].shape,
        window.pixel_size,
        window.interval,
        segment=settings.segment,
        k_cut=window.k_cut,
    )
    for frame, t in zip(window.maps, window.times, strict=True):
        accumulator.push(frame, float(t))
    if accumulator.segments == 0:
        runs = _longest_run(window.times, window.interval)
        if accumulator.skipped:
            raise InputError(
                f"no omega-k spectrum: the {window.label} maps keep under half their pixels "
                "(untrusted)"
            )
        raise InputError(
            f"no omega-k spectrum yet: {runs} maps without a gap, a segment needs "
            f"{settings.segment}"
        )
    return accumulator.spectrum()


def _longest_run(times: np.ndarray, interval: float) -> int:
    if times.size < 2:
        return int(times.size)
    cuts = np.flatnonzero(np.diff(times) > (1.0 + GAP_TOLERANCE) * interval)
    edges = np.concatenate([[0], cuts + 1, [times.size]])
    return int(np.max(np.diff(edges)))


def _mf(window: WaveWindow, settings: WaveSettings) -> MFSpectrum:
    """The (m, f) spectrum around the centre (InputError saying why there is none)."""
    assert settings.centre is not None and window.pixel_size is not None
    grid = polar_grid(
        window.maps[-1].shape, window.pixel_size, settings.centre, m_max=settings.m_max
    )
    accumulator = AzimuthalAccumulator(grid, window.interval, segment=settings.segment)
    for a in range(0, len(window.maps), settings.segment):  # a block at a time: bounded memory
        accumulator.push_block(
            np.stack(window.maps[a : a + settings.segment]), window.times[a : a + settings.segment]
        )
    return accumulator.spectrum()


def analyse_window(
    window: WaveWindow, settings: WaveSettings, *, seq: int = 0, camera_rate: float = 0.0
) -> LiveWaves:
    """Run the panel's analyses on ``window`` (module docstring); never raises InputError.

    Parameters
    ----------
    window : WaveWindow
    settings : WaveSettings
    seq : int
        Number of this analysis.
    camera_rate : float
        The camera's frames per second, Hz (0: not known), said beside the map rate.
    """
    started = time.perf_counter()
    problems: list[str] = []
    spectrum = fit = mf = None
    try:
        spectrum = _spectrum(window, settings)
    except InputError as exc:
        problems.append(str(exc))
    if spectrum is not None:
        try:
            fit = fit_dispersion(
                spectrum,
                settings.fluid,
                depth=settings.depth,
                flow=settings.flow,
                hold=settings.hold,
            )
        except InputError as exc:
            problems.append(str(exc))
        except (ValueError, np.linalg.LinAlgError) as exc:  # a fit scipy gave up on
            problems.append(f"the dispersion fit did not converge ({exc})")
    if settings.centre is not None and window.pixel_size is not None and spectrum is not None:
        try:
            mf = _mf(window, settings)
        except InputError as exc:
            problems.append(str(exc))
    return LiveWaves(
        seq=seq,
        label=window.label,
        frames=len(window.maps),
        rate=window.rate,
        camera_rate=camera_rate,
        stride=window.stride,
        gaps=window.gaps,
        latest=window.maps[-1],
        pixel_size=window.pixel_size,
        spectrum=spectrum,
        fit=fit,
        mf=mf,
        centre=settings.centre if mf is not None else None,
        problems=tuple(problems),
        seconds=time.perf_counter() - started,
    )
