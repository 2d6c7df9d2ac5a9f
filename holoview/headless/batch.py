"""Many recordings in one ``holoview process``: a folder of them, or a glob.

:func:`find_recordings` says whether an input names one recording or many: a glob
pattern (``'runs/*.h5'``, quoted so that the shell leaves it) names the files it
matches; a folder holding recordings (``.h5``/``.hdf5``, videos, ``.npy``/``.npz``)
names those, in natural order. A folder of images is one input, as before.

:func:`process_batch` processes each into its own folder, ``OUT/<name>``, one after
the other, each on the same workers (:mod:`holoview.headless.parallel.runners`, started
once), and writes ``OUT/index.csv``. ``<name>`` is the recording's file name without
its suffix, made safe (:func:`holoview.paths.confined_name`: separators, control and
invisible characters and leading dots become ``_``, so ``...h5`` is ``OUT/__``, never
``OUT/..``; a long name is cut, with a hash); where two recordings give the same name
(compared without regard to case, for file systems that ignore it), the later ones in
the batch's order get ``<name>_2``, ``<name>_3``, ... A recording that fails does not
stop the others. ``OUT`` is locked for the batch (one run at a time, as each
recording's folder is: :mod:`holoview.headless.results.output_folder`).

``index.csv`` describes the folders next to it at every moment: it is rewritten
(under a temporary name, then renamed) after each recording, and each row's figures
are read back from the ``summary.json`` in the recording's folder, whatever run wrote
it. So a batch stopped half-way, or a run whose interruption kept the earlier results,
leaves an index whose rows say what each folder holds. Columns: ``input``, ``out``,
``status`` (what this batch did: ``ok``, ``failed`` with the reason, ``interrupted``,
``not run``), ``message``, ``frames``, ``seconds``, ``results_utc`` (when the results
in the folder were made; empty: the folder holds none), ``fused_rate_m_per_s``,
``fused_rate_stderr_m_per_s``, then for each peak label met in any folder
``rate_<label>_m_per_s`` and ``rate_<label>_stderr_m_per_s`` (empty where a run has no
such peak or no rate). A text cell that begins with ``=``, ``+``, ``-``, ``@``, a tab
or a carriage return (a file name can) gets a ``'`` in front, so that a spreadsheet
shows it as text instead of running it as a formula (OWASP's rule against CSV
injection); numbers are written as they are.
"""

from __future__ import annotations

import contextlib
import csv
import glob
import json
import logging
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from holoview.acquire.frame_file import (
    HDF5_SUFFIXES,
    NUMPY_SUFFIXES,
    VIDEO_SUFFIXES,
    natural_key,
)
from holoview.acquire.replay_files import check_not_results_folder
from holoview.atomic import atomic_path
from holoview.errors import HoloviewError, InputError, OutputError, os_error_text
from holoview.file_kinds import special_file
from holoview.headless.parallel.chunks import plan_jobs
from holoview.headless.parallel.runners import ChunkRunner, open_runner
from holoview.headless.prepare import run_inputs
from holoview.headless.results.output_folder import (
    FolderLock,
    OutputFolder,
    make_folder,
    remove_if_empty,
)
from holoview.headless.run import OUTPUT_NAMES, SUMMARY_JSON, process_file
from holoview.headless.settings import ProcessOptions
from holoview.paths import check_apart, confined_name

logger = logging.getLogger(__name__)

#: The index of a batch, in its output folder.
INDEX_CSV = "index.csv"

#: File suffixes a folder of recordings holds.
RECORDING_SUFFIXES = HDF5_SUFFIXES + VIDEO_SUFFIXES + NUMPY_SUFFIXES

#: First characters that make a spreadsheet read a cell as a formula (OWASP).
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")

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
        if [p.name for p in found] == ["results.h5"]:  # a run's outputs, no recording
            check_not_results_folder(path)
        return sorted(found, key=_natural) or None
    return None


def output_names(recordings: list[Path]) -> list[str]:
    """One folder name per recording (module docs): its stem made safe, ``_2``... where taken."""
    names: list[str] = []
    taken: set[str] = set()
    for recording in recordings:
        base = confined_name(recording.stem, fallback="recording")
        name, k = base, 1
        while name.casefold() in taken:
            k += 1
            name = f"{base}_{k}"
        taken.add(name.casefold())
        names.append(name)
    return names


