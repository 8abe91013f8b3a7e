"""`ServerClock`: one clock stamps every event of every trial.

Monotonic nanoseconds (never jump back) offset to wall time once at start, so stamps are
both ordered and readable as dates.
"""

from __future__ import annotations

import time


class ServerClock:
    def __init__(self) -> None:
        self._offset_ns = time.time_ns() - time.monotonic_ns()

    def now_ns(self) -> int:
        return time.monotonic_ns() + self._offset_ns
