"""The layering rule: cli > ui > headless | live > engine > acquire | processing > optics,
and no package but ui (and the cli above it) imports Qt.

Checked twice: by the import-linter contracts in pyproject.toml (whose power to fail
is itself tested on planted violations), and at run time by importing every module
of the Qt-free packages in a fresh interpreter and looking for Qt in ``sys.modules``.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")
QT_MODULES = ("PyQt6", "PyQt5", "PySide6", "PySide2", "pyqtgraph")


def lint_imports(root: Path) -> subprocess.CompletedProcess[str]:
    """Run import-linter with the project's contracts over the package under ``root``."""
    return subprocess.run(
        [str(LINT_IMPORTS), "--config", str(root / "pyproject.toml"), "--no-cache"],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"},
    )


def test_contracts_hold() -> None:
    result = lint_imports(REPO)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "BROKEN" not in result.stdout


def test_contract_catches_qt_import_in_processing(tmp_path: Path) -> None:
    shutil.copytree(
        REPO / "holoview", tmp_path / "holoview", ignore=shutil.ignore_patterns("__pycache__")
    )
    shutil.copy(REPO / "pyproject.toml", tmp_path)
    (tmp_path / "holoview" / "processing" / "sneaky.py").write_text("from PyQt6 import QtCore\n")
    result = lint_imports(tmp_path)
    assert result.returncode != 0
    assert "holoview.processing.sneaky" in result.stdout


def test_contract_catches_engine_importing_live(tmp_path: Path) -> None:
    shutil.copytree(
        REPO / "holoview", tmp_path / "holoview", ignore=shutil.ignore_patterns("__pycache__")
    )
    shutil.copy(REPO / "pyproject.toml", tmp_path)
    (tmp_path / "holoview" / "engine" / "upward.py").write_text(
        "from holoview.live import session\n"
    )
    result = lint_imports(tmp_path)
    assert result.returncode != 0
    assert "holoview.engine.upward" in result.stdout


LIBRARY_PACKAGES = (
    "holoview.processing",
    "holoview.optics",
    "holoview.acquire",
    "holoview.engine",
    "holoview.live",
    "holoview.headless",
)


def test_no_qt_loaded_by_library_packages() -> None:
    code = (
        "import importlib, pkgutil, sys\n"
        f"for pkg in {LIBRARY_PACKAGES!r}:\n"
        "    mod = importlib.import_module(pkg)\n"
        "    for info in pkgutil.walk_packages(mod.__path__, pkg + '.'):\n"
        "        importlib.import_module(info.name)\n"
        f"print(sorted(m for m in sys.modules if m.split('.')[0] in {QT_MODULES!r}))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


def test_processing_a_recording_does_not_import_dask() -> None:
    """pyFFTW's Dask interface is left out (1.4-1.9 s of every command); Dask still works."""
    code = (
        "import sys\n"
        "from holoview.processing.maps.demodulate import Demodulator\n"
        "from holoview.headless.run import process_file\n"
        "print('dask' in sys.modules)\n"
        "import dask.array as da, numpy as np, pyfftw.interfaces.numpy_fft as f\n"
        "print(float(da.ones(8).sum().compute()), round(float(abs(f.fft(np.ones(4))[0])), 3))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["False", "8.0", "4.0"]
