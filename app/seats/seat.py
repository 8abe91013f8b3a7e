"""`AgentSeats`: a live trial's agent seats, the trial core's `Table` with the runtime as its referee.

The runtime hands `see` every event it records, typed (a Driver frame with the simulator's rays
and its image); each agent seat's `SeatView` turns it into the percepts a person's page in that
seat shows, and the table wakes one agent at a time, off the event loop, in the log's order. Its
actions go through the runtime's one entry for a seat's actions (`TrialPort.act`), so its words,
moves, marks and verdicts are events under the same rules as a person's.

A seat holds its role in the runtime as a person's socket does (`AgentSeat`). Its eyes: a frame
without the simulator's rays (a rover's) is perceived from its pixels with the Driver camera's
calibration, for the Driver and for the Commander's claim frame alike. Its pace: a move waits
until the trial runs and no sooner than a person's may follow the last; two agents together may
be unpaced (`agent_pairs_paced`), and each of their moves is carried out up to the frame after
it, so the same agents play the same trial here as offline (`sim.trial.offline`). Its caps: the
table's, from the settings, and trial-clock minutes for the Driver.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Coroutine
from dataclasses import replace
from typing import Any, Protocol

from app.perception.cameras import CameraUnknown, driver_calibration
from app.seats.base import Oracle, Seating
from app.seats.registry import AgentParts, create_agent
from app.trial.messages import Message
from app.trial.port import TrialView
from sim.core.rays import RayObservation
from sim.robot.frames import FrameError, decode_jpeg
from sim.robot.perception import PerceptionError, perceive
from sim.trial import events as ev
from sim.trial.agent import Agent
from sim.trial.commands import Abort, Act, Action, Command, Note, Pause, RequestMove, Say
from sim.trial.events import LoggedEvent
from sim.trial.percepts import Claimed, Percept, Saw
from sim.trial.specs import BackendKind, BackendSpec, SeatKind, SeatSpec
from sim.trial.state import TrialState
from sim.trial.table import SILENCE, Caps, Table, agent_pair
from sim.trial.vocabulary import Phase, Role

logger = logging.getLogger(__name__)
FIRST_FRAME_S = 30.0  # two agents begin once the first frame is in (a render pool starting up)
CAP_WARNING_S = 120.0  # an agent Driver says this long before its trial-clock cap (at most a fifth of the cap)


class TrialPort(TrialView, Protocol):
    """What the agent seats use of their trial's runtime."""

    history: list[LoggedEvent]

    def apply(self, command: Command) -> Any: ...

    async def act(self, act: Act, paced: bool = True) -> list[ev.Event]: ...

    def true_pose(self) -> tuple[float, float, float] | None: ...


class AgentFailed(Exception):
    """An agent raised: its seat's role; the cause is the agent's error."""

    def __init__(self, role: Role) -> None:
        super().__init__(role)
        self.role = role


class AgentSeat:
    """A role held by an agent, in the runtime's seats as a person's socket is. Agents perceive
    the typed events (`AgentSeats.see`), not the wire's messages."""

    def __init__(self, role: Role) -> None:
        self.role = role

    def deliver(self, message: Message) -> None:
        pass


