"""Agents in a trial's seats: `AgentSeat` is one agent (`sim.agents.turns.Agent`) in one seat of a
live trial, `DriverSeat` and `CommanderSeat` what differs between the seats.

A seat joins the trial like a browser and hears the same filtered messages, which it turns into
percepts (`app.drivers.base` says which); it wakes the agent on each, one `perceive` at a time off
the event loop and in the log's order, and carries out the turns it returns through the trial's
narrow port (`DriverTrial`, `CommanderTrial`) alone, so its words, moves, marks and verdicts go
through the same rules and event log as a person's. A turn the trial refuses comes back to the
agent as `Refused`, and a pause and its end as `Paused`, as a person's page shows them.

The Driver's seat: a move is asked for only while the trial runs, one at a time and no sooner
than a person's may be; the frame taken after it follows its outcome. The frame's rays are the
simulator's (handed to this seat alone, `note_observation`), else perceived from its pixels with
the Driver camera's calibration. Caps (settings): moves per target and trial-clock minutes; on
either the agent says so in the chat and the trial ends, aborted, with the reason logged.

The Commander's seat: the map is the trial's maze (`Seating.maze`), each target's name comes as the
trial reaches it, and a claim's frame, as its page shows it, is perceived from its pixels with the
Driver camera's calibration. It never hears a pose, a frame of the stream or a move.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import logging
from collections import OrderedDict
from collections.abc import Coroutine
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from app.drivers.base import Oracle, Seating
from app.drivers.registry import AgentParts, create_agent
from app.settings import Settings
from app.trial import events as ev
from app.trial.decide import Refused
from app.trial.port import CommanderTrial, DriverTrial, SeatTrial
from app.trial.specs import BackendKind, BackendSpec, SeatKind, SeatSpec
from app.trial.vocabulary import Move, Role, ServerMessage
from sim.agents import turns as t
from sim.robot.frames import FrameError, decode_jpeg
from sim.robot.perception import PerceptionError, RayObservation, perceive

if TYPE_CHECKING:
    from app.trial.runtime import TrialRuntime

logger = logging.getLogger(__name__)
OBSERVATIONS_KEPT = 8  # the simulator's observations of the latest frames, until their events come


def seat_agents(runtime: TrialRuntime) -> tuple[DriverSeat | None, CommanderSeat | None]:
    """The agent seats of a trial, made before its backend so the Driver's hears the first frame."""
    s, parts = runtime.state, runtime.parts.agents
    driver_spec, commander_spec = SeatSpec.parse(s.driver), SeatSpec.parse(s.commander)
    driver = commander = None
    if not driver_spec.human:
        cheats = driver_spec.kind == SeatKind.ORACLE
        oracle = Oracle(s.maze, tuple(s.targets), runtime.true_pose) if cheats else None
        seating = Seating(seed=runtime.trial_id, oracle=oracle, partner_human=commander_spec.human)
        driver = DriverSeat(runtime, parts, seating)
    if not commander_spec.human:
        seating = Seating(seed=runtime.trial_id, maze=s.maze, partner_human=driver_spec.human)
        commander = CommanderSeat(runtime, parts, seating)
    return driver, commander


def perceived(jpeg: bytes, calibration: Any) -> RayObservation | None:
    """A frame's rays as read from its pixels; None where unreadable."""
    try:
        return perceive(decode_jpeg(jpeg), calibration)
    except (FrameError, PerceptionError):
        return None


async def camera_calibration(backend: str, settings: Settings) -> Any:
    """The Driver camera's calibration of `backend`, or None where there is none."""
    from app.perception.cameras import CameraUnknown, driver_calibration

    with contextlib.suppress(CameraUnknown):
        return await asyncio.to_thread(driver_calibration, backend, settings)
    return None


@dataclass(frozen=True)
class _FrameArrived:
    frame_id: int
    capture_ns: int
    jpeg: bytes


