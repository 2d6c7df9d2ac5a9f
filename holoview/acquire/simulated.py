"""The simulated camera (holoview's default source): optics-simulator frames, live.

Frames come from :class:`holoview.optics.synthesis.HologramSynthesizer` for a
surface of a scenario (:data:`holoview.optics.scenarios.SCENARIOS`: ``waves``,
``evaporation``, ``injection``) with the reference-arm jitter of
:mod:`holoview.optics.scenarios`, paced at ``frame_rate_hz`` on the simulated
camera's own clock (frame ``i`` is due ``i / rate`` seconds after the start; a
fetch that comes late gets the frame at once, and never more than one second of
frames in a burst).

Rendering modes (``render``): ``"live"`` renders every frame when it is fetched,
so the surface never repeats; ``"cycle"`` renders ``cycle_frames`` frames on a
background thread (``holoview-sim-render``, started at open, joined at close) and
plays them in a loop: until the cycle is complete each fetch gets the newest frame
rendered so far (the surface moves at the rendering speed), then the cycle repeats
(the surface jumps back at each loop, and evaporating levels repeat); ``"auto"``
(the default) times a render at open and picks ``"live"`` when it takes under 0.8
of a frame interval, else ``"cycle"``. On 2 cores at 1024 x 1024 and 60 frames/s,
uniform levels (evaporation, injection: about 8 ms a frame) render live and waves
(about 30-90 ms) play a cycle. The mode chosen is the read-only ``render_mode``
setting, and frames delivered more than one interval after they were due are
counted in ``late``: a simulator that cannot keep up is never silent about it.

Fault injection for tests, each at its own rate (probability per frame, drawn
from the seeded generator): ``drop_rate`` (the frame is skipped: its id is used,
it is counted in ``lost`` as a transport loss would be), ``late_rate`` (the frame
comes ``late_s`` seconds late), ``corrupt_rate`` (a band of an eighth of the rows
is zeroed, as a buffer handed on with lost packets would be; it is delivered, and
counted in ``injected_corrupt``).
"""

from __future__ import annotations

import functools
import logging
import math
import threading
import time
from typing import Any

import numpy as np

from holoview.acquire.source import ROI, Frame, FrameMeta, Setting, Source
from holoview.errors import InputError
from holoview.optics.camera import NOISE_MODELS
from holoview.optics.scenarios import SCENARIOS, ScenarioConfig, make_surface
from holoview.optics.setup import Setup
from holoview.optics.synthesis import HologramSynthesizer, pixel_coordinates

logger = logging.getLogger(__name__)

#: Render modes.
RENDER_MODES = ("auto", "live", "cycle")
#: ``"auto"`` renders live when a frame takes less than this fraction of an interval.
LIVE_FRACTION = 0.8


def pixel_format_for_bits(bits: int) -> str:
    """The GenICam pixel format a ``bits``-deep camera delivers its frames in."""
    if bits <= 8:
        return "Mono8"
    return f"Mono{bits}" if bits in (10, 12, 14, 16) else "Mono16"


