"""Paths built from data, confined to their folder; outputs kept apart from inputs.

:func:`confined_name` turns a name that comes from data (a recording's file name, a
peak's label) into one file or folder name inside the folder it is meant for: no
separators, never ``.`` or ``..``, no hidden name, no control or invisible
characters, and short enough for the file system. Every path holoview builds from a
name it did not choose goes through it (a batch's output folders, the GUI's map
exports).

:func:`check_apart` refuses outputs that would replace an input (the same file, also
through a hard or symbolic link) or land among the files of a folder read as input.
"""

from __future__ import annotations

import os
import unicodedata
from collections.abc import Iterable
from pathlib import Path

from holoview.atomic import fit_name
from holoview.errors import InputError

#: Longest confined name, bytes: room below NAME_MAX (255) for a ``_NNN`` added to
#: keep two names apart, and for a file system that allows fewer.
MAX_NAME_BYTES = 200

#: Unicode categories replaced: controls, invisible format characters (bidirectional
#: overrides that make a name read otherwise), line and paragraph separators, and the
#: surrogates that stand for bytes of a file name that are not UTF-8.
_REPLACED_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Zl", "Zp"})


def _allowed(char: str) -> bool:
    return char not in "/\\" and unicodedata.category(char) not in _REPLACED_CATEGORIES


def confined_name(text: str, fallback: str = "unnamed") -> str:
    """A single file or folder name made from ``text``, safe to join to any folder.

    Each separator (``/``, ``\\``), control, invisible-format or undecodable character
    becomes ``_``, as does each leading dot (so neither ``.``, ``..`` nor a hidden name
    comes out); a name longer than :data:`MAX_NAME_BYTES` is cut with a hash of the
    whole added (:func:`holoview.atomic.fit_name`); an empty name becomes
    ``fallback``. A name that needs none of this is returned unchanged.

    Examples
    --------
    >>> confined_name("..")
    '__'
    >>> confined_name("day/2\\n")
    'day_2_'
    >>> confined_name("run 3")
    'run 3'
    """
    name = "".join(c if _allowed(c) else "_" for c in text)
    stripped = name.lstrip(".")
    name = "_" * (len(name) - len(stripped)) + stripped
    return fit_name(name, MAX_NAME_BYTES) if name else fallback


def _same(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` are one file or folder (links followed; False if one is missing)."""
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def check_apart(outputs: Iterable[Path], inputs: Iterable[Path], what: str = "--out") -> None:
    """Refuse outputs that are an input, or that lie directly in a folder read as input.

    Parameters
    ----------
    outputs : iterable of Path
        Every file a command will write (they need not exist yet).
    inputs : iterable of Path
        Every file or folder it reads (a recording, a folder of images or of
        recordings, an experiment or background file).
    what : str
        The option that names the outputs, for the message.

    Raises
    ------
    InputError
        One line naming the output and the input it would replace or join.
    """
    sources = [Path(p) for p in inputs if Path(p).exists()]
    for output in outputs:
        for source in sources:
            if _same(output, source):
                raise InputError(
                    f"{what} {output.parent}: its {output.name} would replace the input "
                    f"{source}; choose another folder"
                )
            if source.is_dir() and _same(output.parent, source):
                raise InputError(
                    f"{what} {output.parent} is the input folder {source}: "
                    f"{output.name} would join the files read from it; choose another folder"
                )
