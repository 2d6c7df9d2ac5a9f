"""Event rates over a sliding time window (camera, processing and display frame rates)."""

from __future__ import annotations

import time
from collections import deque


class RateMeter:
    """Count events and report their rate over the last ``window_s`` seconds.

    Parameters
    ----------
    window_s : float
        Length of the averaging window, seconds.
    """

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_s = window_s
        self._ticks: deque[tuple[float, int]] = deque()

    def tick(self, count: int = 1, now: float | None = None) -> None:
        """Record ``count`` events at ``now`` (``time.monotonic()`` seconds by default)."""
        t = time.monotonic() if now is None else now
        self._ticks.append((t, count))
        self._trim(t)

    def rate(self, now: float | None = None) -> float:
        """Return events per second over the window ending at ``now`` (0 with < 2 ticks)."""
        self._trim(time.monotonic() if now is None else now)
        if len(self._ticks) < 2:
            return 0.0
        span = self._ticks[-1][0] - self._ticks[0][0]
        events = sum(c for _, c in list(self._ticks)[1:])
        return events / span if span > 0 else 0.0

    def _trim(self, now: float) -> None:
        while self._ticks and self._ticks[0][0] < now - self.window_s:
            self._ticks.popleft()
