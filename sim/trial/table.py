"""`Table`: agents in a trial's seats, stepped through the referee one percept at a time.

Each event the referee records reaches every agent seat's `SeatView` in the log's order, the
Driver's percepts queued before the Commander's; one agent perceives at a time and its actions are
carried out in order, each through the referee, before the next percept is taken. So two agents
play the same trial whether the referee is offline (`sim.trial.offline`) or the live server (`app.seats`).
Agents have caps, as people have patience: so many messages, and for the Driver so many moves,
per target; at either the agent says so and the trial ends, aborted, the reason logged.
"""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Awaitable, Callable, Collection
from dataclasses import dataclass
from typing import Protocol

from sim.trial import events as ev
from sim.trial.agent import Agent, SeatInfo
from sim.trial.commands import Abort, Act, Action, Command, Note, RequestMove, Say
from sim.trial.decide import Refused
from sim.trial.percepts import Declined, Percept, SeatView
from sim.trial.state import TrialState
from sim.trial.vocabulary import PARTICIPANTS, Role

SEAT_ORDER = (Role.DRIVER, Role.COMMANDER)  # whose percepts of one event are queued first
SILENCE = "both seats wait for the other"


@dataclass(frozen=True)
class Caps:
    moves_per_target: int = 300
    messages_per_target: int = 150


class Referee(Protocol):
    """The trial the table plays in: offline, or the live server's runtime."""

    @property
    def state(self) -> TrialState: ...

    async def act(self, act: Act) -> list[ev.Event]:
        """Carry out a seat's action under the rules (a move up to the frame after it); returns
        the events decided. Raises `Refused`, recording nothing of it."""

    def apply(self, command: Command) -> None:
        """Decide and record one of the server's commands (a refusal noted, an abort)."""

    async def idle(self) -> bool:
        """Wait for something a seat may perceive; False where nothing more can come."""


Wake = Callable[[Role, Agent, Percept], Awaitable[list[Action]]]


class Table:
    def __init__(self, agents: dict[Role, Agent], targets: list[str], caps: Caps | None = None) -> None:
        self.agents, self.caps = agents, caps or Caps()
        self.views = {role: SeatView(role, targets) for role in SEAT_ORDER if role in agents}
        self.queue: deque[tuple[Role, Percept]] = deque()
        self.said: Counter[tuple[Role, int]] = Counter()  # messages per (seat, target index)
        self.moved: Counter[int] = Counter()  # the Driver's moves per target index
        self.targets_total = len(targets)

    def reset(self) -> None:
        for role, agent in self.agents.items():
            agent.reset(SeatInfo(role, self.targets_total))

    def see(self, event: ev.Event, t_ns: int, state: TrialState) -> None:
        """An event the referee recorded (`state`: the trial after it)."""
        for role, view in self.views.items():
            self.queue += [(role, percept) for percept in view.see(event, t_ns, state)]

    def awaiting_frame(self) -> bool:
        view = self.views.get(Role.DRIVER)
        return view is not None and view.awaiting_frame

    async def play(self, referee: Referee, wake: Wake) -> None:
        """Wake the agents with their percepts until the trial is over (or, where `referee.idle`
        says nothing more can come, until both wait for the other)."""
        while not referee.state.over:
            if not self.queue:
                if not await referee.idle():
                    return
                continue
            role, percept = self.queue.popleft()
            for action in await wake(role, self.agents[role], percept):
                if referee.state.over:
                    return
                await self._carry_out(referee, role, action)

    async def _carry_out(self, referee: Referee, role: Role, action: Action) -> None:
        state = referee.state
        cap = self._cap(role, action, state)
        if cap is not None:
            words, reason = cap
            await referee.act(Act(role, Say(words)))
            referee.apply(Abort(reason))
            return
        try:
            events = await referee.act(Act(role, action))
        except Refused as err:  # as a person's refused message: in the log, and the trial goes on
            referee.apply(Note(ev.BadMessage(role=role, error=str(err)[:500])))
            self.queue.append((role, Declined(action, str(err))))
            return
        if isinstance(action, Say):
            self.said[role, state.target_index] += 1
        elif isinstance(action, RequestMove) and events and isinstance(refusal := events[0], ev.MovesRefused):
            view = self.views[Role.DRIVER]
            self.queue += [(role, p) for p in view.refused_as_asked(action.move, refusal.reason, state.last_t_ns or 0)]
        elif isinstance(action, RequestMove):
            self.moved[state.target_index] += 1

    def _cap(self, role: Role, action: Action, state: TrialState) -> tuple[str, str] | None:
        """The words and the logged reason where `action` would pass the seat's cap."""
        index, total = state.target_index, self.targets_total
        if isinstance(action, Say) and self.said[role, index] >= (cap := self.caps.messages_per_target):
            return (
                f"I have sent {cap} messages on target {index + 1} of {total}, the most an agent may; I stop here",
                f"agent {role.title()}'s cap: {cap} messages for target {index + 1}",
            )
        if isinstance(action, RequestMove) and self.moved[index] >= (cap := self.caps.moves_per_target):
            return (
                f"I have made {cap} moves looking for target {index + 1} of {total}, the most an agent may; "
                "I stop here",
                f"agent Driver's cap: {cap} moves for target {index + 1}",
            )
        return None


def agent_pair(agent_roles: Collection[Role]) -> bool:
    """Agents in both participants' seats: nothing but the table can move the trial on."""
    return all(role in agent_roles for role in PARTICIPANTS)
