"""A stop between an auto ``--maps`` run's passes keeps the series of every frame, no maps.

The passes of an auto run (:mod:`holoview.headless.run_passes`): the series, the naming,
the displacements (the spread pass, in this process), the maps. A Ctrl-C lands where the
run is: here it is raised (as Python raises it between two bytecodes) when the run logs
the step the stop is meant for, in one process and on two worker processes.
Before: a stop in the naming, the spread pass or before the maps pass's first chunk was
raised out of the run, exit 130 and nothing written, although every frame's series was
done (``test_sigterm_stops_the_workers_and_keeps_the_frames_done``, now and then).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator
from pathlib import Path

import h5py
import pytest
from headless_sim import Simulated

from holoview.headless.parallel.runners import ChunkRunner, ProcessRunner
from holoview.headless.run import ProcessOutcome, process_file
from holoview.headless.settings import PeakChoice, ProcessOptions, ProcessSettings

#: Where the stop lands: at the record starting with this text that follows as many of
#: them since the naming's "PCA over" (that record included).
WHERE = {
    "naming": ("PCA over", 0),
    "spread pass": ("probing", 1),  # its carrier probe, after its maps step's
    "before the first maps": ("demodulating", 1),  # the maps pass's, after the spread's
}


class _StopAt(logging.Handler):
    """Raise KeyboardInterrupt once, at the record starting with ``text`` that follows
    ``count`` of them since the naming's PCA."""

    def __init__(self, text: str, count: int) -> None:
        super().__init__(logging.DEBUG)
        self.text, self.count = text, count
        self.named = self.fired = False
        self.seen = 0

    def emit(self, record: logging.LogRecord) -> None:
        message = record.getMessage()
        if message.startswith("PCA over"):
            self.named = True
        if self.fired or not self.named or not message.startswith(self.text):
            return
        self.seen += 1
        if self.seen > self.count:
            self.fired = True
            raise KeyboardInterrupt


@pytest.fixture(scope="module")
def two_workers() -> Iterator[ChunkRunner]:
    with ProcessRunner(2) as runner:
        yield runner


def _run(path: Path, out: Path, runner: ChunkRunner | None) -> ProcessOutcome:
    options = ProcessOptions(
        choice=PeakChoice(auto=4), settings=ProcessSettings(maps=True), report=False
    )
    return process_file(path, out, options, runner=runner)


@pytest.mark.slow
@pytest.mark.parametrize("jobs", [1, 2])
@pytest.mark.parametrize("where", list(WHERE))
def test_a_stop_after_the_series_keeps_every_frame_and_no_maps(
    where: str,
    jobs: int,
    evaporation: Simulated,
    two_workers: ChunkRunner,
    tmp_path: Path,
) -> None:
    """The series of every frame, as the whole run's, marked interrupted; no ``/maps``."""
    runner = two_workers if jobs == 2 else None
    whole = _run(evaporation.path, tmp_path / "whole", runner)
    stop = _StopAt(*WHERE[where])
    root = logging.getLogger("holoview")
    level = root.level
    root.addHandler(stop)
    root.setLevel(logging.DEBUG)
    try:
        cut = _run(evaporation.path, tmp_path / "cut", runner)
    finally:
        root.removeHandler(stop)
        root.setLevel(level)
    assert stop.fired, f"the run logged no {WHERE[where]} after its naming"
    assert cut.data.interrupted and cut.data.maps_dropped
    assert len(cut.data.frames) == evaporation.frames
    assert (cut.out / "trends.csv").read_bytes() == (whole.out / "trends.csv").read_bytes()
    assert [p.label for p in cut.analysis.peaks] == [p.label for p in whole.analysis.peaks]
    summary = json.loads((cut.out / "summary.json").read_text())
    assert summary["input"]["interrupted"] is True
    assert summary["frames"]["processed"] == evaporation.frames
    assert any("results.h5 holds none" in note for note in summary["notes"])
    with h5py.File(cut.out / "results.h5", "r") as f:
        assert bool(f.attrs["interrupted"]) is True
        assert "maps" not in f
        assert f["trends/frame"].shape[0] == evaporation.frames
    with h5py.File(whole.out / "results.h5", "r") as f:
        assert f["maps"][next(iter(f["maps"]))].shape[0] == evaporation.frames
