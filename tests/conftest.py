"""Suite-wide fixtures: Qt offscreen, isolated settings and caches, no leaked threads."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

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


@pytest.fixture
def real_data() -> Path:
    """The folder of real holograms; skips with the reason when it is not beside the repo."""
    if not REAL_DATA.is_dir():
        pytest.skip(f"real holograms not found at {REAL_DATA}")
    return REAL_DATA
