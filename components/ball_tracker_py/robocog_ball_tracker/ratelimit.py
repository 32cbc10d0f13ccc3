"""At most one log line a period (on the wall clock: it paces what a person reads)."""

from __future__ import annotations

import time


class RateLimiter:
    def __init__(self, period_s: float):
        self.period_s = period_s
        self._last: float | None = None
        self._suppressed = 0

    def allow(self) -> int | None:
        """The number of lines suppressed since the last allowed one when this one may go out,
        else None (and it is counted as suppressed)."""
        now = time.monotonic()
        if self._last is not None and now - self._last < self.period_s:
            self._suppressed += 1
            return None
        self._last = now
        n, self._suppressed = self._suppressed, 0
        return n
