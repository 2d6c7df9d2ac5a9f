"""``holoview simulate``'s wave scenarios: their options, their truth, warnings (a field
too small for the waves around a centre, waves aliased in time).

The scenarios ``travelling``, ``partial-waves`` and ``ringdown``
(:mod:`holoview.optics.wave_fields`): the options that set a
:class:`~holoview.optics.wave_fields.WaveConfig` (mm, mm/s, rad/m, Hz, nm on the
command line; SI inside), the ``/truth/waves`` group each surface's ``truth()`` fills
(layout in :mod:`holoview.cli.simulate`), and warnings when the field is too small for
waves around a centre or the waves' frequencies pass the Nyquist frequency of the frame
rate.
"""

from __future__ import annotations

import argparse
import logging
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from holoview.errors import InputError

if TYPE_CHECKING:
    import h5py

    from holoview.optics.setup import Setup
    from holoview.optics.wave_fields import WaveConfig

logger = logging.getLogger(__name__)


def _parsed(text: str, kind: type, given: str, what: str) -> Any:
    """``kind(text)``, or one line naming the option and what the value should be."""
    try:
        return kind(text)
    except ValueError:
        raise InputError(f"{given}: {text!r} is not {what}") from None


def finite_number(name: str, value: float | None, scale: float = 1.0) -> float | None:
    """``value * scale``, None for None; an infinite or NaN ``--name`` is one line."""
    if value is None:
        return None
    if not math.isfinite(value):
        raise InputError(f"--{name} must be finite, got {value}")
    return value * scale


def add_wave_scenario_options(parser: argparse.ArgumentParser) -> None:
    """Add the wave scenarios' options to ``simulate``."""
    waves = parser.add_argument_group(
        "wave scenarios (travelling, partial-waves, ringdown; defaults: WaveConfig's)"
    )
    waves.add_argument(
        "--flow-mm-per-s", type=float, nargs=2, metavar=("UX", "UY"), help="uniform mean flow"
    )
    waves.add_argument(
        "--wave-k", type=float, nargs=2, metavar=("K1", "K2"), help="wavenumbers, rad/m"
    )
    waves.add_argument("--wave-components", type=int, metavar="N", help="plane waves summed")
    waves.add_argument(
        "--partial-wave",
        action="append",
        default=[],
        nargs=4,
        metavar=("M", "F_HZ", "IN_NM", "OUT_NM"),
        help="a partial wave: azimuthal number, frequency, incoming and outgoing amplitudes "
        "(complex allowed: 8+6j) (repeatable)",
    )
    waves.add_argument(
        "--centre-mm",
        type=float,
        nargs=2,
        metavar=("X", "Y"),
        help="centre of the partial waves or mode, mm from the frame centre",
    )
    waves.add_argument("--core-mm", type=float, metavar="R", help="partial waves' core radius")
    waves.add_argument(
        "--mode",
        nargs=4,
        metavar=("M", "F_HZ", "DECAY_PER_S", "AMP_NM"),
        help="the damped mode of the ringdown scenario",
    )
    waves.add_argument(
        "--wave-start-s",
        type=float,
        metavar="T",
        help="the waves start at T s (the surface is at rest before; a mode is excited then)",
    )
    waves.add_argument(
        "--wave-rise-s", type=float, metavar="T", help="and reach full height T s later"
    )


