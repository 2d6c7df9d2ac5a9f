"""``holoview live`` opens the window on the simulated camera and closes cleanly."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.gui


def test_holoview_live_runs_and_quits(tmp_path: Path) -> None:
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "XDG_CONFIG_HOME": str(tmp_path)}
    experiment = tmp_path / "exp.json"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "holoview",
            "live",
            "--quit-after",
            "2",
            "--experiment",
            str(experiment),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert (tmp_path / "holoview" / "ui.ini").is_file()  # the layout was remembered
    assert experiment.is_file()  # the simulator's optics were adopted and saved


def test_holoview_live_with_a_missing_file_stays_open_and_quits(tmp_path: Path) -> None:
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "XDG_CONFIG_HOME": str(tmp_path)}
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "holoview",
            "live",
            "--source",
            f"replay:{tmp_path / 'no.h5'}",
            "--quit-after",
            "1",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert "cannot start replay" in result.stderr  # logged as a warning, shown in the window


def test_holoview_file_opens_it_in_the_window(tmp_path: Path, hologram_file: Path) -> None:
    """``holoview FILE`` is ``holoview live FILE``: the window opens the file (and keeps it
    among the recent files); a file that is not there is one line, status 2."""
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "XDG_CONFIG_HOME": str(tmp_path)}
    argv = [sys.executable, "-m", "holoview", str(hologram_file), "--quit-after", "1"]
    result = subprocess.run(argv, capture_output=True, text=True, timeout=120, env=env, check=False)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert str(hologram_file) in (tmp_path / "holoview" / "ui.ini").read_text()
    missing = tmp_path / "gone.h5"
    argv = [sys.executable, "-m", "holoview", str(missing)]
    result = subprocess.run(argv, capture_output=True, text=True, timeout=120, env=env, check=False)
    assert result.returncode == 2
    assert result.stderr.strip() == f"holoview live: error: {missing}: no such file or folder"


def test_the_hologram_view_is_built_without_importing_pyplot() -> None:
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
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    result = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["False", "True", "True"], result.stdout
