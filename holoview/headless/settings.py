"""How a headless run demodulates: :class:`ProcessSettings`, as the ``holoview process`` options."""

from __future__ import annotations

from dataclasses import dataclass

from holoview.headless.reader import DEFAULT_DEPTH

__all__ = ["ProcessSettings"]


@dataclass(frozen=True)
class ProcessSettings:
    """How a run demodulates (names as the ``holoview process`` options).

    Attributes
    ----------
    reference : {"relative", "absolute", "synthetic"} or None
        Reference mode of the maps (the mean-phase series is always relative to the
        first frame). None: the experiment's.
    window : {"raised-cosine", "top-hat", "tukey"} or None
        None: the experiment's.
    radius : float or None
        Window radius, cycles/pixel (None: the experiment's, else automatic from the
        carriers).
    unwrap : {"auto", "always", "never"} or None
        Spatial unwrapping of the maps. None: the experiment's.
    maps : bool
        Write the delta-h maps of every frame, and the fused map.
    area_m2 : float or None
        Basin area, m^2, for volume rates.
    threads : int
        FFTW threads per frame. One by default: the reader thread needs a core too,
        and on a loaded two-core machine a two-thread FFT waiting for a busy core
        took 450 ms instead of 10 ms per 1024 x 1024 frame.
    read_ahead : int
        Frames the reader thread reads ahead.
    background : str or None
        An object-free hologram for absolute phases: a frame index of the input, or
        a file (its first frame); None: the first processed frame.
    """

    reference: str | None = None
    window: str | None = None
    radius: float | None = None
    unwrap: str | None = None
    maps: bool = False
    area_m2: float | None = None
    threads: int = 1
    read_ahead: int = DEFAULT_DEPTH
    background: str | None = None
