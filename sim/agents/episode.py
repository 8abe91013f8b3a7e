"""A Driver agent in offline episodes of the benchmark, stepped through the trial core: with the
oracle Commander (`run`: one leg, or the localization exchange) or with a recorded human
Commander's messages (`replay`: an NDH episode). The referee is the core's `OfflineTrial` (the
trial's rules, the simulator's moves on the graph, each frame's rays the ray table's row) and the
seats a `Table`. What is the episode's own: where it begins (the recorded start, on its leg) and
where the bench ends it (its caps, its end), as an experimenter would abort a trial. The Driver
gets percepts only; the oracle Commander is handed the true pose."""

from __future__ import annotations

import asyncio
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

from sim.agents.oracle_commander import OracleCommander
from sim.core.dynamics import Pose, snap_pose
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.trial import events as ev
from sim.trial.agent import Agent
from sim.trial.commands import Abort, Act, Action, Claim, Localize, RequestMove, Say
from sim.trial.offline import OfflineTrial
from sim.trial.percepts import Heard, Percept
from sim.trial.state import TrialState
from sim.trial.table import Caps, Table
from sim.trial.vocabulary import Phase, Role

MAX_MESSAGES = 80
MAX_REJECTIONS = 3
OVER = "the episode is over"  # the bench's abort
E = TypeVar("E", bound=ev.Event)


@dataclass
class LegResult:
    success: bool = False
    moves: int = 0
    shortest: int = 0  # the fewest moves (turns count) from the start to the target's nearest node
    messages: int = 0
    claims: int = 0
    rejected: int = 0
    dialog: list[tuple[str, str]] = field(default_factory=list)  # (oracle|navigator, text)
    reply_s: list[float] = field(default_factory=list)  # the Driver's time to answer a message
    act_s: list[float] = field(default_factory=list)  # the Driver's time to decide a move


class Episode(OfflineTrial):
    """An offline trial the bench ends: `ends(state, act)` says, of each seat's action, whether
    the episode ends there instead (the action is not carried out); `feed`: recorded Commander
    messages, one each time the table is idle. It begins navigating its one target."""

    def __init__(
        self,
        target: tuple[str, tuple[float, float]],
        start: Pose,
        graph: NavGraph,
        rays: RayTable,
        table: Table,
        navigating: bool,
        ends: Callable[[TrialState, Act], bool] = lambda state, act: False,
        feed: Sequence[str] = (),
    ) -> None:
        self.ends, self.feed = ends, iter(feed)
        self.events: list[ev.Event] = []  # as recorded, typed: the bench's caps count them as they come
        self.counts: Counter[type[ev.Event]] = Counter()
        self.driver_chats = 0
        super().__init__("episode", [target], start, graph, rays, table, navigating=navigating)

    async def act(self, act: Act) -> list[ev.Event]:
        if self.ends(self.state, act):
            self.apply(Abort(OVER))
            return []
        events = await super().act(act)
        if isinstance(act.action, Localize) and not self.state.over:  # a localization exchange ends at the mark
            self.apply(Abort(OVER))
        return events

    async def idle(self) -> bool:
        message = next(self.feed, None)
        if message is None:
            return False
        await super().act(Act(Role.COMMANDER, Say(message)))
        return True

    def _record(self, event: ev.Event) -> None:
        super()._record(event)
        self.events.append(event)
        self.counts[type(event)] += 1
        self.driver_chats += isinstance(event, ev.Chat) and event.role == Role.DRIVER

    def of(self, model: type[E]) -> list[E]:
        return [e for e in self.events if isinstance(e, model)]


def run(
    driver: Agent,
    commander: OracleCommander,
    start: Pose,
    phase: Phase,
    max_moves: int,
    max_driver_messages: int = MAX_MESSAGES,
) -> LegResult:
    """Play from `start` in `phase` (LOCALIZING: the exchange up to the Commander's estimate or
    `max_driver_messages`; NAVIGATING: target 0 of the commander's targets until confirmed or a cap)."""
    out = LegResult()
    graph, targets = commander.graph, commander.targets
    if phase == Phase.NAVIGATING:
        goal = graph.nearest_node(*targets[0][1])
        out.shortest = int(commander.router.moves_to_go(goal)[start.node, start.heading])
    # The bench stops first: the seats' caps lie beyond its own.
    caps = Caps(moves_per_target=max_moves + 1, messages_per_target=MAX_MESSAGES + 1)
    table = Table({Role.DRIVER: driver, Role.COMMANDER: commander}, [targets[0][0]], caps)
    episode = Episode(targets[0], start, graph, commander.rays, table, navigating=phase == Phase.NAVIGATING)

    async def wake(role: Role, agent: Agent, percept: Percept) -> list[Action]:
        capped = (
            episode.state.moves >= max_moves
            or episode.counts[ev.Chat] >= MAX_MESSAGES
            or episode.counts[ev.TargetRejected] >= MAX_REJECTIONS
            or (phase == Phase.LOCALIZING and episode.driver_chats >= max_driver_messages)
        )
        if capped:
            episode.apply(Abort(OVER))
            return []
        commander.pose = episode.pose
        started = time.perf_counter()
        actions = agent.perceive(percept)
        if role == Role.DRIVER:
            spent = time.perf_counter() - started
            if isinstance(percept, Heard) and percept.speaker == Role.COMMANDER:
                out.reply_s.append(spent)
            if any(isinstance(a, RequestMove) for a in actions):
                out.act_s.append(spent)
        return actions

    asyncio.run(table.play(episode, wake))
    out.moves = episode.state.moves
    out.success = bool(episode.of(ev.TargetConfirmed))
    out.claims, out.rejected = len(episode.of(ev.TargetClaimed)), len(episode.of(ev.TargetRejected))
    out.dialog = [("navigator" if c.role == Role.DRIVER else "oracle", c.text) for c in episode.of(ev.Chat)]
    out.messages = len(out.dialog)
    return out


def replay(
    driver: Agent,
    graph: NavGraph,
    rays: RayTable,
    start: Pose,
    target: tuple[str, tuple[float, float]],
    dialog: Sequence[tuple[str, str]],
    max_moves: int,
) -> list[int]:
    """An NDH episode: the recorded Commander's messages (role "oracle") reach the Driver one at a
    time, each once it has finished with the last (spoken or stopped moving); it ends at the Driver's
    claim, after the last message, or at `max_moves`. The Driver's words go nowhere (the recording
    does not answer): the bench keeps them out of the trial. Returns the nodes it stood on, start first."""
    table = Table({Role.DRIVER: driver}, [target[0]], Caps(moves_per_target=max_moves + 1))

    def ends(state: TrialState, act: Act) -> bool:
        return isinstance(act.action, Claim) or (isinstance(act.action, RequestMove) and state.moves >= max_moves)

    feed = [text for role, text in dialog if role == "oracle"]
    episode = Episode(target, start, graph, rays, table, navigating=True, ends=ends, feed=feed)

    async def wake(role: Role, agent: Agent, percept: Percept) -> list[Action]:
        return [a for a in agent.perceive(percept) if not isinstance(a, Say)]

    asyncio.run(table.play(episode, wake))
    return [snap_pose(graph, p.x, p.y, p.heading).node for p in episode.of(ev.PoseSampled)]
