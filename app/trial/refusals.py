"""`RefusedRuns`: move requests refused as they came, logged as runs (`MovesRefused`).

A run is the same reason with nothing logged since; it is logged as one event, with its count,
when it ends (another event, another reason) or `REFUSED_RUN_S` after its first request, so a
flood of requests is not a flood of events and a crash loses at most that much of the count."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from sim.trial import events as ev

REFUSED_RUN_S = 1.0


class RefusedRuns:
    def __init__(self, record: Callable[[ev.Event], object]) -> None:
        self._record = record
        self._run: ev.MovesRefused | None = None
        self._timer: asyncio.TimerHandle | None = None

    def hold(self, refusal: ev.MovesRefused) -> None:
        run = self._run
        if run is not None and run.reason != refusal.reason:
            self.flush()
            run = None
        if run is None:
            self._run = refusal
            self._timer = asyncio.get_running_loop().call_later(REFUSED_RUN_S, self.flush)
        else:
            self._run = run.model_copy(update={"count": run.count + refusal.count})

    def flush(self) -> None:
        """Log the run now (before any other event, so the log keeps them in order)."""
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        run, self._run = self._run, None
        if run is not None:
            self._record(run)
