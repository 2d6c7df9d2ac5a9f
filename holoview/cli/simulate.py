"""``holoview simulate``: a simulated recording with its truth, and optionally a figure.

Frames come from :func:`holoview.optics.scenarios.simulate` (the paper's forward
model, fast synthesis) and go to a holoview recording (layout in
:mod:`holoview.acquire.recording`; ``source`` is ``"simulate:SCENARIO"``, the setup
attributes are :meth:`holoview.optics.setup.Setup.as_attributes`, and the stored
experiment labels RF, RB1 and FB1 on their true twins (the lattice names the rest:
:func:`holoview.engine.true_labels.true_experiment`), so ``holoview process`` needs no
peak options. After the writer closes, this command reopens the file and adds the
truth. The recording and the figure are written under temporary names and renamed
when complete
(:mod:`holoview.atomic`): a simulation that fails or is stopped leaves no file, and
neither an existing recording nor an existing figure is overwritten, also one that
another program created while the simulation ran (a no-replace rename): then the
command ends with one line naming the file and exit status 3 (an output that could
not be put in place), and the complete simulation is kept under its temporary name,
which the line gives (a simulation without ``--seed`` cannot be made again). Every
option is checked before the simulation starts.

``/truth`` layout
-----------------
attributes
    ``scenario`` (str), ``seed`` (int, -1 when none), ``fps_hz``, ``noise`` (str), and
    every :class:`~holoview.optics.scenarios.ScenarioConfig` field with its SI unit in
    the name (``evaporation_rate_m_per_s`` for an evaporation only,
    ``injection_rate_m3_per_s`` for an injection only,
    ``basin_area_m2``, ``basin_side_m``, ``wave_rms_m``, ``vibration_rms_m``,
    ``vibration_time_s``, ...).
``time_s`` (n,) float64
    Simulated time of each frame, s (also ``/t_device_s``).
``mean_height_m`` (n,) float64
    Mean surface height over the frame, m, relative to the rest level.
``reference_path_m``, ``reference_phase_rad`` (n,) float64
    Reference air-path jitter, m, and the phase it adds to RF and RB_j, rad.
``height_m`` (n, rows, cols) float32, gzip
    The height maps, m (every scenario but the uniform ones; not with
    ``--no-truth-maps``).
``waves/`` group (``travelling``, ``partial-waves``, ``ringdown``)
    Attributes: ``kind``, the fluid (``depth_m``, ``sigma_n_per_m``, ``rho_kg_per_m3``,
    ``g_m_per_s2``), ``convention``, and per kind ``flow_m_per_s`` (Ux, Uy);
    ``centre_m`` (x, y on the object plane, 0 at the frame centre), ``centre_frame_px``
    (x, y in frame pixels), ``core_radius_m``; ``m``, ``frequency_hz``,
    ``decay_per_s``, ``amplitude_m`` (real, imaginary), ``wavenumber_rad_per_m``;
    ``start_s`` and ``rise_s`` when the waves start after the first frame.
    Datasets: travelling ``wavevector_rad_per_m`` (n, 2), ``amplitude_m``,
    ``phase_rad``, ``omega_rad_per_s``; partial waves ``m``, ``frequency_hz``,
    ``wavenumber_rad_per_m``, ``incoming_m`` and ``outgoing_m`` (n, 2: real,
    imaginary parts of the coefficients of H_m^(2) and H_m^(1)). Each with a ``unit``.
``families/`` group, one row per predicted family (``max_order`` 4), datasets
    ``label`` and ``kind`` (str), ``carrier_cpp`` (k, 2) cycles/pixel (fx, fy; stored
    twin, unfolded), ``observed_carrier_cpp`` (k, 2) (folded into [-0.5, 0.5)),
    ``aliased`` (bool), ``amplitude`` (modulation depth of the pair), ``alpha``,
    ``displacement_m`` (k, 2), and ``peak_amplitude``, ``peak_displacement_m`` (k, 2):
    the coherent sum of every pair on that carrier (NaN for second-order peaks).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import time
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

from holoview.cli.simulate_figure import spectrum_figure
from holoview.cli.simulate_waves import (
    add_wave_scenario_options,
    build_waves,
    finite_number,
    warn_aliasing,
    warn_field,
    warn_overlap,
    write_wave_truth,
)
from holoview.errors import InputError

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy as np

    from holoview.optics.families import Family
    from holoview.optics.scenarios import FrameTruth, ScenarioConfig
    from holoview.optics.setup import Setup

logger = logging.getLogger(__name__)

#: Mirror passes of the families written to /truth and marked on the figure.
MAX_ORDER = 4

#: The first-order holograms, whose bands the waves must not make overlap.
FIRST_ORDER = ("RF", "RB1", "FB1")

#: Largest frame side, pixels (a 8192 x 8192 simulation needs several GB).
MAX_SIZE = 8192

#: Seeds are stored as an int64 attribute.
MAX_SEED = 2**63 - 1

#: The scenario config fields and the SI unit suffixes of their /truth attributes.
_CONFIG_UNITS = {
    "evaporation_rate": "_m_per_s",
    "injection_rate": "_m3_per_s",
    "basin_area": "_m2",
    "basin_side": "_m",
    "wave_rms": "_m",
    "wave_modes": "",
    "wave_max_index": "",
    "sigma": "_n_per_m",
    "rho": "_kg_per_m3",
    "vibration_rms": "_m",
    "vibration_time": "_s",
}
#: The rates only their scenario applies (a waves scenario has no evaporation).
_RATES = {"evaporation_rate": "evaporation", "injection_rate": "injection"}


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register ``simulate``."""
    from holoview.optics.camera import NOISE_MODELS
    from holoview.optics.scenarios import SCENARIOS
    from holoview.optics.setup import FLUIDS

    parser = subparsers.add_parser(
        "simulate",
        help="write a simulated recording with its truth (and a figure)",
        description="Simulate a multiplexed off-axis hologram sequence of a fluid surface "
        "(paper's forward model) into a new holoview recording, with a /truth group.",
    )
    parser.add_argument("out", type=Path, metavar="OUT.h5", help="the recording to create")
    parser.add_argument(
        "--scenario", choices=SCENARIOS, default="waves", help="the surface (default waves)"
    )
    parser.add_argument(
        "--size", type=int, default=512, metavar="N", help="N x N pixels (default 512)"
    )
    parser.add_argument("--frames", type=int, default=50, metavar="N", help="default 50")
    parser.add_argument(
        "--fps", type=float, default=60.0, metavar="F", help="frames/s (default 60)"
    )
    parser.add_argument(
        "--seed", type=int, default=None, metavar="S", help="same seed, same recording"
    )
    parser.add_argument(
        "--noise", choices=NOISE_MODELS, default="poisson", help="shot noise (default poisson)"
    )
    parser.add_argument(
        "--png",
        type=Path,
        metavar="PATH",
        help="save a frame and its spectrum as a figure (.png, .pdf or .svg)",
    )
    parser.add_argument("--png-frame", type=int, default=0, metavar="I", help="frame for --png")
    setup = parser.add_argument_group("setup (defaults: holoview.optics.setup.Setup)")
    setup.add_argument("--fluid", choices=sorted(FLUIDS), help="sets n2 from a preset")
    setup.add_argument("--n1", type=float, help="refractive index above the surface")
    setup.add_argument("--n2", type=float, help="refractive index of the fluid")
    setup.add_argument("--wavelength-nm", type=float, help="laser wavelength, nm")
    setup.add_argument("--pixel-pitch-um", type=float, help="object-side pixel pitch, um")
    tilt = "tilt, mrad (default: the setup's for 20 um, scaled to --pixel-pitch-um)"
    setup.add_argument(
        "--m-r-mrad", type=float, nargs=2, metavar=("MX", "MY"), help=f"reference mirror {tilt}"
    )
    setup.add_argument(
        "--m-b-mrad", type=float, nargs=2, metavar=("MX", "MY"), help=f"submerged mirror {tilt}"
    )
    setup.add_argument("--depth-mm", type=float, help="fluid depth over the mirror, mm")
    setup.add_argument("--delta-h-mm", type=float, help="arm-length difference, mm")
    setup.add_argument("--reflectivity", type=float, help="submerged mirror power reflectance")
    setup.add_argument("--beam-waist-mm", type=float, help="1/e^2 intensity radius, mm")
    setup.add_argument("--aperture-mm", type=float, help="field-stop radius, mm")
    setup.add_argument("--photons", type=float, help="photons per pixel at the beam centre")
    setup.add_argument("--bits", type=int, help="camera bit depth")
    setup.add_argument("--gamma", type=float, help="camera response exponent")
    setup.add_argument("--saturation", type=float, help="photons at full scale")
    setup.add_argument(
        "--ghost",
        action="append",
        default=[],
        nargs=4,
        metavar=("ARM", "TX_MRAD", "TY_MRAD", "AMPLITUDE"),
        help="a beam-splitter ghost of the reference or probe arm (repeatable)",
    )
    physics = parser.add_argument_group("scenario physics (defaults: the paper's)")
    physics.add_argument("--evaporation-um-per-min", type=float, help="level fall, um/min")
    physics.add_argument("--injection-ul-per-s", type=float, help="injected volume, uL/s")
    physics.add_argument("--basin-area-cm2", type=float, help="basin area for injection, cm^2")
    physics.add_argument("--wave-rms-nm", type=float, help="rms height of the waves, nm")
    physics.add_argument("--vibration-rms-nm", type=float, help="rms reference air-path jitter, nm")
    physics.add_argument("--sigma", type=float, metavar="N_PER_M", help="surface tension, N/m")
    physics.add_argument("--density", type=float, metavar="KG_PER_M3", help="fluid density")
    add_wave_scenario_options(parser)
    parser.add_argument(
        "--no-truth-maps",
        action="store_true",
        help="leave the height maps out of /truth (the wave scenarios' parameters define them)",
    )
    return parser