@dataclass(frozen=True)
class _Outcome:
    moved: t.Moved
    t_ns: int  # when the log recorded it


@dataclass(frozen=True)
class _ClaimArrived:
    target_index: int
    jpeg: bytes | None  # the claim frame, as the Commander's page gets it


class AgentSeat:
    """What both seats share: hearing, the loop that wakes the agent, speaking, pauses, failure."""

    role: Role

    def __init__(self, trial: SeatTrial, parts: AgentParts, seating: Seating) -> None:
        self.trial, self.parts, self.seating = trial, parts, seating
        self.spec = trial.state.driver if self.role == Role.DRIVER else trial.state.commander
        self.inbox: asyncio.Queue[Any] = asyncio.Queue()
        self.chat_seqs: set[int] = set()  # chat events already heard (the welcome repeats them)
        self.phase: tuple[t.Phase, int | None] | None = None
        self.targets_total = len(trial.state.targets)
        self.running = asyncio.Event()
        self.paused = False  # as the agent was last told (a trial starts unpaused)
        self.tasks: list[asyncio.Task[None]] = []
        self.said_for_target = 0  # its own messages since the trial reached the current target

    # -- what a browser in this seat would receive ------------------------------------------------
    def deliver(self, message: dict[str, Any]) -> None:
        kind = message.get("type")
        if kind == ServerMessage.WELCOME:
            self.targets_total = message["targets_total"]
            for event in message["history"]:
                if event["kind"] != ev.PhaseChanged.kind:  # the phase now, below, is what counts
                    self._event(event["kind"], event["seq"], event["payload"], event)
            self._phase(t.Phase(message["phase"]), message["target_index"], message.get("target"))
            self._welcomed(message)
        elif kind == ServerMessage.EVENT:
            self._event(message["kind"], message["seq"], message["payload"], message)
        elif kind == ServerMessage.MOVE_REFUSED:
            self._seat_event(kind, message, message)
        elif kind == ServerMessage.STATUS:
            self.targets_total = message["targets_total"]
        self._sync_running()

    def _event(self, kind: str, seq: int, payload: dict[str, Any], message: dict[str, Any]) -> None:
        if kind == ev.Chat.kind and seq not in self.chat_seqs:
            self.chat_seqs.add(seq)
            self.inbox.put_nowait(t.Heard(t.Speaker(payload["role"]), payload["text"]))
        elif kind == ev.PhaseChanged.kind:
            self._phase(t.Phase(payload["phase"]), payload.get("target_index"), message.get("target"))
        elif kind in (ev.TargetConfirmed.kind, ev.TargetRejected.kind):
            self.inbox.put_nowait(t.Judged(kind == ev.TargetConfirmed.kind, payload["target_index"]))
        else:
            self._seat_event(kind, payload, message)

    def _seat_event(self, kind: str, payload: dict[str, Any], message: dict[str, Any]) -> None:
        """An event (or a `move_refused` reply) only this seat reacts to."""

    def _welcomed(self, message: dict[str, Any]) -> None:
        """What else this seat's welcome holds (the Driver's frame, the Commander's pending claim)."""

    def _phase(self, phase: t.Phase, target_index: int | None, target: str | None) -> None:
        if (phase, target_index) != self.phase:  # the welcome and the event may both say it
            if self.phase is None or self.phase[1] != target_index:
                self.said_for_target = 0
            self.phase = (phase, target_index)
            self.inbox.put_nowait(t.PhaseChanged(phase, target_index, self.targets_total, target))

    def _sync_running(self) -> None:
        state = self.trial.state
        if state.running:
            self.running.set()
        else:
            self.running.clear()
        paused = bool(state.pause_reasons)
        if paused != self.paused:  # the page shows the pause too
            self.paused = paused
            self.inbox.put_nowait(t.Paused(paused))

    # -- life ---------------------------------------------------------------------------------
    def start(self) -> None:
        self.tasks = [asyncio.get_running_loop().create_task(self._guarded(self._run()))]

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
        except Exception as err:  # a broken agent must show in the log, not hang the trial silently
            logger.exception("%s %s failed in trial %s", self.role, self.spec, self.trial.trial_id)
            if not self.trial.state.over:
                self.trial.report_bad_message(self.role, f"agent {self.spec!r} failed: {err}")

    async def _run(self) -> None:
        trial = self.trial
        agent = await asyncio.to_thread(create_agent, self.role, self.spec, self.parts, self.seating)
        await asyncio.to_thread(agent.reset, t.SeatInfo(t.Speaker(self.role), len(trial.state.targets)))
        await self._prepare()
        trial.join(self)
        self._joined()
        while not trial.state.over:
            await self._take(agent, await self.inbox.get())

    async def _prepare(self) -> None:
        """What the seat loads before it joins."""

    def _joined(self) -> None:
        """What the seat starts once it has joined."""

    async def _take(self, agent: t.Agent, item: Any) -> None:
        """One item of the inbox: a percept, or what the seat makes one of."""
        await self._wake(agent, item)

    async def _wake(self, agent: t.Agent, percept: t.Percept) -> None:
        turns = await asyncio.to_thread(agent.perceive, percept)
        for turn in turns:
            if self.trial.state.over:
                return
            await self._carry_out(turn)

    async def _carry_out(self, turn: t.Turn) -> None:
        try:
            match turn:
                case t.DoSay(text=text):
                    await self._say(text)
                case t.DoWait():
                    pass
                case _ if not await self._act(turn):
                    self.trial.report_bad_message(
                        self.role, f"agent {self.spec!r}: {turn!r} is not a {self.role}'s turn"
                    )
        except Refused as err:  # as a person's refused message: in the log, and the trial goes on
            self.trial.report_bad_message(self.role, str(err))
            kind = _TURN_KIND.get(type(turn))
            if kind is not None:  # the agent hears why, as a person's page shows the error
                self.inbox.put_nowait(t.Refused(kind, str(err)))

    async def _act(self, turn: t.Turn) -> bool:
        """A turn of this seat's own; False where the seat has no such turn."""
        return False

    async def _say(self, text: str) -> None:
        cap = self.parts.settings.agent_messages_per_target
        if self.said_for_target >= cap:  # two agents can talk in circles: a cap, as on moves
            index = self.phase[1] if self.phase and self.phase[1] is not None else 0
            await self._give_up(
                f"I have sent {cap} messages on target {index + 1} of {self.targets_total}, the most an agent "
                "may; I stop here",
                f"agent {self.role.title()}'s cap: {cap} messages for target {index + 1}",
            )
            return
        self.said_for_target += 1
        self.trial.say(self.role, text)

    async def _give_up(self, words: str, reason: str) -> None:
        trial = self.trial
        if trial.state.over:
            return
        trial.say(self.role, words)
        trial.abort(reason)


