"""`Throttle`: how often one seat may have a message recorded (a token bucket).

Every message a seat sends is logged, as what it asked for, a refused move (counted in its run)
or a `bad_message`; a seat sending hundreds a second would fill the log and its partner's page.
Every message but a ping (never logged) is counted, a move whether executed or refused.
"""

from __future__ import annotations

import time
from collections.abc import Callable


class Throttle:
    def __init__(self, rate_per_s: float, burst: int, now: Callable[[], float] = time.monotonic) -> None:
        self.rate_per_s, self.burst = rate_per_s, burst
        self._now = now
        self._tokens = float(burst)
        self._at = now()
        self.told = False  # whether the seat was told of the messages refused since the last one taken

    def take(self) -> float:
        """0 when the message may go ahead (and counts), else the seconds until one may."""
        now = self._now()
        self._tokens = min(self.burst, self._tokens + (now - self._at) * self.rate_per_s)
        self._at = now
        if self._tokens >= 1:
            self._tokens -= 1
            return 0.0
        return (1 - self._tokens) / self.rate_per_s