def build_setup(args: argparse.Namespace) -> Setup:
    """Return the setup the command-line options describe (SI units inside)."""
    from holoview.optics.setup import FLUIDS, Ghost, Setup, check_optics

    if args.size is None or not 8 <= args.size <= MAX_SIZE:
        raise InputError(f"--size must be from 8 to {MAX_SIZE} pixels, got {args.size}")
    check_optics(
        wavelength_m=None if args.wavelength_nm is None else args.wavelength_nm * 1e-9,
        pixel_pitch_m=None if args.pixel_pitch_um is None else args.pixel_pitch_um * 1e-6,
        names={
            "wavelength_m": ("--wavelength-nm", 1e-9),
            "pixel_pitch_m": ("--pixel-pitch-um", 1e-6),
        },
    )
    changes: dict[str, object] = {"shape": (args.size, args.size)}
    if args.fluid is not None:
        changes["n2"] = FLUIDS[args.fluid]
    scalar = {
        "n1": ("n1", 1.0),
        "n2": ("n2", 1.0),
        "wavelength_nm": ("wavelength", 1e-9),
        "pixel_pitch_um": ("pixel_pitch", 1e-6),
        "depth_mm": ("depth", 1e-3),
        "delta_h_mm": ("delta_H", 1e-3),
        "reflectivity": ("mirror_reflectivity", 1.0),
        "beam_waist_mm": ("beam_waist", 1e-3),
        "aperture_mm": ("aperture_radius", 1e-3),
        "photons": ("photons_per_pixel", 1.0),
        "gamma": ("gamma", 1.0),
        "saturation": ("saturation", 1.0),
    }
    for option, (name, scale) in scalar.items():
        value = finite_number(option.replace("_", "-"), getattr(args, option), scale)
        if value is not None:
            changes[name] = value
    if args.bits is not None:
        changes["bit_depth"] = args.bits
    for option, name in (("m_r_mrad", "m_r"), ("m_b_mrad", "m_b")):
        tilt = getattr(args, option)
        if tilt is not None:
            changes[name] = (tilt[0] * 1e-3, tilt[1] * 1e-3)
    _tilts_for_the_pitch(changes)
    ghosts = []
    for arm, tx, ty, amplitude in args.ghost:
        try:
            ghosts.append(Ghost(arm, (float(tx) * 1e-3, float(ty) * 1e-3), float(amplitude)))
        except ValueError as exc:
            raise InputError(f"--ghost {arm} {tx} {ty} {amplitude}: {exc}") from exc
    changes["ghosts"] = tuple(ghosts)
    return Setup().replace(**changes)


