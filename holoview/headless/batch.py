"""Many recordings in one ``holoview process``: a folder of them, or a glob.

:func:`find_recordings` says whether an input names one recording or many: a glob
pattern (``'runs/*.h5'``, quoted so that the shell leaves it) names the files it
matches; a folder holding recordings (``.h5``/``.hdf5``, videos, ``.npy``/``.npz``)
names those, in natural order. A folder of images is one input, as before.

:func:`process_batch` processes each into its own folder, ``OUT/<name>`` (the
recording's file name without its suffix; ``<name>_2``, ... where two share one),
one after the other, each on the same workers (:mod:`holoview.headless.parallel`,
started once), and writes ``OUT/index.csv``: one row per recording, its status
(``ok``, ``failed`` with the reason, ``interrupted``), frames, seconds, and the
fused rate and each peak's rate with their standard errors (m/s), under a temporary
name, renamed when complete. A recording that fails does not stop the others.

``index.csv`` columns: ``input``, ``out``, ``status``, ``message``, ``frames``,
``seconds``, ``fused_rate_m_per_s``, ``fused_rate_stderr_m_per_s``, then for each
peak label met in any run ``rate_<label>_m_per_s`` and ``rate_<label>_stderr_m_per_s``
(empty where a run has no such peak or no rate).
"""

from __future__ import annotations

import contextlib
import csv
import glob
import logging
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from holoview.acquire.replay_files import (
    HDF5_SUFFIXES,
    NUMPY_SUFFIXES,
    VIDEO_SUFFIXES,
    natural_key,
)
from holoview.atomic import atomic_path
from holoview.errors import HoloviewError, InputError, OutputError, os_error_text
from holoview.file_kinds import special_file
from holoview.headless.chunks import plan_jobs
from holoview.headless.output_folder import OutputFolder
from holoview.headless.parallel import ChunkRunner, open_runner
from holoview.headless.run import OUTPUT_NAMES, process_file

logger = logging.getLogger(__name__)

#: The index of a batch, in its output folder.
INDEX_CSV = "index.csv"

#: File suffixes a folder of recordings holds.
RECORDING_SUFFIXES = HDF5_SUFFIXES + VIDEO_SUFFIXES + NUMPY_SUFFIXES

_GLOB = re.compile(r"[*?\[]")

#: Frames a batch's workers are planned for when ``--jobs`` is not given (no length known).
_LONG = 1 << 40


def _natural(path: Path) -> tuple[list[object], str]:
    """Sort key: ``run2`` before ``run10``, ``run`` before ``run2`` (the stem, then the suffix)."""
    return natural_key(path.stem), path.suffix.lower()


def _is_entry(path: Path) -> bool:
    """A file a batch takes: a regular file, or a FIFO, device or broken link (a failed row)."""
    return path.is_file() or special_file(path, folder_ok=False) not in (None, "a folder")


def find_recordings(spec: str | Path) -> list[Path] | None:
    """The recordings ``spec`` names, or None when it names one input.

    Entries that are no regular file (a broken symbolic link, a FIFO, a device) are
    named too: each becomes a failed row of the batch, never opened, never dropped.

    Raises
    ------
    InputError
        A pattern that matches no file.
    """
    text = str(spec)
    path = Path(text)
    if not path.exists() and not path.is_symlink() and _GLOB.search(text):
        found = sorted((Path(p) for p in glob.glob(text) if _is_entry(Path(p))), key=_natural)
        if not found:
            raise InputError(f"{text}: no file matches")
        return found
    if path.is_dir():
        found = [
            p
            for p in path.iterdir()
            if not p.name.startswith(".")
            and p.suffix.lower() in RECORDING_SUFFIXES
            and _is_entry(p)
        ]
        return sorted(found, key=_natural) or None
    return None


def output_names(recordings: list[Path]) -> list[str]:
    """One folder name per recording: its stem, ``_2``, ``_3``... added where stems repeat."""
    names: list[str] = []
    taken: set[str] = set()
    for recording in recordings:
        name, k = recording.stem or "recording", 1
        while name in taken:
            k += 1
            name = f"{recording.stem}_{k}"
        taken.add(name)
        names.append(name)
    return names


@dataclass
class BatchRow:
    """One recording of a batch: where its results went and what came out."""

    input: Path
    out: Path
    status: str = "not run"
    message: str = ""
    frames: int = 0
    seconds: float = 0.0
    fused: tuple[float | None, float | None] = (None, None)
    peaks: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)


@dataclass(frozen=True)
class BatchOutcome:
    """What a batch produced: a row per recording, and the index file."""

    rows: tuple[BatchRow, ...]
    index: Path
    interrupted: bool

    @property
    def failed(self) -> list[BatchRow]:
        """The rows of the recordings that failed."""
        return [r for r in self.rows if r.status == "failed"]


