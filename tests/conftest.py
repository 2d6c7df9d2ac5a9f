"""Suite-wide fixtures: Qt offscreen, isolated settings and caches, no leaked threads."""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

# A suite started in the background of a script (``bash test.sh &``) inherits SIGINT
# ignored, and holoview keeps an ignored stop signal ignored, as nohup expects; the tests
# of Ctrl+C need it as a terminal delivers it, in this process and in the children it starts.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

#: The real holograms shared with the project (MIT licence; see their README).
REAL_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"


@pytest.fixture(autouse=True)
def _isolated_user_dirs(
    tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Keep caches (FFT wisdom) and settings of every test out of the user's home."""
    root = tmp_path_factory.getbasetemp()
    monkeypatch.setenv("HOLOVIEW_CACHE_DIR", str(root / "cache"))
    monkeypatch.setenv("XDG_CONFIG_HOME", str(root / "config"))


@pytest.fixture(autouse=True)
def _no_leaked_threads() -> Iterator[None]:
    """Fail a test that leaves a holoview thread running (threads are named ``holoview-*``)."""
    before = set(threading.enumerate())
    yield
    deadline = time.monotonic() + 2.0
    while True:
        leaked = [
            t
            for t in threading.enumerate()
            if t not in before and t.name.startswith("holoview") and t.is_alive()
        ]
        if not leaked or time.monotonic() > deadline:
            break
        time.sleep(0.02)
    assert not leaked, f"threads outlived the test: {[t.name for t in leaked]}"


@pytest.fixture(autouse=True)
def _garbage_between_events(request: pytest.FixtureRequest) -> Iterator[None]:
    """In a Qt test, collect cyclic garbage as the window does: on the GUI thread between
    events (:mod:`holoview.ui.garbage`), the test's own widgets once it has closed them."""
    if "qtbot" not in request.fixturenames:
        yield
        return
    from holoview.ui.garbage import collect_between_events

    with collect_between_events(request.getfixturevalue("qapp")):
        yield


@pytest.fixture
def real_data() -> Path:
    """The folder of real holograms; skips with the reason when it is not beside the repo."""
    if not REAL_DATA.is_dir():
        pytest.skip(f"real holograms not found at {REAL_DATA}")
    return REAL_DATA


#: Travelling waves on 1 mm of water with a flow, as a simulated recording: a bench with
#: carriers far apart; the waves feel the bottom (k d from 0.15 to 1.5, so the depth is
#: fitted too); 160 frames of 128 x 128 pixels of 320 um (a 41 mm field) at 250 frames/s,
#: small enough for the live and window tests of the Waves panel to take seconds.
TRAVELLING_WAVES = [
    *("--size", "128", "--pixel-pitch-um", "320", "--depth-mm", "1"),
    *("--m-r-mrad", "0.4", "0.025", "--m-b-mrad", "0.025", "0.3", "--reflectivity", "0.1"),
    *("--scenario", "travelling", "--frames", "160", "--fps", "250", "--seed", "5"),
    *("--wave-k", "150", "1500", "--wave-components", "120", "--flow-mm-per-s", "20", "10"),
    *("--wave-start-s", "0.002", "--wave-rise-s", "0.01", "--no-truth-maps"),
]


@pytest.fixture(scope="session")
def travelling_waves(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A recording of :data:`TRAVELLING_WAVES` with its truth (``/truth/waves``), made once."""
    from holoview.cli import main

    path = tmp_path_factory.mktemp("travelling") / "travelling.h5"
    assert main(["-q", "simulate", str(path), *TRAVELLING_WAVES]) == 0
    return path