class SimulatedSource(Source):
    """A camera that films the optics simulator.

    Parameters
    ----------
    scenario : str
        ``"waves"`` (default), ``"evaporation"`` or ``"injection"``.
    setup : Setup, optional
        The simulated bench and camera (default :class:`~holoview.optics.setup.Setup`:
        1024 x 1024, 12-bit).
    shape : tuple of int, optional
        ``(rows, cols)`` replacing the setup's frame size.
    frame_rate_hz : float
        Frames per second.
    noise : str
        Shot-noise model (:data:`holoview.optics.camera.NOISE_MODELS`); the default
        ``"pooled"`` is the fastest.
    render : {"auto", "live", "cycle"}
        See the module docstring.
    cycle_frames : int
        Frames pre-rendered in ``"cycle"`` mode.
    seed : int, optional
        Seed of everything random (surface, jitter, noise, faults).
    config : ScenarioConfig, optional
        Physical parameters of the scenarios (default: the paper's).
    drop_rate, late_rate, corrupt_rate : float
        Fault probabilities per frame, 0 to 1.
    late_s : float
        How late a late frame comes, seconds.
    """

    def __init__(
        self,
        *,
        scenario: str = "waves",
        setup: Setup | None = None,
        shape: tuple[int, int] | None = None,
        frame_rate_hz: float = 30.0,
        noise: str = "pooled",
        render: str = "auto",
        cycle_frames: int = 64,
        seed: int | None = None,
        config: ScenarioConfig | None = None,
        drop_rate: float = 0.0,
        late_rate: float = 0.0,
        corrupt_rate: float = 0.0,
        late_s: float = 0.1,
    ) -> None:
        super().__init__(f"sim:{scenario}")
        if scenario not in SCENARIOS:
            raise InputError(f"unknown scenario {scenario!r}; choose one of {', '.join(SCENARIOS)}")
        if noise not in NOISE_MODELS:
            raise InputError(f"noise must be one of {', '.join(NOISE_MODELS)}, got {noise!r}")
        if render not in RENDER_MODES:
            raise InputError(f"render must be one of {', '.join(RENDER_MODES)}, got {render!r}")
        if cycle_frames < 1:
            raise InputError(f"cycle_frames must be at least 1, got {cycle_frames}")
        base = setup or Setup()
        self.sim_setup = base if shape is None else base.replace(shape=tuple(shape))
        self.scenario = scenario
        self.noise = noise
        self.render = render
        self.cycle_frames = int(cycle_frames)
        self.seed = seed
        self.config = config or ScenarioConfig()
        self._rate = 0.0
        self._faults = {"drop_rate": 0.0, "late_rate": 0.0, "corrupt_rate": 0.0}
        self._late_s = float(late_s)
        self._mode = ""
        self._cycle: np.ndarray | None = None
        self._wake = threading.Event()
        self._stop_rendering = threading.Event()
        self._renderer: threading.Thread | None = None
        self._rendered = 0
        self.counters.update({"late": 0, "injected_late": 0, "injected_corrupt": 0})
        self._register_settings()
        for name, value in (
            ("frame_rate_hz", frame_rate_hz),
            ("drop_rate", drop_rate),
            ("late_rate", late_rate),
            ("corrupt_rate", corrupt_rate),
        ):
            self._settings[name].write(self._settings[name].validate(value))

    def _register_settings(self) -> None:
        self.add_setting(
            Setting(
                "frame_rate_hz",
                "float",
                lambda: self._rate,
                self._set_rate,
                unit="Hz",
                limits=(0.1, 1000.0),
            )
        )
        for name in ("drop_rate", "late_rate", "corrupt_rate"):
            self.add_setting(
                Setting(
                    name,
                    "float",
                    functools.partial(self._faults.__getitem__, name),
                    functools.partial(self._set_fault, name),
                    limits=(0.0, 1.0),
                    doc="injected fault probability per frame",
                )
            )
        rows, cols = self.sim_setup.shape
        self.add_setting(Setting("roi", "roi", lambda: ROI(0, 0, cols, rows), unit="pixel"))
        self.add_setting(Setting("pixel_format", "enum", lambda: self._pixel_format))
        self.add_setting(Setting("scenario", "enum", lambda: self.scenario, choices=SCENARIOS))
        self.add_setting(Setting("noise", "enum", lambda: self.noise, choices=NOISE_MODELS))
        self.add_setting(Setting("render_mode", "str", lambda: self._mode))

    def _set_fault(self, name: str, value: float) -> None:
        """Set the probability per frame of the injected fault ``name``."""
        self._faults[name] = float(value)

    def _set_rate(self, rate: float) -> None:
        self._rate = float(rate)
        self._a = math.exp(-1.0 / (self._rate * self.config.vibration_time))
        self._wake.set()

    @property
    def _pixel_format(self) -> str:
        return pixel_format_for_bits(self.sim_setup.bit_depth)

    @property
    def frame_shape(self) -> tuple[int, int]:
        return self.sim_setup.shape

    @property
    def dtype(self) -> np.dtype:
        return np.dtype(np.uint8 if self.sim_setup.bit_depth <= 8 else np.uint16)

    @property
    def setup(self) -> dict[str, Any]:
        """The simulated setup as recording attributes (:meth:`Setup.as_attributes`)."""
        return self.sim_setup.as_attributes()

    # -- open / close ------------------------------------------------------------
    def _do_open(self) -> None:
        setup = self.sim_setup
        self._rng = np.random.default_rng(self.seed)
        self._fault_rng = np.random.default_rng(None if self.seed is None else self.seed + 1)
        self._surface = make_surface(setup, self.scenario, self.config, self._rng)
        self._uniform = bool(getattr(self._surface, "is_uniform", False))
        self._synth = HologramSynthesizer(setup, noise=self.noise)
        self._xy = pixel_coordinates(setup)
        self._jitter = self._rng.standard_normal() * self.config.vibration_rms
        self._next_index = 0
        self._clock = 0.0
        mode = self.render
        if mode == "auto":
            self._render(0.0)  # the first render builds caches; time the second
            t0 = time.perf_counter()
            self._render(0.0)
            cost = time.perf_counter() - t0
            mode = "live" if cost < LIVE_FRACTION / self._rate else "cycle"
            logger.info("%s: a frame renders in %.1f ms: %s mode", self.name, cost * 1e3, mode)
        if mode == "cycle":
            self._start_cycle()
        else:
            self._cycle = None
            self._mode = "live"

    def _start_cycle(self) -> None:
        """Render frame 0 now and the rest of the cycle on a background thread."""
        first = self._render(0.0)
        self._cycle = np.empty((self.cycle_frames, *first.shape), first.dtype)
        self._cycle[0] = first
        self._rendered = 1
        self._mode = f"cycle of {self.cycle_frames} frames"
        self._stop_rendering.clear()
        self._renderer = threading.Thread(
            target=self._render_cycle, args=(self._rate,), name="holoview-sim-render", daemon=True
        )
        self._renderer.start()

    def _render_cycle(self, rate: float) -> None:
        t0 = time.perf_counter()
        cycle = self._cycle
        assert cycle is not None
        for i in range(1, len(cycle)):
            if self._stop_rendering.is_set():
                return
            cycle[i] = self._render(i / rate)
            self._rendered = i + 1
        logger.info(
            "%s: %d frames pre-rendered in %.1f s", self.name, len(cycle), time.perf_counter() - t0
        )

    def _do_close(self) -> None:
        self._stop_rendering.set()
        if self._renderer is not None:
            self._renderer.join()
            self._renderer = None
        self._cycle = None

    def _render(self, t: float) -> np.ndarray:
        """Render the frame at simulated time ``t`` (s) with the next jitter step."""
        config = self.config
        if config.vibration_rms > 0:
            kick = self._rng.standard_normal() * config.vibration_rms * math.sqrt(1 - self._a**2)
            self._jitter = self._a * self._jitter + kick
        setup = self.sim_setup
        phase = 4 * math.pi * setup.n1 / setup.wavelength * self._jitter
        if self._uniform:
            centre = np.zeros(1)
            height: float | np.ndarray = float(np.asarray(self._surface(t, centre, centre))[0])
        else:
            height = np.broadcast_to(self._surface(t, *self._xy), setup.shape).astype(np.float64)
        return self._synth.render(height, reference_phase=phase, rng=self._rng)

    # -- streaming ---------------------------------------------------------------
    def _do_start(self) -> None:
        self._due = time.monotonic()
        self._wake.clear()

    def _do_stop(self) -> None:
        self._wake.set()

    def _do_fetch(self, timeout: float | None) -> Frame | None:
        now = time.monotonic()
        wait = self._due - now
        if wait > 0:
            if timeout is not None and wait > timeout:
                self._wake.wait(timeout)
                self._wake.clear()
                return None
            self._wake.wait(wait)
            self._wake.clear()
            if not self._streaming:
                return None
        interval = 1.0 / self._rate
        lateness = time.monotonic() - self._due
        self._due = max(self._due, time.monotonic() - 1.0) + interval
        index = self._next_index
        self._next_index += 1
        t_sim = self._clock
        self._clock += interval
        faults = self._fault_rng.random(3)
        if faults[0] < self._faults["drop_rate"]:
            self.counters["lost"] += 1
            return None
        if faults[1] < self._faults["late_rate"]:
            self.counters["injected_late"] += 1
            time.sleep(self._late_s)
            lateness += self._late_s
        if lateness > interval:
            self.counters["late"] += 1
        if self._cycle is not None:
            rendered = self._rendered
            slot = index % rendered if rendered == len(self._cycle) else rendered - 1
            data = self._cycle[slot].copy()
        else:
            data = self._render(t_sim)
        if faults[2] < self._faults["corrupt_rate"]:
            self.counters["injected_corrupt"] += 1
            band = max(1, data.shape[0] // 8)
            start = int(self._fault_rng.integers(0, data.shape[0] - band + 1))
            data[start : start + band] = 0
        meta = FrameMeta(
            frame_id=index,
            t_device=t_sim,
            t_host=time.time(),
            pixel_format=self._pixel_format,
        )
        return Frame(data, meta)