def build_waves(args: argparse.Namespace) -> WaveConfig:
    """Return the wave scenarios' parameters the options describe (SI units inside)."""
    from holoview.optics.wave_fields import PartialWave, WaveConfig

    changes: dict[str, object] = {}
    if args.flow_mm_per_s is not None:
        changes["flow"] = tuple(finite_number("flow-mm-per-s", v, 1e-3) for v in args.flow_mm_per_s)
    if args.wave_k is not None:
        changes["k_range"] = tuple(finite_number("wave-k", v) for v in args.wave_k)
    if args.wave_components is not None:
        changes["components"] = args.wave_components
    if args.centre_mm is not None:
        changes["centre"] = tuple(finite_number("centre-mm", v, 1e-3) for v in args.centre_mm)
    if args.core_mm is not None:
        changes["core_radius"] = finite_number("core-mm", args.core_mm, 1e-3)
    for option, name in (("wave_start_s", "start"), ("wave_rise_s", "rise")):
        value = finite_number(option.replace("_", "-"), getattr(args, option))
        if value is not None:
            changes[name] = value
    partial = []
    for m, f, incoming, outgoing in args.partial_wave:
        given = f"--partial-wave {m} {f} {incoming} {outgoing}"
        amplitude = "an amplitude in nm such as 8 or 8+6j"
        wave = (
            int(_parsed(m, int, given, "M, a whole number")),
            float(_parsed(f, float, given, "F_HZ, a frequency in Hz")),
            complex(_parsed(incoming, complex, given, f"IN_NM, {amplitude}")) * 1e-9,
            complex(_parsed(outgoing, complex, given, f"OUT_NM, {amplitude}")) * 1e-9,
        )
        try:
            partial.append(PartialWave(*wave))
        except ValueError as exc:
            raise InputError(f"{given}: {exc}") from exc
    if partial:
        changes["partial_waves"] = tuple(partial)
    if args.mode is not None:
        m, f, decay, amplitude = args.mode
        try:
            changes.update(
                mode_m=int(m),
                mode_frequency=float(f),
                mode_decay=float(decay),
                mode_amplitude=float(amplitude) * 1e-9,
            )
        except ValueError as exc:
            raise InputError(f"--mode {m} {f} {decay} {amplitude}: {exc}") from exc
    return WaveConfig(**changes)  # type: ignore[arg-type]


def write_wave_truth(group: h5py.Group, surface: object, setup: Setup) -> None:
    """Add ``waves/`` (attributes and datasets of the surface's ``truth()``) to ``group``.

    Complex amplitudes are stored as (n, 2) arrays of their real and imaginary parts; a
    centre also in frame pixels (``centre_frame_px``, x then y).
    """
    import numpy as np

    attrs, data = surface.truth()  # type: ignore[attr-defined]
    waves = group.create_group("waves")
    for name, value in attrs.items():
        waves.attrs[name] = value
    if "centre_m" in attrs:
        rows, cols = setup.shape
        x0, y0 = attrs["centre_m"]
        waves.attrs["centre_frame_px"] = [
            (cols - 1) / 2 + x0 / setup.pixel_pitch,
            (rows - 1) / 2 + y0 / setup.pixel_pitch,
        ]
    for name, (values, unit) in data.items():
        array = np.asarray(values)
        if np.iscomplexobj(array):
            array = np.stack([array.real, array.imag], axis=-1)
            waves[name] = array
            waves[name].attrs["complex"] = "last axis: real part, imaginary part"
        else:
            waves[name] = array
        waves[name].attrs["unit"] = unit


def warn_field(surface: object, width: float, height: float) -> None:
    """Warn when the field cannot show the waves as holoview waves analyses them.

    ``width``, ``height``: the field, m, centred on the frame's centre as the surface's
    coordinates are. Travelling waves all below
    :data:`~holoview.processing.waves.dispersion.FIRST_STEPS` steps of the field's
    wave vector leave the dispersion fit nothing; partial waves are held down within 1.5
    core radii of their centre; a wave around a centre longer than the field leaves less
    than one wavelength in the maps. The scenarios' defaults need a field of centimetres
    (``--pixel-pitch-um``), not the 5-10 mm of the camera's defaults.
    """
    from holoview.optics.wave_fields import CORE_FULL
    from holoview.processing.waves.dispersion import FIRST_STEPS

    inner = getattr(surface, "surface", surface)  # a SwitchedOn wrapper
    field = f"the field ({width * 1e3:.3g} x {height * 1e3:.3g} mm)"
    widen = "widen it with --pixel-pitch-um or --size"
    if getattr(inner, "wavevectors", None) is not None:
        first = FIRST_STEPS * 2 * math.pi / min(width, height)
        top = max(_wavenumbers(inner), default=0.0)
        if top and top < first:
            logger.warning(
                "the waves reach %.0f rad/m, below the first wavenumber holoview waves fits "
                "in a %.3g x %.3g mm field, %.0f rad/m (%g steps of its wave vector): the "
                "field is too small for them: %s, or raise --wave-k",
                top,
                width * 1e3,
                height * 1e3,
                first,
                FIRST_STEPS,
                widen,
            )
        return
    centre = getattr(inner, "centre", None)
    if centre is None:
        return
    core = float(getattr(inner, "core_radius", 0.0))
    x0, y0 = centre
    far = max(
        math.hypot(sx * width / 2 - x0, sy * height / 2 - y0) for sx in (-1, 1) for sy in (-1, 1)
    )
    if core > 0 and far < CORE_FULL * core:
        logger.warning(
            "%s lies within %g core radii of the partial waves' centre, where the core holds "
            "them down (zero within %.3g mm, full beyond %.3g mm): %s, or give --core-mm",
            field,
            CORE_FULL,
            core * 1e3,
            CORE_FULL * core * 1e3,
            widen,
        )
        return
    longest = max((2 * math.pi / k for k in _wavenumbers(inner) if k > 0), default=0.0)
    if longest > min(width, height):
        logger.warning(
            "the waves reach a wavelength of %.3g mm, longer than %s: the maps hold less "
            "than one wavelength of them (%s)",
            longest * 1e3,
            field,
            widen,
        )