def _tilts_for_the_pitch(changes: dict[str, object]) -> None:
    """Scale the default tilts to a pixel pitch given without them (``changes``, in place).

    A carrier lies at ``2 n m pitch / wavelength`` cycles per pixel: the default tilts,
    set for the default 20 um pitch, put RB1 past Nyquist from 50 um on, and a wider field
    (what the wave scenarios need, and what their warning says to ask for) failed. A
    tilt not given is the default times ``default pitch / pitch``, so the carriers keep
    their place in the spectrum, as an experimenter aligns them for the optics at hand.
    """
    from holoview.optics.setup import Setup

    pitch = changes.get("pixel_pitch")
    default = Setup()
    if not isinstance(pitch, float) or pitch == default.pixel_pitch:
        return
    scaled = []
    for name in ("m_r", "m_b"):
        if name not in changes:
            tilt = tuple(m * default.pixel_pitch / pitch for m in getattr(default, name))
            changes[name] = tilt
            scaled.append(f"{name} ({tilt[0] * 1e3:.4g}, {tilt[1] * 1e3:.4g}) mrad")
    if scaled:
        logger.info(
            "tilts for the %.4g um pitch: %s (the defaults times %.4g: the carriers keep "
            "their place in cycles/pixel)",
            pitch * 1e6,
            ", ".join(scaled),
            default.pixel_pitch / pitch,
        )