class AgentSeats:
    def __init__(self, trial: TrialPort, parts: AgentParts, seats: dict[Role, tuple[SeatSpec, Seating]]) -> None:
        self.trial, self.parts, self.seats = trial, parts, seats
        settings = parts.settings
        self.caps = Caps(settings.agent_moves_per_target, settings.agent_messages_per_target)
        self.pair = agent_pair(seats.keys())
        self.paced = settings.agent_pairs_paced or not self.pair
        self.table: Table | None = None
        self.news = asyncio.Event()  # a percept queued while the table waited
        self.calibration: Any = None  # the Driver camera's, where frames come without rays
        self.tasks: list[asyncio.Task[None]] = []
        self._early: list[tuple[ev.Event, int]] = []  # events recorded before the agents were made

    @classmethod
    def of(cls, trial: TrialPort, parts: AgentParts) -> AgentSeats | None:
        """The agent seats of a trial (None: people in both), made before its backend starts so
        the first frame is seen."""
        s = trial.state
        seed = s.seed if s.seed is not None else trial.trial_id
        driver, commander = SeatSpec.parse(s.driver), SeatSpec.parse(s.commander)
        seats: dict[Role, tuple[SeatSpec, Seating]] = {}
        if not driver.human:
            oracle = Oracle(s.maze, tuple(s.targets), trial.true_pose) if driver.kind == SeatKind.ORACLE else None
            seats[Role.DRIVER] = (driver, Seating(seed=seed, oracle=oracle, partner_human=commander.human))
        if not commander.human:
            seats[Role.COMMANDER] = (
                commander,
                Seating(seed=seed, maze=s.maze, partner_human=driver.human),
            )
        return cls(trial, parts, seats) if seats else None

    # -- what the runtime tells --------------------------------------------------------------
    def see(self, event: ev.Event, t_ns: int) -> None:
        if self.table is None:
            self._early.append((event, t_ns))
            return
        self.table.see(event, t_ns, self.trial.state)
        self.news.set()

    # -- life ---------------------------------------------------------------------------------
    def start(self) -> None:
        loop = asyncio.get_running_loop()
        self.tasks = [loop.create_task(self._guarded(self._run()))]
        if Role.DRIVER in self.seats:
            self.tasks.append(loop.create_task(self._guarded(self._clock())))

    async def stop(self) -> None:
        for task in list(self.tasks):
            if task is not asyncio.current_task():
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await task

    async def _guarded(self, work: Coroutine[Any, Any, None]) -> None:
        try:
            await work
        except asyncio.CancelledError:
            raise
        except AgentFailed as failed:  # a broken agent must show in the log, not hang the trial silently
            logger.exception("trial %s: the %s's agent failed", self.trial.trial_id, failed.role)
            if not self.trial.state.over:
                error = f"agent {str(self.seats[failed.role][0])!r} failed: {failed.__cause__}"
                self.trial.apply(Note(ev.BadMessage(role=failed.role, error=error[:500])))
                # The person in the other seat would talk to nothing: the clock stops, and both
                # seats and the experimenter are told why (the experimenter aborts or restarts).
                self.trial.apply(Pause(f"the {failed.role}'s agent stopped working; the experimenter has been told"))

    async def _run(self) -> None:
        agents: dict[Role, Agent] = {}
        for role, (spec, seating) in self.seats.items():
            try:
                agents[role] = await asyncio.to_thread(create_agent, role, str(spec), self.parts, seating)
            except Exception as err:
                raise AgentFailed(role) from err
        state = self.trial.state
        if BackendSpec.parse(state.backend).kind != BackendKind.SIM:  # the simulator hands its rays
            with contextlib.suppress(CameraUnknown):
                self.calibration = await asyncio.to_thread(driver_calibration, state.backend, self.parts.settings)
        table = Table(agents, list(state.targets), self.caps)
        await asyncio.to_thread(table.reset)
        self._catch_up(table)
        if self.pair:  # they begin alike on every server: with the first frame in
            await self._first_frame(table)
        for role in agents:
            self.trial.join(AgentSeat(role))
        await table.play(self, self._wake)
        if not self.trial.state.over:
            self.trial.apply(Abort(SILENCE))

    def _catch_up(self, table: Table) -> None:
        """The seats of a reopened trial hear the dialog so far and where the trial stands; the
        events since the seats were made come as they were recorded."""
        self.table = table
        state = self.trial.state
        for logged in self.trial.history:
            event = ev.typed(logged)
            if event is not None and not isinstance(event, ev.PhaseChanged):
                table.see(event, logged.t_ns, state)
        if state.phase != Phase.WAITING:
            table.see(ev.PhaseChanged(phase=state.phase, target_index=state.target_index), 0, state)
        for event, t_ns in self._early:
            table.see(event, t_ns, state)
        self._early.clear()

    async def _first_frame(self, table: Table) -> None:
        view = table.views.get(Role.DRIVER)
        loop = asyncio.get_running_loop()
        deadline = loop.time() + FIRST_FRAME_S
        while view is not None and view.latest is None and loop.time() < deadline:
            self.news.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.news.wait(), deadline - loop.time())

    # -- the table's referee: the runtime ------------------------------------------------------
    @property
    def state(self) -> TrialState:
        return self.trial.state

    def apply(self, command: Command) -> None:
        self.trial.apply(command)

    async def act(self, act: Act) -> list[ev.Event]:
        if isinstance(act.action, RequestMove) and self.paced:
            await self._pace()
        events = await self.trial.act(act, paced=self.paced)
        if isinstance(act.action, RequestMove) and self.pair:  # up to the frame after it
            while self.table is not None and self.table.awaiting_frame() and not self.state.over:
                self.news.clear()
                await self.news.wait()
        return events

    async def idle(self) -> bool:
        """Wait for news. Two agents alone wait only while the trial is paused: otherwise
        nothing more can come."""
        if self.pair and not self.state.pause_reasons and self.state.phase != Phase.WAITING:
            return False
        self.news.clear()
        await self.news.wait()
        return True

    async def _pace(self) -> None:
        """A move while paused would be refused, and one too soon after the last: a person waits too."""
        settings, clock = self.parts.settings, self.parts.clock
        while not self.state.running and not self.state.over:
            self.news.clear()
            await self.news.wait()
        while (last := self.state.last_move_ns) is not None:
            wait_ns = last + settings.min_move_interval_s * 1e9 - clock.now_ns()
            if wait_ns <= 0:
                break
            await asyncio.sleep(wait_ns / 1e9)  # again where the loop wakes a little early

    async def _wake(self, role: Role, agent: Agent, percept: Percept) -> list[Action]:
        seen = await self._eyes(percept)
        try:
            return await asyncio.to_thread(agent.perceive, seen)
        except Exception as err:
            raise AgentFailed(role) from err

    async def _eyes(self, percept: Percept) -> Percept:
        """A frame without the simulator's rays, as the seat perceives it from its pixels."""
        if self.calibration is None or self.table is None:
            return percept
        frames = next(iter(self.table.views.values())).frames
        if isinstance(percept, Saw | Claimed) and percept.rays is None:
            claim = self.state.pending_claim
            frame_id = percept.frame_id if isinstance(percept, Saw) else claim.frame_id if claim else None
            frame = frames.get(frame_id) if frame_id is not None else None
            if frame is not None and frame.jpeg is not None:
                rays = await asyncio.to_thread(perceived, frame.jpeg, self.calibration)
                return replace(percept, rays=rays)
        return percept

    async def _clock(self) -> None:
        """The Driver's trial-clock cap: the clock runs only while the trial does, so sleep what is
        left; said in the chat ahead (a person commanding the agent did not know the cap, and the
        trial ended with the paddle close ahead)."""
        minutes = self.parts.settings.agent_minutes_per_trial
        warn_s = min(CAP_WARNING_S, minutes * 60 / 5)
        warned = False
        while not self.state.over:
            left_s = minutes * 60 - self.state.active_s(self.parts.clock.now_ns())
            if not warned and left_s <= warn_s:
                warned = True
                said = f"i can drive for {left_s:.0f} more seconds in this trial: my cap is {minutes:g} minutes"
                await self.trial.act(Act(Role.DRIVER, Say(said)))
            if left_s > warn_s:
                await asyncio.sleep(left_s - warn_s)
                continue
            if left_s <= 0:
                await self.trial.act(
                    Act(Role.DRIVER, Say(f"my {minutes:g} minutes for this trial are over; I stop here"))
                )
                self.trial.apply(Abort(f"agent Driver's cap: {minutes:g} minutes per trial"))
                return
            await asyncio.sleep(max(left_s, 0.05))


def perceived(jpeg: bytes, calibration: Any) -> RayObservation | None:
    """A frame's rays as read from its pixels; None where unreadable."""
    try:
        return perceive(decode_jpeg(jpeg), calibration)
    except (FrameError, PerceptionError):
        return None
