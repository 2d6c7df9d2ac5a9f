"""The experiment: optics, labelled peaks and demodulation settings, with its one JSON format.

An experiment is what an operator sets at alignment and what every later replay needs:
the optics (wavelength, pixel pitch, refractive indices), the labelled peaks on the
twin where the phase grows with the height (docs/design.md), the window, its radius, the
reference mode and the unwrapping policy. The GUI saves and loads it, ``holoview peaks
--json`` writes it, ``holoview process --experiment`` and ``holoview live --experiment``
read it, and every recording carries the one in force
(:mod:`holoview.acquire.recording`).

The JSON layout (format ``holoview-experiment``, version 2)::

    {"format": "holoview-experiment", "version": 2,
     "wavelength_m": 5.32e-07, "pixel_pitch_m": 5.5e-06, "n1": 1.0, "n2": 1.333,
     "window": "tukey", "radius": null, "reference": "relative", "unwrap": "auto",
     "peaks": [{"label": "RB1", "carrier": [0.12, -0.05]},
               {"label": "G1", "carrier": [0.31, 0.02], "alpha": 0.5}]}

Carriers and the radius are in cycles per pixel (``fx`` along columns, ``fy`` along
rows), lengths in metres. ``radius`` is a number (every peak's window), ``"matched"``
or ``null`` (the automatic radius: per peak, matched to the surface's spectrum, never
past the bound) or ``"bound"`` (per peak, the widest reaching no other peak: what
``null`` meant before issue 23). A file whose radius is ``"bound"`` or ``"matched"``
is written as version 3 (earlier holoviews refuse it by its version); any other as
version 2, as before. A peak's
``alpha`` is optional for the model's families (RF, RB_j, FB_j, ...), whose prefactor
follows from the label and the indices, and needed for any other label. Every key
but ``format`` and ``version`` may be left out (an experiment that only names peaks
takes its optics from the recording). Version 1 files (peaks as ``{label, fx, fy}``)
are still read.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Iterable, Mapping
from collections.abc import Set as AbstractSet
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from holoview.errors import InputError, finite_number
from holoview.file_kinds import read_regular_file
from holoview.optics.families import alpha_of
from holoview.optics.setup import check_optics
from holoview.processing.fourier.windows import DEFAULT_WINDOW, WINDOW_KINDS
from holoview.processing.maps.demod_results import REFERENCE_MODES, UNWRAP_MODES
from holoview.processing.peaks.radii import radius_rule

__all__ = [
    "EXPERIMENT_FORMAT",
    "EXPERIMENT_VERSION",
    "MAX_PEAKS",
    "OPTICS_FIELDS",
    "PEAK_LABELS",
    "Experiment",
    "LabelledPeak",
    "check_carrier",
    "check_label",
    "config_dir",
    "default_experiment_path",
    "is_model_label",
]

EXPERIMENT_FORMAT = "holoview-experiment"
EXPERIMENT_VERSION = 3
#: Versions :meth:`Experiment.from_json` reads.
READABLE_VERSIONS = (1, 2, 3)
#: The version written when the radius is a number or automatic (readable before version 3).
NUMERIC_RADIUS_VERSION = 2

#: The optical values an experiment carries (SI units), as options and sources name them.
OPTICS_FIELDS: tuple[str, ...] = ("wavelength_m", "pixel_pitch_m", "n1", "n2")

#: Labels offered when an operator names a peak (any other usable name is allowed).
PEAK_LABELS: tuple[str, ...] = ("RB1", "FB1", "RF", "RB2", "FB2")

#: A label usable as a CSV value and an HDF5 name.
LABEL_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+~-]{0,31}")

#: Names a label cannot take: the fused map's, and the dimensions of ``results.h5``'s maps.
RESERVED_LABELS = ("fused", "time", "frame", "y", "x")

Carrier = tuple[float, float]

#: Most labelled peaks an experiment may hold. Every peak's window, and its twin's, must
#: keep clear of the others: at a window radius of 1/64 cycles/pixel (maps 32 times
#: narrower than the frame) the spectrum holds about 650 such windows, and every peak
#: costs a window's FFT in every frame (at 1024 x 1024, 256 peaks take about a third of a
#: second a frame). The peak model names about 20 peaks; a setup of the paper's kind
#: shows 5 to 10. An experiment of thousands is a mistake, and an expensive one (10 000
#: peaks kept the live window from opening for over 40 s, growing past 4.7 GB).
MAX_PEAKS = 256


def check_label(label: object, where: str) -> str:
    """Return ``label`` if it can name a series, a CSV row and an HDF5 dataset."""
    if not isinstance(label, str) or not LABEL_PATTERN.fullmatch(label) or label in RESERVED_LABELS:
        raise InputError(
            f"{where}: label {label!r} is not usable (a letter or digit, then letters, "
            f"digits and _.+~-, at most 32 characters, not {', '.join(RESERVED_LABELS)})"
        )
    return label


def check_carrier(carrier: object, where: str) -> Carrier:
    """Return a carrier ``(fx, fy)`` in cycles/pixel, or raise naming what is wrong.

    An ordered pair only: a JSON object or a set is refused (their keys or members would
    otherwise be read as fx and fy, a set's in no fixed order), so is a string.
    """
    wrong = f"{where}: carrier must be [fx, fy] in cycles/pixel, got {carrier!r}"
    if isinstance(carrier, str | bytes | Mapping | AbstractSet) or not isinstance(
        carrier, Iterable
    ):
        raise InputError(wrong)
    try:
        fx, fy = (float(v) for v in carrier)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(wrong) from exc
    if not (math.isfinite(fx) and math.isfinite(fy)):
        raise InputError(f"{where}: carrier ({fx}, {fy}) is not finite")
    if abs(fx) > 0.5 or abs(fy) > 0.5:
        raise InputError(
            f"{where}: carrier ({fx:g}, {fy:g}) is outside the spectrum "
            "(|fx|, |fy| <= 0.5 cycles/pixel)"
        )
    if fx == 0 and fy == 0:
        raise InputError(f"{where}: carrier (0, 0) is zero frequency, not a carrier")
    return fx, fy


def is_model_label(label: str) -> bool:
    """Whether ``label`` names one of the model's families (RF, RB_j, FB_j, B_lB_j, 2X, ...)."""
    try:
        alpha_of(label, 1.0, 1.5)
    except InputError:
        return False
    return True


@dataclass(frozen=True)
class LabelledPeak:
    """A peak the operator (or a file) named.

    Attributes
    ----------
    label : str
        The family name (``RB1``, ``FB1``, ``RF``, ...) or another usable name.
    carrier : tuple of float
        ``(fx, fy)`` in cycles per pixel on the twin whose phase grows with the height.
    alpha : float or None
        Phase-to-height prefactor (dimensionless); None: the model's, from the label.
    """

    label: str
    carrier: Carrier
    alpha: float | None = None

    def __post_init__(self) -> None:
        where = f"peak {self.label!r}"
        check_label(self.label, where)
        object.__setattr__(self, "carrier", check_carrier(self.carrier, where))
        if self.alpha is not None:
            if isinstance(self.alpha, bool) or not isinstance(self.alpha, int | float):
                raise InputError(f"{where}: alpha must be a number, got {self.alpha!r}")
            object.__setattr__(self, "alpha", finite_number(f"{where}: alpha", self.alpha))
            if self.alpha == 0:
                raise InputError(f"{where}: alpha must be nonzero, got {self.alpha}")

    @property
    def fx(self) -> float:
        """Carrier along columns, cycles/pixel."""
        return self.carrier[0]

    @property
    def fy(self) -> float:
        """Carrier along rows, cycles/pixel."""
        return self.carrier[1]

    def to_dict(self) -> dict[str, Any]:
        """The peak as its JSON object."""
        out: dict[str, Any] = {"label": self.label, "carrier": [self.fx, self.fy]}
        if self.alpha is not None:
            out["alpha"] = self.alpha
        return out


def _optional_positive(name: str, value: object) -> float | None:
    if value is None:
        return None
    number = finite_number(name, value)
    if number <= 0:
        raise InputError(f"{name} must be positive, got {value!r}")
    return number


@dataclass(frozen=True)
class Experiment:
    """Optics, labelled peaks and demodulation settings (SI units; cycles per pixel).

    Attributes
    ----------
    wavelength_m : float or None
        Laser wavelength in vacuum, m (None: not known here).
    pixel_pitch_m : float or None
        Object-side pixel pitch, m.
    n1, n2 : float or None
        Refractive indices above the surface (air) and of the fluid.
    window : str
        Spectral window around each peak
        (:data:`~holoview.processing.fourier.windows.WINDOW_KINDS`).
    radius : float, "bound" or None
        Window radius, cycles/pixel; None: automatic, matched per peak to the surface's
        spectrum (``"matched"`` is read as None); ``"bound"``: per peak, the widest
        reaching no other peak (:func:`~holoview.processing.peaks.radii.peak_windows`).
    reference : {"relative", "absolute", "synthetic"}
        Reference mode of the maps (docs/design.md).
    unwrap : {"auto", "always", "never"}
        Spatial unwrapping of the maps.
    peaks : tuple of LabelledPeak
        The labelled peaks, each label once.

    Raises
    ------
    InputError
        For a value that is not usable, naming it.
    """

    wavelength_m: float | None = 532e-9
    pixel_pitch_m: float | None = 5.5e-6
    n1: float | None = 1.0
    n2: float | None = 1.333
    window: str = DEFAULT_WINDOW
    radius: float | str | None = None
    reference: str = "relative"
    unwrap: str = "auto"
    peaks: tuple[LabelledPeak, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        for name in ("wavelength_m", "pixel_pitch_m", "n1", "n2"):
            object.__setattr__(self, name, _optional_positive(name, getattr(self, name)))
        if self.radius is None or isinstance(self.radius, str):
            if radius_rule(self.radius) == "matched":
                object.__setattr__(self, "radius", None)
        else:
            radius = _optional_positive("radius", self.radius)
            object.__setattr__(self, "radius", radius)
            if radius is not None and radius >= 0.5:
                raise InputError(f"window radius {radius} cycles/pixel is beyond Nyquist (0.5)")
        for name, allowed in (
            ("window", WINDOW_KINDS),
            ("reference", REFERENCE_MODES),
            ("unwrap", UNWRAP_MODES),
        ):
            if getattr(self, name) not in allowed:
                raise InputError(
                    f"{name} {getattr(self, name)!r} is not one of {', '.join(allowed)}"
                )
        check_optics(
            wavelength_m=self.wavelength_m, pixel_pitch_m=self.pixel_pitch_m, n1=self.n1, n2=self.n2
        )
        object.__setattr__(self, "peaks", tuple(self.peaks))
        labels = [p.label for p in self.peaks]
        twice = sorted({k for k in labels if labels.count(k) > 1})
        if twice:
            raise InputError(f"label {', '.join(twice)} is given twice")

    # ---- derived -----------------------------------------------------------
    @property
    def radius_rule(self) -> str:
        """``"matched"``, ``"bound"`` or ``"given"``: how the windows' radii are chosen."""
        return radius_rule(self.radius)

    @property
    def fixed_radius(self) -> float | None:
        """The radius given, cycles/pixel; None when each peak's is chosen by a rule."""
        return self.radius if isinstance(self.radius, float) else None

    def alpha(self, peak: LabelledPeak) -> float | None:
        """The prefactor of ``peak``: its own, else the model's for its label, else None."""
        return peak.alpha if peak.alpha is not None else self.alpha_of_label(peak.label)

    def alpha_of_label(self, label: str) -> float | None:
        """The model's prefactor of a family label (RF, RB_j, FB_j, ...), else None."""
        if self.n1 is None or self.n2 is None:
            return None
        try:
            return alpha_of(label, self.n1, self.n2)
        except InputError:
            return None

    def require(self, *names: str) -> None:
        """Raise InputError naming the option to give for each parameter that is unknown."""
        hints = {
            "wavelength_m": "the laser wavelength is not known: give --wavelength-nm",
            "pixel_pitch_m": "the pixel pitch is not known: give --pixel-pitch-um",
            "n2": "the fluid's refractive index is not known: give --n2 or --fluid",
            "n1": "the refractive index above the surface is not known: give --n1",
        }
        missing = [hints[name] for name in names if getattr(self, name) is None]
        if missing:
            raise InputError("; ".join(missing))

    # ---- changes -----------------------------------------------------------
    def with_peak(self, peak: LabelledPeak) -> Experiment:
        """Return a copy where ``peak`` replaces any peak of the same label or carrier."""
        kept = tuple(p for p in self.peaks if p.label != peak.label and p.carrier != peak.carrier)
        return replace(self, peaks=(*kept, peak))

    def without_label(self, label: str) -> Experiment:
        """Return a copy without the peak named ``label``."""
        return replace(self, peaks=tuple(p for p in self.peaks if p.label != label))

    def updated(
        self,
        *,
        window: str | None = None,
        reference: str | None = None,
        unwrap: str | None = None,
        radius: float | str | None = None,
    ) -> Experiment:
        """Return a copy with the demodulation settings given (None leaves a field as it is).

        ``radius``: a number (cycles/pixel), ``"matched"`` or ``"bound"``.
        """
        return replace(
            self,
            window=self.window if window is None else window,
            reference=self.reference if reference is None else reference,
            unwrap=self.unwrap if unwrap is None else unwrap,
            radius=self.radius if radius is None else radius,
        )

    def with_optics(self, optics: Mapping[str, float]) -> Experiment:
        """Return a copy with the optical values ``optics`` gives, the others kept.

        Parameters
        ----------
        optics : mapping of str to float
            Some of :data:`OPTICS_FIELDS` (SI units), as the optics options or a source's
            setup give them.

        Raises
        ------
        InputError
            For a value that is not usable, naming it.
        ValueError
            For a key that is not an optical value (a programming error).
        """
        unknown = sorted(set(optics) - set(OPTICS_FIELDS))
        if unknown:
            raise ValueError(f"not optical values of an experiment: {', '.join(unknown)}")
        return replace(
            self,
            wavelength_m=optics.get("wavelength_m", self.wavelength_m),
            pixel_pitch_m=optics.get("pixel_pitch_m", self.pixel_pitch_m),
            n1=optics.get("n1", self.n1),
            n2=optics.get("n2", self.n2),
        )

    # ---- JSON --------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The experiment as its JSON object (module docstring)."""
        return {
            "format": EXPERIMENT_FORMAT,
            "version": (
                EXPERIMENT_VERSION if isinstance(self.radius, str) else NUMERIC_RADIUS_VERSION
            ),
            "wavelength_m": self.wavelength_m,
            "pixel_pitch_m": self.pixel_pitch_m,
            "n1": self.n1,
            "n2": self.n2,
            "window": self.window,
            "radius": self.radius,
            "reference": self.reference,
            "unwrap": self.unwrap,
            "peaks": [p.to_dict() for p in self.peaks],
        }

    def to_json(self) -> str:
        """Return the experiment as JSON text."""
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_dict(cls, data: object, where: str = "experiment") -> Experiment:
        """Build an experiment from its JSON object; InputError naming what is wrong.

        Keys left out take no value (optics) or the default (demodulation settings).
        """
        if not isinstance(data, dict) or data.get("format") != EXPERIMENT_FORMAT:
            raise InputError(
                f"{where}: not a {EXPERIMENT_FORMAT} file (its format field is missing or "
                "wrong; `holoview peaks --json` writes one)"
            )
        version = data.get("version")
        if version not in READABLE_VERSIONS:
            raise InputError(
                f"{where}: {EXPERIMENT_FORMAT} version {version!r} is not supported "
                f"(this holoview reads {', '.join(map(str, READABLE_VERSIONS))})"
            )
        items = data.get("peaks", [])
        if not isinstance(items, list):
            raise InputError(f"{where}: peaks must be a list")
        if len(items) > MAX_PEAKS:
            raise InputError(
                f"{where}: {len(items)} peaks; an experiment holds at most {MAX_PEAKS} "
                "(their windows could not keep clear of each other)"
            )
        peaks = []
        for i, item in enumerate(items):
            peaks.append(_peak_from_dict(item, version, f"{where}, peak {i}"))
        known = ("wavelength_m", "pixel_pitch_m", "n1", "n2")
        settings = ("window", "radius", "reference", "unwrap")
        kwargs: dict[str, Any] = {k: data.get(k) for k in known}
        kwargs.update({k: data[k] for k in settings if k in data})
        try:
            return cls(**kwargs, peaks=tuple(peaks))
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from exc

    @classmethod
    def from_json(cls, text: str, where: str = "experiment") -> Experiment:
        """Parse JSON text written by :meth:`to_json`; InputError naming what is wrong."""
        try:
            data = json.loads(text, parse_int=_json_int)
        except json.JSONDecodeError as exc:
            raise InputError(f"{where}: not valid JSON ({exc.msg}, line {exc.lineno})") from exc
        except RecursionError:
            raise InputError(
                f"{where}: not an experiment (its JSON is nested too deeply to read)"
            ) from None
        return cls.from_dict(data, where)

    def save(self, path: Path) -> None:
        """Write the experiment to ``path`` (parent folders created; written whole or not)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f".{path.name}.partial")
        try:
            partial.write_text(self.to_json(), encoding="utf-8")
            os.replace(partial, path)
        finally:
            partial.unlink(missing_ok=True)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Experiment:
        """Read an experiment file; InputError when it is missing, unreadable or malformed."""
        p = Path(path)
        raw = read_regular_file(p, f"experiment file {p}")
        # PowerShell's ">" writes UTF-16 with a byte-order mark; read it as what it is
        encoding = "utf-16" if raw[:2] in (b"\xff\xfe", b"\xfe\xff") else "utf-8-sig"
        try:
            text = raw.decode(encoding)
        except UnicodeDecodeError:
            raise InputError(
                f"experiment file {p}: not text (a binary file? save it as UTF-8 JSON)"
            ) from None
        return cls.from_json(text, f"experiment file {p}")


#: Digits beyond which a JSON integer is read as a float (inf past 1e308): Python refuses
#: to convert integers of more than 4300 digits, and no experiment value needs 20.
_INT_DIGITS = 20


def _json_int(text: str) -> int | float:
    """A JSON integer: an int, or a float where it is too long to be a sensible one."""
    return int(text) if len(text) <= _INT_DIGITS else float(text)


def _peak_from_dict(item: object, version: int, where: str) -> LabelledPeak:
    """One peak entry: ``{label, carrier[, alpha]}`` (version 1: ``{label, fx, fy}``)."""
    if not isinstance(item, dict):
        raise InputError(f"{where}: expected an object with a label and a carrier")
    if version == 1 and "carrier" not in item:
        carrier: object = (item.get("fx"), item.get("fy"))
    else:
        carrier = item.get("carrier")
    if "label" not in item or carrier is None:
        raise InputError(f'{where}: expected {{"label": ..., "carrier": [fx, fy]}}')
    named = f"peak {item['label']!r}"
    try:
        label = check_label(item["label"], named)
        return LabelledPeak(label, check_carrier(carrier, named), item.get("alpha"))
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from exc


def config_dir() -> Path:
    """Return holoview's configuration folder, ``$XDG_CONFIG_HOME/holoview``.

    Read from the environment on every call, so that tests (and users) can point it
    elsewhere at any time.
    """
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "holoview"


def default_experiment_path() -> Path:
    """Return where the GUI keeps the experiment between sessions."""
    return config_dir() / "experiment.json"