@dataclass
class BatchRow:
    """One recording of a batch: what this batch did with it, and what its folder holds."""

    input: Path
    out: Path
    status: str = "not run"
    message: str = ""
    frames: int | None = None
    seconds: float | None = None
    results_utc: str = ""
    fused: tuple[float | None, float | None] = (None, None)
    peaks: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)
    #: The failure was an output that could not be written (a full disk): exit status 3.
    output_failed: bool = False
    #: What is wrong with the folder's summary, if anything.
    note: str = ""

    def read_folder(self) -> None:
        """Take the figures from the ``summary.json`` in :attr:`out` (none: empty figures)."""
        self.frames, self.seconds, self.results_utc = None, None, ""
        self.fused, self.peaks, self.note = (None, None), {}, ""
        try:
            document = json.loads((self.out / SUMMARY_JSON).read_text(encoding="utf-8"))
            self.frames = int(document["frames"]["processed"])
            self.seconds = float(document["timing"]["seconds"])
            self.results_utc = str(document.get("created_utc") or "")
            fused = document.get("fused") or {}
            self.fused = (fused.get("rate_m_per_s"), fused.get("rate_stderr_m_per_s"))
            self.peaks = {
                str(label): (entry.get("rate_m_per_s"), entry.get("rate_stderr_m_per_s"))
                for label, entry in (document.get("peaks") or {}).items()
            }
        except FileNotFoundError:
            return
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            self.note = f"its {SUMMARY_JSON} cannot be read ({exc!r})"


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
    return "" if not isinstance(value, int | float) else format(value, ".10g")


def text_cell(text: str) -> str:
    """A text cell of a CSV file that a spreadsheet will not run as a formula (OWASP).

    Examples
    --------
    >>> text_cell("=1+1.h5")
    "'=1+1.h5"
    >>> text_cell("run.h5")
    'run.h5'
    """
    return f"'{text}" if text.startswith(FORMULA_STARTS) else text