_TURN_KIND: dict[type, t.TurnKind] = {
    t.DoSay: t.TurnKind.SAY,
    t.DoMove: t.TurnKind.MOVE,
    t.DoClaim: t.TurnKind.CLAIM,
    t.DoJudge: t.TurnKind.JUDGE,
    t.DoLocalize: t.TurnKind.LOCALIZE,
}


class CommanderSeat(AgentSeat):
    """An agent in the Commander's seat: the map, the targets' names, the chat, the claim frames."""

    role = Role.COMMANDER

    def __init__(self, trial: CommanderTrial, parts: AgentParts, seating: Seating) -> None:
        super().__init__(trial, parts, seating)
        self.port = trial
        self.calibration: Any = None

    async def _prepare(self) -> None:
        self.calibration = await camera_calibration(self.trial.state.backend, self.parts.settings)

    def _seat_event(self, kind: str, payload: dict[str, Any], message: dict[str, Any]) -> None:
        if kind == ev.TargetClaimed.kind:
            self._claim(payload["target_index"], message.get("claim"))

    def _welcomed(self, message: dict[str, Any]) -> None:
        if "claim" in message:  # a claim waiting for the verdict
            self._claim(self.trial.state.target_index, message["claim"])

    def _claim(self, target_index: int, claim: dict[str, Any] | None) -> None:
        jpeg = claim.get("jpeg") if claim else None
        self.inbox.put_nowait(_ClaimArrived(target_index, base64.b64decode(jpeg) if jpeg else None))

    async def _take(self, agent: t.Agent, item: Any) -> None:
        if isinstance(item, _ClaimArrived):
            rays = None
            if item.jpeg is not None and self.calibration is not None:
                rays = await asyncio.to_thread(perceived, item.jpeg, self.calibration)
            item = t.Claimed(item.target_index, rays)
        await self._wake(agent, item)

    async def _act(self, turn: t.Turn) -> bool:
        match turn:
            case t.DoLocalize(x=x, y=y, heading=heading):
                self.port.localize(x, y, heading)
            case t.DoJudge(confirmed=confirmed):
                self.port.judge(confirmed)
            case _:
                return False
        return True


