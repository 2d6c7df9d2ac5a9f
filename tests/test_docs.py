"""The documentation: a command reference that matches the parsers, a repository that
names no file outside itself, a short README.

The site itself is built with warnings as errors by ``scripts/test.sh``
(``mkdocs build --strict``): broken links and anchors, pages missing from the nav and
docstrings the API pages cannot read fail there.
"""

from __future__ import annotations

import importlib.util
import re
import subprocess
from pathlib import Path

import pytest

from holoview.cli import COMMANDS, build_parser
from holoview.cli.reference import command_reference, option_strings

REPO = Path(__file__).resolve().parents[1]


def test_every_command_and_option_is_in_the_reference() -> None:
    parser = build_parser()
    reference = command_reference(parser)
    options = option_strings(parser)
    assert set(options) == {"", *COMMANDS}
    for command, strings in options.items():
        if command:
            assert f"## holoview {command}\n" in reference
            section = reference.split(f"## holoview {command}\n", 1)[1].split("\n## ", 1)[0]
        else:
            section = reference.split("\n## holoview ", 1)[0]
        for option in strings:
            if option in ("-h", "--help"):
                continue
            assert re.search(rf"[`,] ?{re.escape(option)}[ ,`]", section), (command, option)


def test_the_reference_wraps_the_same_on_any_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "40")
    narrow = command_reference()
    monkeypatch.setenv("COLUMNS", "300")
    assert command_reference() == narrow


def test_the_build_puts_the_reference_into_the_commands_page() -> None:
    spec = importlib.util.spec_from_file_location("hooks", REPO / "scripts" / "mkdocs_hooks.py")
    assert spec is not None and spec.loader is not None
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    page = (REPO / "docs" / "commands.md").read_text(encoding="utf-8")
    assert page.count(hooks.MARKER) == 1
    built = hooks.on_page_markdown(page, page=None, config=None, files=None)
    assert hooks.MARKER not in built
    assert "`--report-format {png,pdf,svg}`" in built
    assert "## holoview process" in built


#: What a file of the repository must not name: files of the machine it was written on.
OUTSIDE = re.compile(r"\.\./shared|/work/|DESIGN\.md|ENVIRONMENT\.md|STYLE\.md|shared/paper")
#: Tests may locate the real holograms beside the repository, and skip when absent.
ALLOWED = re.compile(r"\.\./shared/data/real")


def tracked_files() -> list[Path]:
    """The repository's files (git's list), text ones only."""
    listed = subprocess.run(
        ["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True, timeout=60
    ).stdout.split(b"\0")
    files = []
    for name in filter(None, listed):
        path = REPO / name.decode()
        if path.is_file() and b"\0" not in path.read_bytes()[:4096]:
            files.append(path)
    return files


def test_no_file_names_a_file_outside_the_repository() -> None:
    found = []
    for path in tracked_files():
        if path == Path(__file__).resolve():
            continue  # the patterns above
        relative = path.relative_to(REPO)
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            hit = OUTSIDE.search(line)
            if hit and not (relative.parts[0] == "tests" and ALLOWED.search(line)):
                found.append(f"{relative}:{number}: {line.strip()}")
    assert not found, "\n".join(found)


def test_the_readme_is_short_starts_with_the_two_commands_and_links_resolve() -> None:
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    lines = readme.splitlines()
    assert len(lines) <= 150
    first_block = readme.split("```", 2)[1]
    assert "bash scripts/run.sh" in first_block and "bash scripts/test.sh" in first_block
    targets = re.findall(r"\]\(([^)#\s]+)", readme)
    assert any(t.startswith("docs/") for t in targets)
    for target in targets:
        if "://" not in target:
            assert (REPO / target).exists(), target
