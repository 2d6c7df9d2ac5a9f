"""The output folder of ``holoview process``: what it may replace, and when.

Policy
------
- A folder that already holds the results of a run (any of ``trends.csv``,
  ``summary.json``, ``results.h5``, ``report.png``) is refused, one line and exit
  status 2, unless ``--overwrite`` is given; then the command says, before it starts,
  which files it will replace and whose run they are (the earlier ``summary.json``'s
  input and time). Other files in the folder are never touched.
- Every output is written under a hidden temporary name in the folder
  (:mod:`holoview.atomic`) and renamed only when the run is complete, one after the
  other. A run that fails (an unreadable frame, a full disk, a bug) or is stopped
  before it ends (Ctrl-C, SIGTERM, SIGHUP) removes its temporary files and leaves the
  folder as it was.
- A run interrupted after some frames writes the results of the frames done, marked
  as such (``summary.json``: ``input.interrupted``; ``results.h5``: the root attribute
  ``interrupted``; the report's title), exit status 130, but only into a folder that
  held no earlier results: partial results never replace complete ones. Into a folder
  that did, the earlier results are kept and the partial ones are dropped, and the
  command says so.
- With ``--overwrite``, earlier outputs this run does not write again are removed
  once its own are in place, so that the folder never mixes two runs.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Sequence
from pathlib import Path

from holoview.atomic import OutputSet
from holoview.errors import InputError, os_error_text

logger = logging.getLogger(__name__)


def _earlier_run(folder: Path, names: Sequence[str]) -> str:
    """``", from the run of TIME on INPUT"`` as the earlier summary says (or ``""``)."""
    summary = folder / "summary.json"
    if "summary.json" not in names or not summary.is_file():
        return ""
    try:
        document = json.loads(summary.read_text(encoding="utf-8"))
        when = document.get("created_utc") or "?"
        source = Path(str(document.get("input", {}).get("path", "?"))).name
    except (OSError, ValueError, AttributeError):
        return ""
    return f", from the run of {when} on {source}"


class OutputFolder(OutputSet):
    """The output folder of one run, its policy checked at construction (module docs).

    Parameters
    ----------
    folder : Path
        The folder (created by :meth:`create` if missing).
    names : sequence of str
        The file names a run writes there.
    overwrite : bool
        Replace the results of an earlier run.

    Raises
    ------
    InputError
        The folder is a file, or holds an earlier run's results and ``overwrite`` is
        False.

    Attributes
    ----------
    earlier : list of str
        The outputs already in the folder (replaced when this run completes).
    """

    def __init__(self, folder: Path, names: Sequence[str], *, overwrite: bool) -> None:
        super().__init__(folder)
        self.names = tuple(names)
        if folder.exists() and not folder.is_dir():
            raise InputError(f"--out {folder} is a file, not a folder")
        self.earlier = [name for name in self.names if (folder / name).exists()]
        if self.earlier:
            what = f"{', '.join(self.earlier)}{_earlier_run(folder, self.earlier)}"
            if not overwrite:
                raise InputError(
                    f"--out {folder} holds the results of an earlier run ({what}); give "
                    "--overwrite to replace them when this run completes, or another folder"
                )
            logger.warning("%s: replacing %s when this run completes", folder, what)

    def create(self) -> None:
        """Create the folder (and its parents) if missing."""
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(
                f"--out {self.folder}: cannot create the folder ({os_error_text(exc)})"
            ) from exc

    def finish(self, *, interrupted: bool) -> list[Path]:
        """Put the run's files in place; return them (empty: earlier results kept).

        Parameters
        ----------
        interrupted : bool
            The run was stopped early: its partial results replace no earlier ones.

        Raises
        ------
        OutputError
            A file could not be flushed or renamed (nothing more is replaced).
        """
        if interrupted and self.earlier:
            logger.info("interrupted: the earlier results in %s are kept", self.folder)
            self.discard()
            return []
        written = self.commit()
        for name in self.earlier:
            stale = self.folder / name
            if stale not in written:
                stale.unlink(missing_ok=True)
        return written