class DriverSeat(AgentSeat):
    """An agent in the Driver's seat: the chat, its frames, its moves' outcomes, its claims."""

    role = Role.DRIVER

    def __init__(self, trial: DriverTrial, parts: AgentParts, seating: Seating) -> None:
        super().__init__(trial, parts, seating)
        self.port = trial
        self.observations: OrderedDict[int, RayObservation] = OrderedDict()
        self.latest: _FrameArrived | None = None
        self.seen_first = False
        self.move_started_ns: int | None = None  # a move asked for whose frame the agent has not seen
        self.outcome_ns: int | None = None  # when that move's outcome was logged (None: not yet)
        self.target_index: int | None = None
        self.moves_for_target = 0
        self.calibration: Any = None

    # -- what a browser Driver would receive ------------------------------------------------
    def note_observation(self, frame_id: int, observation: RayObservation) -> None:
        """The simulator's rays at a frame about to be delivered (this seat's alone)."""
        self.observations[frame_id] = observation
        while len(self.observations) > OBSERVATIONS_KEPT:
            self.observations.popitem(last=False)

    def _welcomed(self, message: dict[str, Any]) -> None:
        if "frame" in message:
            frame = message["frame"]
            self.inbox.put_nowait(_FrameArrived(frame["frame_id"], 0, base64.b64decode(frame["jpeg"])))

    def _seat_event(self, kind: str, payload: dict[str, Any], message: dict[str, Any]) -> None:
        put = self.inbox.put_nowait
        if kind == ev.MoveExecuted.kind:
            moved = t.Moved(t.Move(payload["action"]), t.Outcome(payload["outcome"]), payload.get("reason"))
            put(_Outcome(moved, message["t_ns"]))
        elif kind == ServerMessage.MOVE_REFUSED:  # refused as it was asked for: no event of its own
            put(_Outcome(t.Moved(t.Move(payload["action"]), t.Outcome.REFUSED, payload["reason"]), message["t_ns"]))
        elif kind == ev.FrameRecorded.kind and "jpeg" in message:
            put(_FrameArrived(payload["frame_id"], payload["capture_ns"], base64.b64decode(message["jpeg"])))
        elif kind == ev.TargetClaimed.kind:
            put(t.Claimed(payload["target_index"]))

    # -- life ---------------------------------------------------------------------------------
    async def _prepare(self) -> None:
        if (
            BackendSpec.parse(self.trial.state.backend).kind != BackendKind.SIM
        ):  # the simulator hands its rays; a rover's are perceived
            self.calibration = await camera_calibration(self.trial.state.backend, self.parts.settings)

    def _joined(self) -> None:
        self.tasks.append(asyncio.get_running_loop().create_task(self._guarded(self._clock())))  # its cap

    async def _take(self, agent: t.Agent, item: Any) -> None:
        if isinstance(item, _FrameArrived):
            await self._frame(agent, item)
            return
        if isinstance(item, t.PhaseChanged):
            if item.target_index != self.target_index:
                self.moves_for_target = 0
            self.target_index = item.target_index
        if isinstance(item, _Outcome):
            await self._moved(agent, item)
        else:
            await self._wake(agent, item)

    async def _moved(self, agent: t.Agent, outcome: _Outcome) -> None:
        """A move's outcome, then the frame after it where that came first (for a move not made,
        the frame as it stands: the robot did not move)."""
        started, moved = self.move_started_ns, outcome.moved
        self.outcome_ns = outcome.t_ns  # one move at a time: the pending move's
        await self._wake(agent, moved)
        latest = self.latest
        if started is None or self.move_started_ns != started or latest is None:
            return  # no frame to show, or the agent has moved again already
        if moved.result == t.Outcome.REFUSED or self._after_move(latest):
            await self._saw(agent, latest)

    async def _frame(self, agent: t.Agent, frame: _FrameArrived) -> None:
        self.latest = frame
        if not self.seen_first or (self.move_started_ns is not None and self._after_move(frame)):
            await self._saw(agent, frame)

    def _after_move(self, frame: _FrameArrived) -> bool:
        """Whether `frame` shows where the pending move left the robot: the simulator draws one
        frame when a move ends (captured after it started); a rover streams, so its frame is the
        first captured once the move's outcome is logged."""
        started, done = self.move_started_ns, self.outcome_ns
        if started is None or done is None or done < started:
            return False  # the outcome has not come back yet
        return frame.capture_ns > (started if frame.frame_id in self.observations else done)

    async def _saw(self, agent: t.Agent, frame: _FrameArrived) -> None:
        self.seen_first, self.move_started_ns = True, None
        rays = self.observations.get(frame.frame_id)
        if rays is None and self.calibration is not None:
            rays = await asyncio.to_thread(perceived, frame.jpeg, self.calibration)
        await self._wake(agent, t.Saw(frame.frame_id, rays))

    async def _act(self, turn: t.Turn) -> bool:
        match turn:
            case t.DoMove(move=move):
                await self._move(move)
            case t.DoClaim():
                self.port.claim()
            case _:
                return False
        return True

    async def _move(self, move: t.Move) -> None:
        settings, clock = self.parts.settings, self.parts.clock
        cap = settings.agent_moves_per_target
        if self.moves_for_target >= cap:
            index = self.target_index or 0
            await self._give_up(
                f"I have made {cap} moves looking for target {index + 1} of {self.targets_total}, "
                "the most an agent may; I stop here",
                f"agent Driver's cap: {cap} moves for target {index + 1}",
            )
            return
        await self.running.wait()  # a move while paused would be refused; a person waits too
        while (last := self.trial.state.last_move_ns) is not None:  # no sooner than a person's next move
            wait_ns = last + settings.min_move_interval_s * 1e9 - clock.now_ns()
            if wait_ns <= 0:
                break
            await asyncio.sleep(wait_ns / 1e9)  # again where the loop wakes a little early
        self.moves_for_target += 1
        self.move_started_ns, self.outcome_ns = clock.now_ns(), None
        await self.port.request_move(Move(move))

    async def _clock(self) -> None:
        """The trial-clock cap: the clock runs only while the trial does, so sleep what is left."""
        minutes = self.parts.settings.agent_minutes_per_trial
        while not self.trial.state.over:
            left_s = minutes * 60 - self.trial.state.active_s(self.parts.clock.now_ns())
            if left_s <= 0:
                await self._give_up(
                    f"my {minutes:g} minutes for this trial are over; I stop here",
                    f"agent Driver's cap: {minutes:g} minutes per trial",
                )
                return
            await asyncio.sleep(max(left_s, 0.05))
