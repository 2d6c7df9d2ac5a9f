"""The Examples sections of the documented entry points, run as doctests.

Each module listed runs its docstrings' examples (``ELLIPSIS`` and
``NORMALIZE_WHITESPACE`` on); temporary files go under the test's own folder.
"""

from __future__ import annotations

import doctest
import importlib
import io
import tempfile
from pathlib import Path

import pytest

#: Modules whose docstring examples run here.
DOCTEST_MODULES = (
    "holoview.api",
    "holoview.headless.cf",
    "holoview.headless.results_layout",
    "holoview.headless.export_mat",
)


@pytest.mark.slow
@pytest.mark.parametrize("name", DOCTEST_MODULES)
def test_docstring_examples_run(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    module = importlib.import_module(name)
    tests = [t for t in doctest.DocTestFinder().find(module) if t.examples]
    assert tests, f"{name} has no examples"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    report = io.StringIO()
    for test in tests:
        runner.run(test, out=report.write)
    results = runner.summarize(verbose=False)
    assert results.failed == 0, report.getvalue()
    assert results.attempted >= len(tests)
