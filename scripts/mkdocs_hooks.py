"""MkDocs hooks of the documentation site (``mkdocs.yml``): nothing written by hand twice.

- The commands page holds the marker ``<!-- command reference -->``; the build puts
  there the reference that :func:`holoview.cli.reference.command_reference` writes
  from the parsers, so it always matches the code.
- The screenshots of the live window stay where ``scripts/screenshots.py`` writes
  them (``resources/screenshots``); the build serves them as ``screenshots/...``.
"""

from __future__ import annotations

from pathlib import Path

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files
from mkdocs.structure.pages import Page

#: The line of the commands page that the reference replaces.
MARKER = "<!-- command reference -->"

REPOSITORY = Path(__file__).resolve().parents[1]
SCREENSHOTS = REPOSITORY / "resources" / "screenshots"


def on_files(files: Files, config: MkDocsConfig) -> Files:
    """Add every screenshot under ``screenshots/`` of the site."""
    for path in sorted(SCREENSHOTS.rglob("*.png")):
        uri = "screenshots/" + path.relative_to(SCREENSHOTS).as_posix()
        files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files


def on_page_markdown(markdown: str, page: Page, config: MkDocsConfig, files: Files) -> str:
    """Put the command reference in place of :data:`MARKER`."""
    if MARKER not in markdown:
        return markdown
    from holoview.cli.reference import command_reference

    return markdown.replace(MARKER, command_reference())