def write_index(path: Path, rows: list[BatchRow], *, replace: bool = True) -> None:
    """Write ``index.csv`` (module documentation) under a temporary name, then rename it.

    Parameters
    ----------
    path : Path
        The index.
    rows : list of BatchRow
        One per recording.
    replace : bool
        Replace an index there; False: a no-replace rename.

    Raises
    ------
    OutputError
        It could not be written (:class:`~holoview.atomic.TargetExistsError`: without
        ``replace``, another program created it meanwhile).
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
        "results_utc",
        "fused_rate_m_per_s",
        "fused_rate_stderr_m_per_s",
    ]
    for label in labels:
        header += [f"rate_{label}_m_per_s", f"rate_{label}_stderr_m_per_s"]
    try:
        with (
            atomic_path(path, replace=replace) as temporary,
            open(temporary, "w", newline="", encoding="utf-8", errors="backslashreplace") as f,
        ):
            writer = csv.writer(f, lineterminator="\n")
            writer.writerow(text_cell(cell) for cell in header)
            for row in rows:
                line = [
                    *(text_cell(str(text)) for text in (row.input, row.out, row.status)),
                    text_cell("; ".join(m for m in (row.message, row.note) if m)),
                    "" if row.frames is None else str(row.frames),
                    "" if row.seconds is None else format(row.seconds, ".3f"),
                    text_cell(row.results_utc),
                    _number(row.fused[0]),
                    _number(row.fused[1]),
                ]
                for label in labels:
                    rate, stderr = row.peaks.get(label, (None, None))
                    line += [_number(rate), _number(stderr)]
                writer.writerow(line)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {os_error_text(exc)}") from exc


class _Index:
    """``index.csv`` rewritten after each recording; a stale one never outlives a failed write."""

    def __init__(self, path: Path, rows: list[BatchRow], *, replace: bool) -> None:
        self.path = path
        self.rows = rows
        self._replace = replace  # False until this batch has written it (no-replace first)
        self.error: OutputError | None = None

    def publish(self) -> None:
        """Write the index from the rows; on failure remove the old one (it would mislead)."""
        try:
            write_index(self.path, self.rows, replace=self._replace)
        except OutputError as exc:
            self.error = exc
            if self._replace:
                self.path.unlink(missing_ok=True)
            logger.warning("%s", exc)
            return
        self._replace = True
        self.error = None


def _check_folders(out: Path, rows: list[BatchRow], options: ProcessOptions) -> None:
    """Refuse, before anything runs, earlier results (without overwrite) and inputs as outputs."""
    index = out / INDEX_CSV
    overwrite = options.overwrite
    if index.exists() and not overwrite:
        raise InputError(
            f"--out {out} holds the index of an earlier batch ({INDEX_CSV}); give "
            "--overwrite to replace it when this batch completes, or another folder"
        )
    inputs = [
        path for row in rows for path in run_inputs(row.input, options.choice, options.settings)
    ]
    check_apart([index], inputs)
    for row in rows:
        OutputFolder(row.out, OUTPUT_NAMES, overwrite=overwrite, inputs=inputs)


def _attempt(
    row: BatchRow,
    runner: ChunkRunner | None,
    options: ProcessOptions,
    progress: Callable[[int, int], None] | None,
) -> bool:
    """Process one recording into its row (status, message); True when the batch must stop."""
    try:
        outcome = process_file(row.input, row.out, options, progress=progress, runner=runner)
    except HoloviewError as exc:
        row.status, row.message = "failed", str(exc)
        row.output_failed = isinstance(exc, OutputError)
        logger.warning("%s: %s", row.input, exc)  # the command prints it again at the end
        return False
    except KeyboardInterrupt:
        row.status, row.message = "interrupted", "stopped before its results were written"
        return True
    if not outcome.data.interrupted:
        row.status = "ok"
        return False
    row.status = "interrupted"
    if not outcome.files:
        row.message = "stopped; the results already in its folder are kept"
    return True


def process_batch(
    recordings: list[Path],
    out: str | Path,
    options: ProcessOptions,
    *,
    progress: Callable[[int, int], None] | None = None,
) -> BatchOutcome:
    """Process every recording into ``out/<name>`` and write ``out/index.csv``.

    Parameters
    ----------
    recordings : list of Path
        From :func:`find_recordings`.
    out : str or Path
        The batch's folder (created if missing).
    options : ProcessOptions
        Each recording's (:func:`~holoview.headless.run.process_file`); the workers
        (``jobs``, ``scheduler``) are started once for the whole batch, and
        ``overwrite`` replaces earlier results (each recording's, and the index).
    progress : callable, optional
        ``progress(done, total)`` within each recording.

    Returns
    -------
    BatchOutcome
        Failed recordings are rows with status ``failed``; after an interruption the
        rows not reached are ``not run``.

    Raises
    ------
    InputError
        Earlier results in the folders without ``overwrite``, an output that is an
        input, a folder another run holds, bad ``jobs``, or a scheduler that does not
        answer (before anything runs).
    OutputError
        The index could not be written (a stale index is removed).
    """
    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise InputError(f"--out {folder} is a file, not a folder")
    rows = [
        BatchRow(input=r, out=folder / name)
        for r, name in zip(recordings, output_names(recordings), strict=True)
    ]
    _check_folders(folder, rows, options)
    interrupted = False
    created = make_folder(folder)
    index = _Index(folder / INDEX_CSV, rows, replace=options.overwrite)
    try:
        with contextlib.ExitStack() as stack:
            stack.enter_context(FolderLock(folder))
            runner: ChunkRunner | None = None
            workers = plan_jobs(options.jobs, _LONG, "hdf5")
            if workers > 1 or options.scheduler is not None:
                runner = stack.enter_context(open_runner(workers, options.scheduler))
            for row in rows:
                row.read_folder()
            for k, row in enumerate(rows):
                logger.info("recording %d of %d: %s", k + 1, len(rows), row.input)
                try:
                    interrupted = _attempt(row, runner, options, progress)
                finally:
                    row.read_folder()
                    index.publish()
                if interrupted:
                    break
    finally:
        remove_if_empty(created)
    if index.error is not None:
        raise index.error
    return BatchOutcome(tuple(rows), index.path, interrupted)
