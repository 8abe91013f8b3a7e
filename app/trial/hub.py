"""`TrialHub`: the live trials of this process, opened on first use and resumed from the log."""

from __future__ import annotations

import asyncio
import contextlib
import logging

from sqlalchemy import select

from app.db.models import Trial
from app.trial.messages import TrialSnapshot
from app.trial.relay import RedisRelay, RemoteTrial
from app.trial.runtime import TrialParts, TrialRuntime, UnknownTrial
from sim.trial.vocabulary import Phase

logger = logging.getLogger(__name__)


class TrialHub:
    """`start` and `close` with the server: they start and stop the relay (with Redis) too."""

    def __init__(self, parts: TrialParts, relay_url: str | None = None) -> None:
        self.parts = parts
        self._runtimes: dict[int, TrialRuntime] = {}
        self._opening: dict[int, asyncio.Lock] = {}
        # With Redis, trials are shared between the processes on the same database.
        self.relay = RedisRelay(self, relay_url, parts.settings) if relay_url else None
        parts.log.on_lost = self._lost

    def _lost(self, trial_id: int, error: Exception) -> None:
        """Its events could not be committed (another process runs it now): stop running it here;
        it reopens from the log when next needed."""
        runtime = self._runtimes.pop(trial_id, None)
        self._opening.pop(trial_id, None)
        if runtime is not None:
            with contextlib.suppress(RuntimeError):  # no loop (a script): nothing runs it anyway
                asyncio.get_running_loop().create_task(runtime.close())

    async def get(self, trial_id: int) -> TrialRuntime | RemoteTrial:
        """Where the trial runs: its runtime here, or (with Redis) a `RemoteTrial` forwarding to
        the process that runs it."""
        relay = self.relay
        if relay is None or trial_id in self._runtimes:
            return await self.local(trial_id)
        owner = await relay.owner(trial_id)
        if owner == relay.id:
            return await self.local(trial_id)
        if not self.parts.log.exists(trial_id):
            raise UnknownTrial(f"trial {trial_id} does not exist")
        return RemoteTrial(relay, trial_id, owner)

    async def start(self) -> None:
        """At start: reopen the trials that were running when the server stopped, so their grace
        timers run even if no seat comes back, and a study's trials still waiting for their seats,
        so their join deadlines do (with Redis, the first process up takes them)."""
        if self.relay is not None:
            await self.relay.start()
        with self.parts.db() as db:
            running = Trial.phase.in_([Phase.LOCALIZING, Phase.NAVIGATING])
            paired = (Trial.phase == Phase.WAITING) & Trial.study.is_not(None)
            ids = db.scalars(select(Trial.id).where(running | paired)).all()
        for trial_id in ids:
            try:
                await self.get(trial_id)
            except Exception:  # one trial that cannot reopen (its maze left the library) must not stop the rest
                logger.exception("trial %s could not be reopened", trial_id)

    async def local(self, trial_id: int) -> TrialRuntime:
        """The trial's runtime in this process, started (from its events) if not yet."""
        runtime = self._runtimes.get(trial_id)
        if runtime is not None:
            return runtime
        lock = self._opening.setdefault(trial_id, asyncio.Lock())
        async with lock:
            runtime = self._runtimes.get(trial_id)
            if runtime is None:
                runtime = TrialRuntime(trial_id, self.parts, self.forget)
                await runtime.start()
                self._runtimes[trial_id] = runtime
        return runtime

    def forget(self, trial_id: int) -> None:
        """Drop a trial that is over from this process (it is reopened from its log if needed)."""
        runtime = self._runtimes.get(trial_id)
        if runtime is not None and runtime.state.over:
            del self._runtimes[trial_id]
            self._opening.pop(trial_id, None)

    def peek(self, trial_id: int) -> TrialRuntime | None:
        return self._runtimes.get(trial_id)

    def live(self) -> list[TrialRuntime]:
        """The trials this process runs that are not over."""
        return [r for r in self._runtimes.values() if not r.state.over]

    async def snapshots(self) -> list[TrialSnapshot]:
        """Every live trial of the server for the dashboard: this process's, and with Redis the
        other processes' (a trial taken over meanwhile is listed once, as this process has it)."""
        mine = [runtime.snapshot() for runtime in self.live()]
        if self.relay is None:
            return mine
        here = {snapshot["trial_id"] for snapshot in mine}
        return mine + [s for s in await self.relay.others_snapshots() if s["trial_id"] not in here]

    async def close(self) -> None:
        if self.relay is not None:
            await self.relay.close()  # hands its trials back first
        for runtime in list(self._runtimes.values()):
            await runtime.close()
        self._runtimes.clear()
