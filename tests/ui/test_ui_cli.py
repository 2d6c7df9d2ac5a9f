"""``holoview live`` opens the window on the simulated camera and closes cleanly."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.gui


def _python(config: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """Run ``python ARGS`` to its end, Qt offscreen, its settings under ``config``."""
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "XDG_CONFIG_HOME": str(config)}
    return subprocess.run(
        [sys.executable, *args], capture_output=True, text=True, timeout=120, env=env, check=False
    )


def test_holoview_live_runs_and_quits(tmp_path: Path) -> None:
    experiment = tmp_path / "exp.json"
    result = _python(
        tmp_path, "-m", "holoview", "live", "--quit-after", "2", "--experiment", str(experiment)
    )
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert (tmp_path / "holoview" / "ui.ini").is_file()  # the layout was remembered
    assert experiment.is_file()  # the simulator's optics were adopted and saved


def test_holoview_live_with_a_missing_file_stays_open_and_quits(tmp_path: Path) -> None:
    replay = f"replay:{tmp_path / 'no.h5'}"
    result = _python(tmp_path, "-m", "holoview", "live", "--source", replay, "--quit-after", "1")
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert "cannot start replay" in result.stderr  # logged as a warning, shown in the window


def test_holoview_file_opens_it_in_the_window(tmp_path: Path, hologram_file: Path) -> None:
    """``holoview FILE`` is ``holoview live FILE``: the window opens the file (and keeps it
    among the recent files); a file that is not there is one line, status 2."""
    result = _python(tmp_path, "-m", "holoview", str(hologram_file), "--quit-after", "1")
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert str(hologram_file) in (tmp_path / "holoview" / "ui.ini").read_text()
    missing = tmp_path / "gone.h5"
    result = _python(tmp_path, "-m", "holoview", str(missing))
    assert result.returncode == 2
    assert result.stderr.strip() == f"holoview live: error: {missing}: no such file or folder"


def test_the_hologram_view_is_built_without_importing_pyplot(tmp_path: Path) -> None:
    """The levels' gradient menu lists matplotlib's maps by category without importing
    ``matplotlib.pyplot`` (1.4 s of each window's start); pyqtgraph's own listing is
    restored afterwards. In a fresh process: this one may hold pyplot already."""
    code = (
        "import sys\n"
        "import pyqtgraph.widgets.ColorMapMenu as menus\n"
        "listing = menus.find_mpl_leftovers\n"
        "from holoview.ui.app import application\n"
        "app = application()\n"
        "from holoview.ui.hologram_view import HologramView\n"
        "view = HologramView()\n"
        "titles = [action.text() for action in view.histogram.gradient.menu.actions()]\n"
        "print('matplotlib.pyplot' in sys.modules, 'matplotlib' in titles,"
        " menus.find_mpl_leftovers is listing)\n"
    )
    result = _python(tmp_path, "-c", code)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["False", "True", "True"], result.stdout
