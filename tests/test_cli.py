"""The ``holoview`` entry point: version, info, usage errors, logging flags."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from holoview import __version__
from holoview.cli import main


def run_cli(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``python -m holoview ARGS`` in a child process and capture its output."""
    return subprocess.run(
        [sys.executable, "-m", "holoview", *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        check=False,
    )


def test_version_prints_package_version() -> None:
    result = run_cli("--version")
    assert result.returncode == 0
    assert result.stdout.strip() == f"holoview {__version__}"


def test_info_names_every_component_and_aravis_status() -> None:
    result = run_cli("info")
    assert result.returncode == 0, result.stderr
    names = [line.split("  ")[0].strip() for line in result.stdout.splitlines()]
    for name in (
        "Python",
        "Qt",
        "PyQt6",
        "pyqtgraph",
        "numpy",
        "pyFFTW",
        "h5py",
        "OpenCV",
        "GenICam (Aravis)",
    ):
        assert name in names
    aravis = next(line for line in result.stdout.splitlines() if line.startswith("GenICam"))
    assert aravis.split("  ", 1)[1].strip().startswith(("yes: Aravis 0.8", "no: "))
    assert "not importable" not in result.stdout.replace(aravis, "")


@pytest.mark.parametrize("argv", [["nonsense"], ["live", "--bogus"], ["-v", "-q", "info"]])
def test_usage_error_is_one_line_exit_2(argv: list[str]) -> None:
    result = run_cli(*argv)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("holoview: error:")
    assert "Traceback" not in result.stderr


def test_live_without_display_says_how_to_run_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM"):
        monkeypatch.delenv(name, raising=False)
    assert main([]) == 2
    err = capsys.readouterr().err
    assert "xvfb-run -a holoview" in err and "holoview process" in err


@pytest.mark.parametrize("where", ["before", "after"])
@pytest.mark.parametrize("command", ["record", "simulate"])
def test_quiet_and_verbose_before_or_after_the_subcommand(
    tmp_path, where: str, command: str
) -> None:
    args = [command, str(tmp_path / "o.h5"), "--frames", "3"]
    if command == "simulate":
        args += ["--size", "64"]
    quiet = run_cli(*(["-q", *args] if where == "before" else [*args, "-q"]))
    assert quiet.returncode == 0, quiet.stderr
    assert quiet.stderr == ""
    (tmp_path / "o.h5").unlink()
    verbose = run_cli(*(["-v", *args] if where == "before" else [*args, "-v"]))
    assert verbose.returncode == 0, verbose.stderr
    assert " INFO holoview." in verbose.stderr


def test_every_command_spells_the_optics_the_same_way() -> None:
    from holoview.cli import build_parser

    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    for name in ("live", "record", "simulate", "process", "peaks"):
        options = {o for a in commands[name]._actions for o in a.option_strings}
        assert {"--wavelength-nm", "--pixel-pitch-um", "--n1", "--n2", "--fluid"} <= options, name
        assert {"-q", "-v"} <= options, name
        assert "--wavelength" not in options and "--pixel-pitch" not in options, name


def test_the_commands_and_the_window_start_without_scipy_stats() -> None:
    """scipy.stats takes a second to import (its distributions' docstrings): the noise
    floors' chi-square median is computed without it, and nothing a command or the live
    window imports at start brings it in."""
    code = (
        "import sys\n"
        "import holoview.cli.process, holoview.headless.run, holoview.live.session\n"
        "import holoview.ui.main_window\n"
        "print('scipy.stats' in sys.modules)\n"
    )
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    assert done.stdout.strip() == "False", done.stdout + done.stderr


@pytest.mark.parametrize("given", [None, "2"])
def test_the_commands_run_blas_on_one_thread_unless_told(given: str | None) -> None:
    """OpenBLAS's pool only spun beside the small products (bench_process: +29 % a frame)."""
    code = (
        "import os, sys\n"
        "from holoview.cli import main\n"
        "main(['--version'])\n"
        "assert 'numpy' in sys.modules\n"
        "print(os.environ['OPENBLAS_NUM_THREADS'], len(os.listdir('/proc/self/task')))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    setting, threads = done.stdout.split()[-2:]
    assert setting == (given or "1")
    if given is None:
        assert threads == "1"  # no BLAS thread beside the main one


@pytest.mark.parametrize(
    ("raised", "said"),
    [
        # a bare MemoryError is true in a boolean context: its empty message was printed
        # as "not enough memory ()" before the fallback was taken from its text
        (MemoryError(), "not enough memory (an array too large)"),
        (MemoryError("Unable to allocate 8 GiB"), "not enough memory (Unable to allocate 8 GiB)"),
    ],
)
def test_out_of_memory_is_one_line_exit_2(
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    raised: MemoryError,
    said: str,
) -> None:
    import holoview.cli.info

    def run(args: object) -> int:
        raise raised

    monkeypatch.setattr(holoview.cli.info, "run", run)
    assert main(["info"]) == 2
    err = capsys.readouterr().err
    assert said in err and err.count("\n") == 1