def build_config(args: argparse.Namespace) -> ScenarioConfig:
    """Return the scenario physics the options describe (SI units inside)."""
    from dataclasses import replace

    from holoview.optics.scenarios import ScenarioConfig

    def given(option: str, scale: float, default: float) -> float:
        value = finite_number(option.replace("_", "-"), getattr(args, option), scale)
        return default if value is None else value

    base = ScenarioConfig()
    return replace(
        base,
        evaporation_rate=given("evaporation_um_per_min", 1e-6 / 60, base.evaporation_rate),
        injection_rate=given("injection_ul_per_s", 1e-9, base.injection_rate),
        basin_area=given("basin_area_cm2", 1e-4, base.basin_area),
        wave_rms=given("wave_rms_nm", 1e-9, base.wave_rms),
        vibration_rms=given("vibration_rms_nm", 1e-9, base.vibration_rms),
        sigma=given("sigma", 1.0, base.sigma),
        rho=given("density", 1.0, base.rho),
    )


def write_truth(
    path: Path,
    *,
    truths: list[FrameTruth],
    families: list[Family],
    setup: Setup,
    config: ScenarioConfig,
    args: argparse.Namespace,
    surface: Callable[[float, np.ndarray, np.ndarray], np.ndarray],
) -> None:
    """Add the ``/truth`` group (see the module docstring) to a closed recording.

    Height maps are evaluated again from ``surface`` at each frame's time (the same
    values the frames were made from), one frame at a time, not kept in memory.
    """
    import h5py
    import numpy as np

    from holoview.optics.families import coherent_amplitude, coherent_displacement
    from holoview.optics.synthesis import pixel_coordinates

    with h5py.File(path, "a") as f:
        group = f.create_group("truth")
        group.attrs["scenario"] = args.scenario
        group.attrs["seed"] = -1 if args.seed is None else int(args.seed)
        group.attrs["fps_hz"] = float(args.fps)
        group.attrs["noise"] = args.noise
        for name, value in asdict(config).items():
            if _RATES.get(name, args.scenario) == args.scenario:  # a rate of its scenario
                group.attrs[name + _CONFIG_UNITS.get(name, "")] = value
        group["time_s"] = np.array([t.time for t in truths])
        group["mean_height_m"] = np.array([t.mean_height for t in truths])
        group["reference_path_m"] = np.array([t.reference_path for t in truths])
        group["reference_phase_rad"] = np.array([t.reference_phase for t in truths])
        for name, unit in (
            ("time_s", "s"),
            ("mean_height_m", "m"),
            ("reference_path_m", "m"),
            ("reference_phase_rad", "rad"),
        ):
            group[name].attrs["unit"] = unit
        if hasattr(surface, "truth"):
            write_wave_truth(group, surface, setup)
        if not (getattr(surface, "is_uniform", False) or args.no_truth_maps):
            rows, cols = setup.shape
            x, y = pixel_coordinates(setup)
            maps = group.create_dataset(
                "height_m",
                shape=(len(truths), rows, cols),
                dtype=np.float32,
                chunks=(1, rows, cols),
                compression="gzip",
                shuffle=True,
            )
            maps.attrs["unit"] = "m"
            for i, truth in enumerate(truths):
                maps[i] = np.broadcast_to(surface(truth.time, x, y), setup.shape)
        table = group.create_group("families")
        table["label"] = np.array([fam.label for fam in families], dtype=h5py.string_dtype())
        table["kind"] = np.array([fam.kind for fam in families], dtype=h5py.string_dtype())
        table["carrier_cpp"] = np.array([fam.carrier for fam in families]).reshape(-1, 2)
        table["observed_carrier_cpp"] = np.array(
            [fam.observed_carrier for fam in families]
        ).reshape(-1, 2)
        table["aliased"] = np.array([fam.aliased for fam in families], dtype=bool)
        table["amplitude"] = np.array([fam.amplitude for fam in families])
        table["alpha"] = np.array([fam.alpha for fam in families])
        table["displacement_m"] = np.array([fam.displacement for fam in families]).reshape(-1, 2)
        peaks = [
            (coherent_amplitude(setup, fam.label), *coherent_displacement(setup, fam.label))
            if fam.kind != "second-order"
            else (math.nan, math.nan, math.nan)
            for fam in families
        ]
        table["peak_amplitude"] = np.array([p[0] for p in peaks])
        table["peak_displacement_m"] = np.array([p[1:] for p in peaks]).reshape(-1, 2)


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse, before simulating, outputs that exist or cannot be written (InputError)."""
    from holoview.headless.results.figures import figure_format

    if args.out.exists():
        raise InputError(f"{args.out} exists; holoview does not overwrite recordings")
    if not args.out.parent.is_dir():
        raise InputError(f"folder {args.out.parent} does not exist")
    if args.png is None:
        return
    if not 0 <= args.png_frame < args.frames:
        raise InputError(f"--png-frame must be in 0..{args.frames - 1}, got {args.png_frame}")
    if os.path.abspath(args.png) == os.path.abspath(args.out):
        raise InputError(f"--png {args.png} is the recording's own name; give another")
    if args.png.is_dir():
        raise InputError(f"--png {args.png} is a folder; give a file name such as figure.png")
    if args.png.exists():
        raise InputError(f"--png {args.png} exists; holoview does not overwrite it")
    if not args.png.parent.is_dir():
        raise InputError(f"folder {args.png.parent} does not exist")
    figure_format(args.png, "--png")


def run(args: argparse.Namespace) -> int:
    """Simulate, write the recording and its truth, and the figure if asked."""
    import dataclasses

    import numpy as np
    from tqdm import tqdm

    from holoview.acquire.recording_writer import RecordingWriter
    from holoview.atomic import atomic_path
    from holoview.engine.true_labels import true_experiment, visible_amplitudes
    from holoview.optics.families import predict_families
    from holoview.optics.scenarios import make_surface, simulate

    if args.frames is None or args.frames < 1:
        raise InputError(f"--frames must be at least 1, got {args.frames}")
    if not (math.isfinite(args.fps) and 0 < args.fps <= 1e7):
        raise InputError(f"--fps must be a frame rate from 0 to 1e7 frames/s, got {args.fps}")
    if args.seed is not None and not 0 <= args.seed <= MAX_SEED:
        raise InputError(f"--seed must be an integer from 0 to 2**63 - 1, got {args.seed}")
    check_outputs(args)
    setup = build_setup(args)
    config = build_config(args)
    families = predict_families(setup, max_order=MAX_ORDER)
    visible = visible_amplitudes(setup, families)
    for family in families:
        if family.aliased and visible[family.label] >= 1e-3:
            log = logger.warning if visible[family.label] >= 1e-2 else logger.info
            log(
                "%s carrier (%+.3f, %+.3f) cycles/pixel is past Nyquist; it appears folded "
                "at (%+.3f, %+.3f)",
                family.label,
                *family.carrier,
                *family.observed_carrier,
            )
    settings = {"frame_rate_hz": float(args.fps), "noise": args.noise}
    truths = []
    figure_frame = None
    surface = make_surface(
        setup, args.scenario, config, np.random.default_rng(args.seed), build_waves(args)
    )
    warn_aliasing(surface, args.fps)
    warn_field(surface, args.size * setup.pixel_pitch, args.size * setup.pixel_pitch)
    first_order = {f.label: f.observed_carrier for f in families if f.label in FIRST_ORDER}
    warn_overlap(surface, first_order, setup.pixel_pitch)
    sequence = simulate(
        setup,
        args.scenario,
        frames=args.frames,
        fps=args.fps,
        seed=args.seed,
        config=config,
        noise=args.noise,
        surface=surface,
    )
    with atomic_path(args.out, replace=False, keep=True) as partial:
        with RecordingWriter(
            partial,
            setup.shape,
            "uint8" if setup.bit_depth <= 8 else "uint16",
            setup=setup.as_attributes(),
            settings=settings,
            source=f"simulate:{args.scenario}",
            significant_bits=setup.bit_depth,
            pixel_format=f"Mono{setup.bit_depth}" if setup.bit_depth in (8, 10, 12, 16) else None,
            experiment=true_experiment(setup, families, visible).to_json(),
        ) as writer:
            progress = tqdm(total=args.frames, unit="frame", disable=args.quiet, desc="simulate")
            with progress:
                for frame, truth in sequence:
                    writer.append(frame, truth.index, truth.time, time.time())
                    truths.append(dataclasses.replace(truth, height=None))
                    if truth.index == args.png_frame:
                        figure_frame = frame
                    progress.update(1)
        write_truth(
            partial,
            truths=truths,
            families=families,
            setup=setup,
            config=config,
            args=args,
            surface=surface,
        )
    if args.png is not None and figure_frame is not None:
        from holoview.headless.results.figures import save_figure

        figure = spectrum_figure(
            figure_frame,
            families,
            pixel_pitch_m=setup.pixel_pitch,
            title=f"{args.out.name}: simulated {args.scenario}, frame {args.png_frame} "
            f"at {args.png_frame / args.fps:.3g} s, {setup.shape[1]} x {setup.shape[0]} pixels",
            amplitudes=visible,
        )
        with atomic_path(args.png, replace=False, keep=True) as partial_png:
            save_figure(figure, partial_png, name=str(args.png))
    logger.info("wrote %d frames to %s", len(truths), args.out)
    return 0
