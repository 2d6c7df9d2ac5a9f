"""GUI test fixtures: per-test settings folder, a replayable hologram stack, a window closer."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from PyQt6.QtCore import QTimer

from .holograms import write_stack


@pytest.fixture(autouse=True)
def _own_config_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Give each GUI test its own QSettings and experiment file (the suite shares one)."""
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))


@pytest.fixture
def hologram_file(tmp_path: Path) -> Path:
    """A 16-frame 256 x 256 TIFF stack of synthetic holograms to replay."""
    return write_stack(tmp_path / "holograms.tif", n=16, shape=(256, 256))


@pytest.fixture
def open_windows(qtbot) -> Iterator[list]:
    """Windows a test opens; closed at the end, and their timers checked stopped."""
    windows: list = []
    yield windows
    for window in windows:
        window.close()
        assert not window.timer.isActive()
        assert window.session is None
        ours = [t for t in window.findChildren(QTimer) if t.objectName().startswith("holoview")]
        assert {t.objectName() for t in ours} >= {"holoview-redraw", "holoview-discovery"}
        assert not [t.objectName() for t in ours if t.isActive()]
