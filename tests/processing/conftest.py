"""Processing tests plan FFTs with FFTW_ESTIMATE: exact all the same, and planned at once.

FFTW_MEASURE (the library's default) times candidate algorithms, which on a busy
2-core machine takes seconds per new frame shape; the results do not depend on it.
The wisdom test asks for FFTW_MEASURE explicitly.
"""

from __future__ import annotations

import pytest

from holoview.processing.fourier import fftplans


@pytest.fixture(autouse=True)
def _estimate_plans(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fftplans, "PLANNER_EFFORT", "FFTW_ESTIMATE")
