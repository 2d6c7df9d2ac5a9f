"""Where the GUI keeps what it remembers.

Two kinds of state, kept apart on purpose:

- **UI state** (window geometry, dock layout, last directories) lives in a
  :class:`~PyQt6.QtCore.QSettings` INI file, ``$XDG_CONFIG_HOME/holoview/ui.ini``.
  It belongs to one operator on one machine.
- **Experiment settings** (wavelength, pixel pitch, refractive indices, labelled
  peaks, window kind and radius, reference mode) live in a portable JSON file,
  ``$XDG_CONFIG_HOME/holoview/experiment.json`` by default, that can be copied to
  another machine or kept beside a recording.

The JSON layout (format ``holoview-experiment``, version 1)::

    {"format": "holoview-experiment", "version": 1,
     "wavelength_m": 5.32e-07, "pixel_pitch_m": 5.5e-06, "n1": 1.0, "n2": 1.333,
     "window": "raised-cosine", "radius": 0.06, "reference": "relative",
     "peaks": [{"label": "RB1", "fx": 0.12, "fy": -0.05}, ...]}

``fx`` and ``fy`` are in cycles per pixel, ``radius`` too; lengths are in metres.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from PyQt6.QtCore import QSettings

from holoview.errors import InputError

EXPERIMENT_FORMAT = "holoview-experiment"
EXPERIMENT_VERSION = 1

#: Reference modes of the demodulation (DESIGN.md, paper section 3).
REFERENCE_MODES: tuple[str, ...] = ("relative", "absolute", "synthetic")

#: Labels offered when an operator names a peak (a custom name is also allowed).
PEAK_LABELS: tuple[str, ...] = ("RB1", "FB1", "RF", "RB2", "FB2")


def config_dir() -> Path:
    """Return holoview's configuration folder, ``$XDG_CONFIG_HOME/holoview``.

    Read from the environment on every call, so that tests (and users) can point it
    elsewhere at any time; Qt's own default paths are cached once per process.
    """
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "holoview"


def ui_settings() -> QSettings:
    """Return the QSettings that hold the window layout (an INI file in :func:`config_dir`)."""
    return QSettings(str(config_dir() / "ui.ini"), QSettings.Format.IniFormat)


@dataclass(frozen=True)
class LabelledPeak:
    """A peak the operator (or the model) named.

    Attributes
    ----------
    label : str
        The family name (``RB1``, ``FB1``, ``RF``, ...) or a custom name.
    fx, fy : float
        Carrier in cycles per pixel, fx along columns, fy along rows.
    """

    label: str
    fx: float
    fy: float


@dataclass(frozen=True)
class ExperimentSettings:
    """The portable experiment settings (SI units; frequencies in cycles per pixel).

    Attributes
    ----------
    wavelength_m : float
        Laser wavelength in metres.
    pixel_pitch_m : float
        Camera pixel pitch in metres.
    n1, n2 : float
        Refractive indices of the medium above the surface (air) and of the fluid.
    window : str
        Window kind used around each peak.
    radius : float
        Window radius in cycles per pixel.
    reference : str
        Reference mode: ``relative``, ``absolute`` or ``synthetic``.
    peaks : tuple of LabelledPeak
        The labelled peaks.
    """

    wavelength_m: float = 532e-9
    pixel_pitch_m: float = 5.5e-6
    n1: float = 1.0
    n2: float = 1.333
    window: str = "raised-cosine"
    radius: float = 0.06
    reference: str = "relative"
    peaks: tuple[LabelledPeak, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        for name in ("wavelength_m", "pixel_pitch_m", "n1", "n2", "radius"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise InputError(
                    f"experiment setting {name} must be a positive number, not {value!r}"
                )
        if self.radius >= 0.5:
            raise InputError(f"window radius {self.radius} cycles/pixel is beyond Nyquist (0.5)")
        if self.reference not in REFERENCE_MODES:
            raise InputError(
                f"reference mode {self.reference!r} is not one of {', '.join(REFERENCE_MODES)}"
            )

    def with_peak(self, peak: LabelledPeak) -> ExperimentSettings:
        """Return a copy where ``peak`` replaces any peak of the same label."""
        kept = tuple(p for p in self.peaks if p.label != peak.label)
        return replace(self, peaks=(*kept, peak))

    def without_label(self, label: str) -> ExperimentSettings:
        """Return a copy without the peak named ``label``."""
        return replace(self, peaks=tuple(p for p in self.peaks if p.label != label))

    def to_json(self) -> str:
        """Return the settings as the portable JSON text described in the module docstring."""
        data = {"format": EXPERIMENT_FORMAT, "version": EXPERIMENT_VERSION, **asdict(self)}
        return json.dumps(data, indent=2)

    @classmethod
    def from_json(cls, text: str) -> ExperimentSettings:
        """Parse settings written by :meth:`to_json`; raise InputError naming what is wrong."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"experiment settings are not valid JSON ({exc})") from exc
        if not isinstance(data, dict) or data.get("format") != EXPERIMENT_FORMAT:
            raise InputError(f"not a {EXPERIMENT_FORMAT} file (format field missing or wrong)")
        if data.get("version") != EXPERIMENT_VERSION:
            raise InputError(
                f"experiment settings version {data.get('version')!r} is not supported"
            )
        known = {f for f in cls.__dataclass_fields__ if f != "peaks"}
        kwargs = {k: v for k, v in data.items() if k in known}
        try:
            peaks = tuple(
                LabelledPeak(str(p["label"]), float(p["fx"]), float(p["fy"]))
                for p in data.get("peaks", [])
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"experiment settings: a peak entry is malformed ({exc})") from exc
        return cls(**kwargs, peaks=peaks)

    def save(self, path: Path) -> None:
        """Write the settings to ``path`` as JSON (parent folders are created)."""
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.to_json(), encoding="utf-8")

    @classmethod
    def load(cls, path: Path) -> ExperimentSettings:
        """Read settings from ``path``; raise InputError when it is missing or malformed."""
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise InputError(f"cannot read experiment settings {path}: {exc.strerror}") from exc
        return cls.from_json(text)


def default_experiment_path() -> Path:
    """Return where the experiment settings are kept between sessions."""
    return config_dir() / "experiment.json"
