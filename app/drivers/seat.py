"""`AgentSeat`: an agent (`sim.agents.turns.Agent`) in the Driver's seat of a live trial.

It joins the trial like a browser Driver and hears the same filtered messages, which it turns
into percepts (`app.drivers.base` says which); it wakes the agent on each, one `perceive` at a
time off the event loop and in the log's order, and carries out the turns it returns through
`DriverTrial` alone, so its words and moves go through the same rules and event log as a
person's. A move is asked for only while the trial runs, one at a time and no sooner than a
person's may be; the frame taken after it follows its outcome. A turn `DriverTrial` refuses comes
back to the agent as `Refused`, and a pause and its end as `Paused`, as the Driver's page shows them. The frame's rays are the
simulator's (handed to this seat alone, `note_observation`), else perceived from its pixels with
the Driver camera's calibration. Caps (settings): moves per target and trial-clock minutes; on
either the agent says so in the chat and the trial ends, aborted, with the reason logged.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import logging
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

from app.drivers.base import Oracle, Seating
from app.drivers.registry import DriverParts, create_driver
from app.trial import events as ev
from app.trial.decide import Refused
from app.trial.port import DriverTrial
from app.trial.vocabulary import Move, Role
from sim.agents import turns as t
from sim.robot.frames import FrameError, decode_jpeg
from sim.robot.perception import PerceptionError, RayObservation, perceive

logger = logging.getLogger(__name__)
_TURN_KIND: dict[type, t.TurnKind] = {t.DoSay: t.TurnKind.SAY, t.DoMove: t.TurnKind.MOVE, t.DoClaim: t.TurnKind.CLAIM}
OBSERVATIONS_KEPT = 8  # the simulator's observations of the latest frames, until their events come


@dataclass(frozen=True)
class _FrameArrived:
    frame_id: int
    capture_ns: int
    jpeg: bytes


@dataclass(frozen=True)
class _Outcome:
    moved: t.Moved
    t_ns: int  # when the log recorded it


class AgentSeat:
    role = Role.DRIVER

    def __init__(self, trial: DriverTrial, parts: DriverParts, oracle: Oracle | None = None) -> None:
        self.trial, self.parts, self.oracle = trial, parts, oracle
        self.spec = trial.state.driver
        self.inbox: asyncio.Queue[t.Percept | _FrameArrived | _Outcome] = asyncio.Queue()
        self.observations: OrderedDict[int, RayObservation] = OrderedDict()
        self.chat_seqs: set[int] = set()  # chat events already heard (the welcome repeats them)
        self.phase: tuple[t.Phase, int | None] | None = None
        self.targets_total = len(trial.state.targets)
        self.latest: _FrameArrived | None = None
        self.seen_first = False
        self.move_started_ns: int | None = None  # a move asked for whose frame the agent has not seen
        self.outcome_ns: int | None = None  # when that move's outcome was logged (None: not yet)
        self.target_index: int | None = None
        self.moves_for_target = 0
        self.calibration: Any = None
        self.running = asyncio.Event()
        self.paused = False  # as the agent was last told (a trial starts unpaused)
        self.tasks: list[asyncio.Task] = []

    # -- what a browser Driver would receive ------------------------------------------------
    def note_observation(self, frame_id: int, observation: RayObservation) -> None:
        """The simulator's rays at a frame about to be delivered (this seat's alone)."""
        self.observations[frame_id] = observation
        while len(self.observations) > OBSERVATIONS_KEPT:
            self.observations.popitem(last=False)

    def deliver(self, message: dict[str, Any]) -> None:
        kind = message.get("type")
        if kind == "welcome":
            self.targets_total = message["targets_total"]
            for event in message["history"]:
                self._event(event["kind"], event["seq"], event["payload"], event)
            self._phase(t.Phase(message["phase"]), message["target_index"])
            if "frame" in message:
                frame = message["frame"]
                self.inbox.put_nowait(_FrameArrived(frame["frame_id"], 0, base64.b64decode(frame["jpeg"])))
        elif kind == "event":
            self._event(message["kind"], message["seq"], message["payload"], message)
        elif kind == "status":
            self.targets_total = message["targets_total"]
        self._sync_running()

    def _event(self, kind: str, seq: int, payload: dict[str, Any], message: dict[str, Any]) -> None:
        put = self.inbox.put_nowait
        if kind == ev.Chat.kind and seq not in self.chat_seqs:
            self.chat_seqs.add(seq)
            put(t.Heard(t.Speaker(payload["role"]), payload["text"]))
        elif kind == ev.PhaseChanged.kind:
            self._phase(t.Phase(payload["phase"]), payload.get("target_index"))
        elif kind == ev.MoveExecuted.kind:
            moved = t.Moved(t.Move(payload["action"]), t.Outcome(payload["outcome"]), payload.get("reason"))
            put(_Outcome(moved, message["t_ns"]))
        elif kind == ev.FrameRecorded.kind and "jpeg" in message:
            put(_FrameArrived(payload["frame_id"], payload["capture_ns"], base64.b64decode(message["jpeg"])))
        elif kind == ev.TargetClaimed.kind:
            put(t.Claimed(payload["target_index"]))
        elif kind in (ev.TargetConfirmed.kind, ev.TargetRejected.kind):
            put(t.Judged(kind == ev.TargetConfirmed.kind, payload["target_index"]))

    def _phase(self, phase: t.Phase, target_index: int | None) -> None:
        if (phase, target_index) != self.phase:  # the welcome and the event may both say it
            self.phase = (phase, target_index)
            self.inbox.put_nowait(t.PhaseChanged(phase, target_index, self.targets_total))

    def _sync_running(self) -> None:
        state = self.trial.state
        if state.running:
            self.running.set()
        else:
            self.running.clear()
        paused = bool(state.pause_reasons)
        if paused != self.paused:  # the Driver's page shows the pause too
            self.paused = paused
            self.inbox.put_nowait(t.Paused(paused))

    # -- life ---------------------------------------------------------------------------------
    def start(self) -> None:
        self.tasks = [asyncio.get_running_loop().create_task(self._guarded(self._drive()))]

    async def stop(self) -> None:
        for task in list(self.tasks):
            if task is not asyncio.current_task():
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await task

    async def _guarded(self, work) -> None:
        try:
            await work
        except asyncio.CancelledError:
            raise
        except Exception as err:  # a broken agent must show in the log, not hang the trial silently
            logger.exception("driver %s failed in trial %s", self.spec, self.trial.trial_id)
            if not self.trial.state.over:
                self.trial.report_bad_message(Role.DRIVER, f"agent {self.spec!r} failed: {err}")

    async def _drive(self) -> None:
        trial, settings = self.trial, self.parts.settings
        seating = Seating(seed=trial.trial_id, oracle=self.oracle)
        agent = await asyncio.to_thread(create_driver, self.spec, self.parts, seating)
        await asyncio.to_thread(agent.reset, t.SeatInfo(t.Speaker.DRIVER, len(trial.state.targets)))
        if trial.state.backend != "sim":  # the simulator hands its rays; a rover's are perceived
            from app.perception.cameras import CameraUnknown, driver_calibration

            with contextlib.suppress(CameraUnknown):
                self.calibration = await asyncio.to_thread(driver_calibration, trial.state.backend, settings)
        trial.join(self)
        self.tasks.append(asyncio.get_running_loop().create_task(self._guarded(self._clock())))  # its cap
        while not trial.state.over:
            item = await self.inbox.get()
            if isinstance(item, _FrameArrived):
                await self._frame(agent, item)
                continue
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
            rays = await asyncio.to_thread(self._perceive, frame.jpeg)
        await self._wake(agent, t.Saw(frame.frame_id, rays))

    def _perceive(self, jpeg: bytes) -> RayObservation | None:
        try:
            return perceive(decode_jpeg(jpeg), self.calibration)
        except (FrameError, PerceptionError):
            return None

    async def _wake(self, agent: t.Agent, percept: t.Percept) -> None:
        turns = await asyncio.to_thread(agent.perceive, percept)
        for turn in turns:
            if self.trial.state.over:
                return
            await self._carry_out(turn)

    async def _carry_out(self, turn: t.Turn) -> None:
        trial = self.trial
        kind = _TURN_KIND.get(type(turn))
        try:
            match turn:
                case t.DoSay(text=text):
                    trial.say(Role.DRIVER, text)
                case t.DoMove(move=move):
                    await self._move(move)
                case t.DoClaim():
                    trial.claim()
                case t.DoWait():
                    pass
                case _:
                    trial.report_bad_message(Role.DRIVER, f"agent {self.spec!r}: {turn!r} is not a Driver's turn")
        except Refused as err:  # as a person's refused message: in the log, and the trial goes on
            trial.report_bad_message(Role.DRIVER, str(err))
            if kind is not None:  # the agent hears why, as a person's page shows the error
                self.inbox.put_nowait(t.Refused(kind, str(err)))

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
        await self.trial.request_move(Move(move))

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

    async def _give_up(self, words: str, reason: str) -> None:
        trial = self.trial
        if trial.state.over:
            return
        trial.say(Role.DRIVER, words)
        trial.abort(reason)
