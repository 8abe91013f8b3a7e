"""`Throttle`: how often one seat may have a message recorded (a token bucket); `SeatRates`: one per seat.

Every message a seat sends is logged, as what it asked for, a refused move (counted in its run)
or a `bad_message`; a seat sending hundreds a second would fill the log and its partner's page.
Every message but a ping (never logged) is counted, a move whether executed or refused.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from app.trial.messages import ServerMessage
from app.trial.port import Connection


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


class SeatRates:
    """Each seat's throttle, from the settings, and the `rate_limited` reply to the first message
    of a run it drops (one reply each would flood the sender's own socket)."""

    def __init__(self, rate_per_s: float, burst: int) -> None:
        self.rate_per_s, self.burst = rate_per_s, burst
        self._throttles: dict[str, Throttle] = {}

    def allows(self, conn: Connection, role: str) -> bool:
        """Whether a seat's message may be recorded now; else neither the log nor the other seat
        hears of it."""
        throttle = self._throttles.get(role)
        if throttle is None:
            throttle = self._throttles[role] = Throttle(self.rate_per_s, self.burst)
        wait_s = throttle.take()
        if not wait_s:
            throttle.told = False
        elif not throttle.told:
            throttle.told = True
            conn.deliver(
                {
                    "type": ServerMessage.ERROR,
                    "code": "rate_limited",
                    "error": f"too many messages at once (at most {throttle.rate_per_s:g} a second); "
                    "this one and any more before the pause were not sent",
                    "retry_after_s": math.ceil(wait_s * 1000) / 1000,
                }
            )
        return not wait_s
