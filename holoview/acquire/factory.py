"""Source specifications (``sim``, ``aravis[:ID]``, ``v4l2[:N]``, ``replay:PATH``) to sources.

Only the chosen source's module is imported, so ``sim`` needs neither PyGObject nor
a camera, and a missing Aravis is an error only for ``aravis``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from holoview.acquire.source import Source
from holoview.errors import InputError

#: The forms a source specification takes, for help texts and errors.
SPEC_FORMS = "sim[:SCENARIO], aravis[:ID], v4l2[:N] or replay:PATH"


class SourceSpec(NamedTuple):
    """A parsed source specification: ``kind`` and its argument (``""`` when none)."""

    kind: str
    argument: str


def parse_source_spec(spec: str) -> SourceSpec:
    """Split ``spec`` into kind and argument, checking both.

    ``sim`` takes an optional scenario name, ``aravis`` an optional device id (the
    Aravis id such as ``Aravis-Fake-GV01``, a serial, or an IP address; default:
    the first camera found), ``v4l2`` an optional device index (default 0), and
    ``replay`` a required path (everything after the first colon, so paths may
    contain colons).

    Raises
    ------
    InputError
        Unknown kind, a missing replay path, or a V4L2 index that is not a number.
    """
    text = spec.strip()
    kind, _, argument = text.partition(":")
    kind = kind.lower()
    if kind not in ("sim", "aravis", "v4l2", "replay"):
        raise InputError(f"unknown source {spec!r}: use {SPEC_FORMS}")
    if kind == "replay" and not argument:
        raise InputError("replay needs a path: replay:PATH")
    if kind == "v4l2" and argument and not argument.isdigit():
        raise InputError(f"v4l2 device must be an index (v4l2:0), got {argument!r}")
    return SourceSpec(kind, argument)


def make_source(spec: str, **options: Any) -> Source:
    """Return the (not yet opened) source for ``spec``; ``options`` go to its constructor."""
    kind, argument = parse_source_spec(spec)
    if kind == "sim":
        from holoview.acquire.simulated import SimulatedSource

        if argument:
            options.setdefault("scenario", argument)
        return SimulatedSource(**options)
    if kind == "aravis":
        from holoview.acquire.aravis import AravisSource

        return AravisSource(argument or None, **options)
    if kind == "v4l2":
        from holoview.acquire.v4l2 import V4L2Source

        return V4L2Source(int(argument or 0), **options)
    from holoview.acquire.replay import ReplaySource

    return ReplaySource(argument, **options)


def open_source(spec: str, **options: Any) -> Source:
    """Return the source for ``spec``, opened (not streaming).

    Parameters
    ----------
    spec : str
        ``sim[:SCENARIO]``, ``aravis[:ID]``, ``v4l2[:N]`` or ``replay:PATH``.
    **options
        Passed to the source's constructor (e.g. ``frame_rate_hz`` for ``sim``,
        ``speed`` and ``loop`` for ``replay``).

    Raises
    ------
    InputError
        A malformed specification or option value.
    CameraNotFoundError
        No device or file answers to it.
    """
    source = make_source(spec, **options)
    source.open()
    return source
