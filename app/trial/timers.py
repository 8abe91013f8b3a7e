"""`TrialTimers`: a live trial's clocks, all derived from its log so that they survive a restart:
each away participant's grace period (`TrialState.away`), the `still_away` marks while anyone is
away, a lobby's join deadline (`TrialState.join_by_ns`) and a practice's time cap. When one runs
out it is a command for the referee (`GraceExpired`, `JoinsDue`, `Abort`); what that means for the
trial is `decide`'s rule."""

from __future__ import annotations

import asyncio
from collections.abc import Coroutine
from typing import Any, Protocol

from app.clock import ServerClock
from sim.trial import commands as c
from sim.trial import events as ev
from sim.trial.state import TrialState
from sim.trial.vocabulary import Phase, Role

AWAY_MARK_S = 1.0  # how much of a participant's time away a crash can lose from the grace period


class TimedTrial(Protocol):
    @property
    def state(self) -> TrialState: ...

    def apply(self, command: c.Command) -> Any: ...

    def spawn(self, coro: Coroutine[Any, Any, Any]) -> asyncio.Task[Any]: ...


class TrialTimers:
    def __init__(self, trial: TimedTrial, clock: ServerClock, grace_period_s: float) -> None:
        self.trial, self.clock, self.grace_period_s = trial, clock, grace_period_s
        self._grace: dict[Role, asyncio.TimerHandle] = {}
        self._join: asyncio.TimerHandle | None = None
        self._marks: asyncio.Task[None] | None = None

    def expect_joins(self) -> None:
        """A lobby's trial: its seats still unopened at the logged deadline are due then."""
        s = self.trial.state
        if s.join_by_ns is not None and s.phase == Phase.WAITING:
            left_s = max(0.0, (s.join_by_ns - self.clock.now_ns()) / 1e9)
            self._join = asyncio.get_running_loop().call_later(left_s, self.trial.apply, c.JoinsDue())

    def expect_time_cap(self) -> None:
        """A practice: aborted once its clock reaches the cap (the clock stops while paused, so
        sleep what is left and look again)."""
        if self.trial.state.time_cap_s is not None and not self.trial.state.over:
            self.trial.spawn(self._cap_clock(self.trial.state.time_cap_s))  # the trial's close cancels it

    async def _cap_clock(self, cap_s: float) -> None:
        while not self.trial.state.over:
            left_s = cap_s - self.trial.state.active_s(self.clock.now_ns())
            if left_s <= 0:
                self.trial.apply(c.Abort(f"the practice's {cap_s / 60:g} minutes are up"))
                return
            await asyncio.sleep(max(left_s, 0.05))

    def sync(self) -> None:
        """After each change: a grace timer for each participant away, none for the others."""
        away = self.trial.state.away
        for role in [r for r in self._grace if r not in away]:
            self._grace.pop(role).cancel()
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        for role in away:
            if role not in self._grace:
                self._grace[role] = loop.call_later(self._grace_left_s(role), self._grace_expired, role)
        if away and (self._marks is None or self._marks.done()):
            self._marks = self.trial.spawn(self._mark_time_away())

    def close(self) -> None:
        for timer in self._grace.values():
            timer.cancel()
        self._grace.clear()
        if self._join is not None:
            self._join.cancel()

    async def _mark_time_away(self) -> None:
        """A restart knows when the server was last up only from the log: while anyone is away,
        note it every `AWAY_MARK_S`, so their time away before a crash still counts."""
        while True:
            await asyncio.sleep(AWAY_MARK_S)
            if not self.trial.state.away:
                return
            self.trial.apply(c.Note(ev.StillAway(roles=sorted(self.trial.state.away))))

    def _grace_left_s(self, role: Role) -> float:
        gone = self.trial.state.away[role].away_ns(self.clock.now_ns())
        return self.grace_period_s - gone / 1e9

    def _grace_expired(self, role: Role) -> None:
        self._grace.pop(role, None)
        if role not in self.trial.state.away:
            return
        left_s = self._grace_left_s(role)
        if left_s > 0:  # event loops may wake a little early (uvloop: to the millisecond)
            self._grace[role] = asyncio.get_running_loop().call_later(left_s, self._grace_expired, role)
            return
        self.trial.apply(c.GraceExpired(role))
