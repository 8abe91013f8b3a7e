"""`TrialHub`: the live trials of this process, opened on first use and resumed from the log."""

from __future__ import annotations

import asyncio

from app.trial.runtime import TrialRuntime


class TrialHub:
    def __init__(self, services) -> None:
        self.services = services
        self._runtimes: dict[int, TrialRuntime] = {}
        self._opening: dict[int, asyncio.Lock] = {}

    async def get(self, trial_id: int) -> TrialRuntime:
        """The trial's runtime, started (from its events) if this process has not yet."""
        runtime = self._runtimes.get(trial_id)
        if runtime is not None:
            return runtime
        lock = self._opening.setdefault(trial_id, asyncio.Lock())
        async with lock:
            runtime = self._runtimes.get(trial_id)
            if runtime is None:
                runtime = TrialRuntime(trial_id, self.services)
                await runtime.start()
                self._runtimes[trial_id] = runtime
        return runtime

    def peek(self, trial_id: int) -> TrialRuntime | None:
        return self._runtimes.get(trial_id)

    def live(self) -> list[TrialRuntime]:
        return list(self._runtimes.values())

    async def close(self) -> None:
        for runtime in list(self._runtimes.values()):
            await runtime.close()
        self._runtimes.clear()