def warn_overlap(
    surface: object, carriers: Mapping[str, tuple[float, float]], pixel_pitch: float
) -> None:
    """Warn when the waves spread the holograms into one another.

    A wave of wavenumber ``k`` puts sidebands ``k pitch / (2 pi)`` cycles/pixel from every
    carrier whose hologram the surface modulates: two terms of the spectrum (the
    ``carriers`` given and their twins, mirrored through zero) closer than twice that
    share a band, which no window separates. The scenarios' default tilts suit the
    default 20 um pitch; a field of centimetres for the waves wants carriers farther
    apart.

    Parameters
    ----------
    surface : object
        The simulated surface (its waves' wave vectors or wavenumbers, rad/m).
    carriers : mapping of str to (float, float)
        The families' carriers where the camera sees them, cycles/pixel: the first
        order's (RF, RB1, FB1), the holograms every experiment labels (three points
        of the spectrum but in a degenerate setup, where they do overlap); a weaker
        family's band may touch theirs at a few per cent of their amplitude.
    pixel_pitch : float
        Object-side pixel pitch, m.
    """
    inner = getattr(surface, "surface", surface)  # a SwitchedOn wrapper
    spread = max(_wavenumbers(inner), default=0.0) * pixel_pitch / (2 * math.pi)
    if spread <= 0:
        return
    terms = [(name, (fx, fy)) for name, (fx, fy) in carriers.items()]
    terms += [(f"{name}'s twin", (-fx, -fy)) for name, (fx, fy) in carriers.items()]
    pairs = [
        (math.dist(a, b), name_a, name_b)
        for i, (name_a, a) in enumerate(terms)
        for name_b, b in terms[i + 1 :]
    ]
    if not pairs:
        return
    distance, first, second = min(pairs)
    if distance < 2 * spread:
        logger.warning(
            "the waves spread each hologram %.3f cycles/pixel around its carrier (%.0f rad/m "
            "at %.3g um a pixel), and %s and %s lie %.3f apart: their bands overlap and no "
            "window separates them (spread the carriers with --m-r-mrad and --m-b-mrad, or "
            "make the waves longer)",
            spread,
            spread * 2 * math.pi / pixel_pitch,
            pixel_pitch * 1e6,
            first,
            second,
            distance,
        )


def _wavenumbers(inner: object) -> list[float]:
    """The simulated waves' wavenumbers, rad/m: the travelling waves' (of their wave
    vectors), the partial waves', or the mode's; empty for a surface without waves."""
    vectors = getattr(inner, "wavevectors", None)
    if vectors is not None:
        return [math.hypot(float(kx), float(ky)) for kx, ky in vectors]
    numbers = getattr(inner, "wavenumbers", None) or [getattr(inner, "wavenumber", 0.0)]
    return [float(k) for k in numbers if k]


def warn_aliasing(surface: object, fps: float) -> None:
    """Warn when the waves' highest frequency is past the Nyquist frequency of ``fps``."""
    import numpy as np

    inner = getattr(surface, "surface", surface)  # a SwitchedOn wrapper
    omegas = getattr(inner, "omegas", None)
    if omegas is None:
        frequencies = [w.frequency for w in getattr(inner, "waves", ())]
        if hasattr(inner, "frequency"):
            frequencies.append(inner.frequency)
        top = max(frequencies, default=0.0)
    else:
        top = float(np.max(omegas)) / (2 * math.pi)
    if top > fps / 2:
        logger.warning(
            "the waves reach %.4g Hz, past the Nyquist frequency %.4g Hz of %g frames/s: "
            "they alias in time (raise --fps or lower --wave-k)",
            top,
            fps / 2,
            fps,
        )