def _number(value: float | None) -> str:
    return "" if value is None else format(value, ".10g")


def write_index(path: Path, rows: list[BatchRow]) -> None:
    """Write ``index.csv`` (module documentation) under a temporary name, then rename it.

    Raises
    ------
    OutputError
        It could not be written.
    """
    labels: list[str] = []
    for row in rows:
        labels += [label for label in row.peaks if label not in labels]
    header = [
        "input",
        "out",
        "status",
        "message",
        "frames",
        "seconds",
        "fused_rate_m_per_s",
        "fused_rate_stderr_m_per_s",
    ]
    for label in labels:
        header += [f"rate_{label}_m_per_s", f"rate_{label}_stderr_m_per_s"]
    try:
        with (
            atomic_path(path) as temporary,
            open(temporary, "w", newline="", encoding="utf-8") as f,
        ):
            writer = csv.writer(f, lineterminator="\n")
            writer.writerow(header)
            for row in rows:
                line = [
                    str(row.input),
                    str(row.out),
                    row.status,
                    row.message,
                    str(row.frames),
                    format(row.seconds, ".3f"),
                    _number(row.fused[0]),
                    _number(row.fused[1]),
                ]
                for label in labels:
                    rate, stderr = row.peaks.get(label, (None, None))
                    line += [_number(rate), _number(stderr)]
                writer.writerow(line)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {os_error_text(exc)}") from exc


def _check_folders(out: Path, rows: list[BatchRow], overwrite: bool) -> None:
    """Refuse, before anything runs, output folders holding earlier results."""
    index = out / INDEX_CSV
    if index.exists() and not overwrite:
        raise InputError(
            f"--out {out} holds the index of an earlier batch ({INDEX_CSV}); give "
            "--overwrite to replace it when this batch completes, or another folder"
        )
    for row in rows:
        OutputFolder(row.out, OUTPUT_NAMES, overwrite=overwrite)


def process_batch(
    recordings: list[Path],
    out: str | Path,
    *,
    progress: Callable[[int, int], None] | None = None,
    jobs: int | None = None,
    scheduler: str | None = None,
    overwrite: bool = False,
    **options: Any,
) -> BatchOutcome:
    """Process every recording into ``out/<name>`` and write ``out/index.csv``.

    Parameters
    ----------
    recordings : list of Path
        From :func:`find_recordings`.
    out : str or Path
        The batch's folder (created if missing).
    progress : callable, optional
        ``progress(done, total)`` within each recording.
    jobs, scheduler : optional
        As for :func:`~holoview.headless.run.process_file`; the workers are started
        once for the whole batch.
    overwrite : bool
        Replace earlier results (each recording's, and the index).
    **options
        Passed to :func:`~holoview.headless.run.process_file` (``choice``,
        ``optics_options``, ``settings``, ``frames``, ``report``).

    Returns
    -------
    BatchOutcome
        Failed recordings are rows with status ``failed``; after an interruption the
        rows not reached are ``not run``.

    Raises
    ------
    InputError
        Earlier results in the folders without ``overwrite``, bad ``jobs``, or a
        scheduler that does not answer (before anything runs).
    OutputError
        The index could not be written.
    """
    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise InputError(f"--out {folder} is a file, not a folder")
    rows = [
        BatchRow(input=r, out=folder / name)
        for r, name in zip(recordings, output_names(recordings), strict=True)
    ]
    _check_folders(folder, rows, overwrite)
    interrupted = False
    with contextlib.ExitStack() as stack:
        runner: ChunkRunner | None = None
        workers = plan_jobs(jobs, _LONG, "hdf5")
        if workers > 1 or scheduler is not None:
            runner = stack.enter_context(open_runner(workers, scheduler))
        for k, row in enumerate(rows):
            logger.info("recording %d of %d: %s", k + 1, len(rows), row.input)
            try:
                outcome = process_file(
                    row.input,
                    row.out,
                    progress=progress,
                    overwrite=overwrite,
                    runner=runner,
                    **options,
                )
            except HoloviewError as exc:
                row.status, row.message = "failed", str(exc)
                logger.error("%s: %s", row.input, exc)
                continue
            except KeyboardInterrupt:
                interrupted = True
                break
            data, analysis = outcome.data, outcome.analysis
            row.status = "interrupted" if data.interrupted else "ok"
            row.frames, row.seconds = len(data.frames), data.wall_seconds
            if analysis.fit is not None:
                row.fused = (analysis.fit.rate, analysis.fit.stderr)
            row.peaks = {p.label: (p.rate, p.rate_stderr) for p in analysis.peaks}
            if data.interrupted:
                interrupted = True
                break
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create {folder}: {os_error_text(exc)}") from exc
    index = folder / INDEX_CSV
    write_index(index, rows)
    return BatchOutcome(tuple(rows), index, interrupted)
