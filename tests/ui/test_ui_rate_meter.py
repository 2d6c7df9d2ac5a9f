"""The display's rate meter: events over a sliding window."""

from __future__ import annotations

import pytest

from holoview.ui.status_bar import RateMeter


def test_rate_meter() -> None:
    meter = RateMeter(window_s=1.0)
    for i in range(31):
        meter.tick(now=i / 30)
    assert meter.rate(now=1.0) == pytest.approx(30.0, rel=0.05)
    assert meter.rate(now=5.0) == 0.0
