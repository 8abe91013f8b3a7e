"""`TrialRuntime`: one live trial in this process. It only does input and output.

Everything that happens becomes a command for the trial core's referee (`sim.trial.decide`); the
events it returns are logged (`EventLog`, committed at the end of this event-loop turn), folded,
handed to the agent seats (`AgentSeats`) and, once committed, to whoever hears the trial
(`Audience`). Its robot seat, timers, seats' rates, runs of refused moves and watchers' views are
parts of their own. Nothing awaits between reading the state and recording, so a trial's events
are totally ordered without locks."""

from __future__ import annotations

import asyncio
import uuid
from collections.abc import Callable, Coroutine
from dataclasses import dataclass, replace
from typing import Any

from sqlalchemy.orm import Session, sessionmaker

from app.backends.base import Frame
from app.backends.registry import BackendParts
from app.clock import ServerClock
from app.mazes import Mazes
from app.seats.registry import AgentParts
from app.seats.seat import AgentSeat, AgentSeats
from app.settings import Settings
from app.trial import messages as m
from app.trial import views
from app.trial.audience import Attachments, Audience
from app.trial.frames_store import FrameStore
from app.trial.log import EventLog, FrameRow, TrialCache
from app.trial.messages import ServerMessage, StatusMessage, TrialSnapshot, WelcomeMessage
from app.trial.port import Connection
from app.trial.refusals import RefusedRuns
from app.trial.robot_seat import RobotSeat
from app.trial.throttle import SeatRates
from app.trial.timers import TrialTimers
from app.trial.watch import Watch, WatchParts
from sim.trial import commands as c
from sim.trial import events as ev
from sim.trial.decide import Refused, decide
from sim.trial.events import LoggedEvent
from sim.trial.state import TrialState, fold
from sim.trial.vocabulary import FrameSource, Outcome, Phase, Role


class UnknownTrial(LookupError):
    pass


@dataclass(frozen=True)
class TrialParts:
    """What a trial's runtime uses of the server, shared by every trial of this process."""

    settings: Settings
    db: sessionmaker[Session]
    log: EventLog
    clock: ServerClock
    mazes: Mazes
    frames: FrameStore  # the camera images' files
    backends: BackendParts
    agents: AgentParts
    watch: WatchParts
    over: Callable[[int, Phase], None]  # told once, as a trial of this process becomes over (a study's webhook)


class TrialRuntime:
    def __init__(self, trial_id: int, parts: TrialParts, forget: Callable[[int], None]) -> None:
        self.trial_id, self.parts, self.settings = trial_id, parts, parts.settings
        self._forget = forget  # lets the hub drop a trial that is over and that nobody holds
        self.state = TrialState()
        self.watching = Watch(self, parts.watch)
        self.robot = RobotSeat(self, parts.frames, parts.clock, self.watching)
        self.audience = Audience(trial_id, parts.log, self.watching.watchers)
        self.agents: AgentSeats | None = None
        self.timers = TrialTimers(self, parts.clock, self.settings.grace_period_s)
        self.rates = SeatRates(self.settings.seat_message_rate_per_s, self.settings.seat_message_burst)
        self.refusals = RefusedRuns(lambda event: self._record(event, {}))
        self._tasks: set[asyncio.Task[Any]] = set()
        self._ending = False
        self.history: list[LoggedEvent] = []  # the dialog so far (`views.HISTORY`): welcomes read no log

    # -- life cycle ---------------------------------------------------------------
    async def start(self) -> None:
        events = self.parts.log.load(self.trial_id)
        if not events:
            raise UnknownTrial(f"trial {self.trial_id} does not exist")
        self.state = fold(events)
        self.history = [e for e in events if e.is_(*views.HISTORY)]
        self.apply(c.Reopen())  # seats and moves of an earlier server process are gone
        if self.state.over:
            return
        self.timers.expect_joins()
        self.timers.expect_time_cap()
        self.agents = AgentSeats.of(self, self.parts.agents)  # before the backend: the first frame is seen
        await self.robot.start(self.parts.backends)
        if self.agents is not None:
            self.agents.start()

    async def close(self) -> None:
        self.timers.close()
        self.refusals.flush()
        if self.state.over:
            self.apply(c.AbandonMoves(f"the trial is {self.state.phase}"))
        for task in list(self._tasks):
            if task is not asyncio.current_task():
                task.cancel()
        if self.agents is not None:
            await self.agents.stop()
            seats = self.audience.seats
            self.audience.seats = {role: conn for role, conn in seats.items() if not isinstance(conn, AgentSeat)}
        self.watching.close()
        await self.robot.close()

    def _forget_if_unheld(self) -> None:  # nobody left: this process can let it go
        if self.state.over and self.audience.empty:
            self._forget(self.trial_id)

    async def _end(self) -> None:
        await self.close()
        self._forget_if_unheld()

    def spawn(self, coro: Coroutine[Any, Any, Any]) -> asyncio.Task[Any]:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    # -- the log ------------------------------------------------------------------
    def apply(
        self, command: c.Command, attachments: Attachments | None = None, frame: FrameRow | None = None
    ) -> list[ev.Event]:
        """Decide, commit, fold and tell the seats; returns the events. Raises `Refused`, recording nothing."""
        events = decide(self.state, command)
        if events:
            self.refusals.flush()  # the refusals came first: the log keeps them in order
        was_over = self.state.over
        for event in events:
            self._record(event, attachments or {}, frame)
        if events:
            self._after_change()
            if self.state.over and not was_over:
                self.parts.over(self.trial_id, self.state.phase)
        return events

    def _record(self, event: ev.Event, attachments: Attachments, frame: FrameRow | None = None) -> None:
        t_ns = self.parts.clock.now_ns()
        if self.state.last_t_ns is not None:
            t_ns = max(t_ns, self.state.last_t_ns + 1)  # one trial's stamps never go back, even across restarts
        logged = LoggedEvent(self.state.last_seq + 1, event.kind, t_ns, event.payload())
        cache: TrialCache | None = None
        if isinstance(event, ev.PhaseChanged):
            if event.phase.running and event.target_index is not None:  # the Commander learns each target as reached
                attachments = {**attachments, Role.COMMANDER: {"target": self.state.targets[event.target_index]}}
            active = self.state.active_s(t_ns) if event.phase == Phase.FINISHED else None
            cache = TrialCache(phase=str(event.phase), moves=self.state.moves, active_s=active)
        frame = frame if isinstance(event, ev.FrameRecorded) else None
        self.parts.log.append(self.trial_id, logged, frame=frame, trial_cache=cache)
        self.state.apply_event(event, logged.seq, logged.t_ns)
        if self.agents is not None:
            self.agents.see(event, logged.t_ns)
        if logged.is_(*views.HISTORY):
            self.history.append(logged)
        self.audience.hear(logged, attachments)
        self.watching.ldh.after(logged)

    def _after_change(self) -> None:
        self.audience.status(self.status())
        self.timers.sync()
        if self.state.over and not self._ending:
            self._ending = True
            self.spawn(self._end())

    def status(self) -> StatusMessage:
        return views.status_of(self.state, self.parts.clock.now_ns())

    # -- the robot ----------------------------------------------------------------
    def record_pose(self, pose: tuple[float, float, float]) -> None:
        self.robot.record_pose(pose)

    def record_frame(self, jpeg: bytes, capture_ns: int, width: int, height: int, source: FrameSource) -> int:
        return self.robot.record_frame(Frame(jpeg, capture_ns, width, height), source)

    def frame_jpeg(self, frame_id: int) -> bytes | None:
        return self.parts.frames.read(self.trial_id, frame_id)

    def report_bad_message(self, role: Role, error: str) -> None:
        self.apply(c.Note(ev.BadMessage(role=role, error=error[:500])))

    def true_pose(self) -> tuple[float, float, float] | None:
        return self.robot.true_pose()

    # -- seats and watchers -------------------------------------------------------
    def join(self, conn: Connection) -> None:
        previous = self.audience.seats.get(conn.role)
        self.audience.seats[conn.role] = conn
        if previous is not None:  # the same seat opened again (a second tab): the newest wins
            previous.deliver({"type": ServerMessage.REPLACED})
        else:
            self.apply(c.Join(Role(conn.role)))
        self.audience.send(conn, self.welcome(conn.role))

    def leave(self, conn: Connection) -> None:
        if self.audience.seats.get(conn.role) is not conn:
            return
        del self.audience.seats[conn.role]
        self.apply(c.Leave(Role(conn.role)))
        self._forget_if_unheld()

    def watch(self, conn: Connection) -> None:
        """An experimenter's live view: every seat's events, the true pose, the beliefs (`Watch`)."""
        self.audience.send(conn, self.welcome(views.EXPERIMENTER))
        self.watching.add(conn, live=self.robot.backend is not None and not self.state.over)

    def unwatch(self, conn: Connection) -> None:
        self.watching.remove(conn)
        self._forget_if_unheld()

    def welcome(self, role: str) -> WelcomeMessage:  # sent once the log has committed what it tells
        seats = self.audience.seats
        return views.welcome(role, self.trial_id, self.state, seats, self.history, self.status(), self.frame_jpeg)

    # -- a seat's actions ---------------------------------------------------------
    async def receive(self, conn: Connection, role: str, message: m.SeatMessage) -> None:
        """One message from a seat's socket, its token checked there; one not allowed now gets an
        error reply and a `bad_message` event. Moves run beside the socket's reader, so one sent while
        one executes is refused, not queued. All but pings count against the seat's rate."""
        action = m.action_of(message)
        if action is None or not self.rates.allows(conn, role):
            return
        acting = self._act_replying(conn, c.Act(Role(role), action))
        if isinstance(action, c.RequestMove):
            self.spawn(acting)
        else:
            await acting

    def refuse_unread(self, conn: Connection, role: str, error: str) -> None:
        """A message its socket could not read (not JSON, too big, another seat's token): refused
        as any other, within the seat's rate."""
        if self.rates.allows(conn, role):
            self.refuse(conn, role, error)

    async def _act_replying(self, conn: Connection, act: c.Act) -> None:
        try:
            await self.act(act)
        except Refused as err:
            self.refuse(conn, act.role, str(err))

    def refuse(self, conn: Connection, role: str, error: str) -> None:
        """The documented error reply, and the refusal in the log (while the trial runs)."""
        self.audience.refused(conn, error)
        if not self.state.over:
            self.report_bad_message(Role(role), error)

    async def act(self, act: c.Act, paced: bool = True) -> list[ev.Event]:
        """A seat's action, from its socket or its agent: decided, recorded and carried out (a move
        up to its outcome); returns the events decided. Raises `Refused`, recording nothing.
        `paced`: a move no sooner than `min_move_interval_s` after the last (two agents may be unpaced)."""
        interval_ns = int(self.settings.min_move_interval_s * 1e9) if paced else 0
        now = c.Now(self.parts.clock.now_ns(), self.robot.backend is not None, interval_ns)
        match act.action:
            case c.RequestMove():
                return await self._move(replace(act, now=now))
            case c.Claim() if (frame_id := self.state.last_frame_id) is not None:
                claim = views.claim_attachment(frame_id, self.frame_jpeg)
                return self.apply(replace(act, now=now), {Role.COMMANDER: {"claim": claim}})
            case c.Judge() if (pose := self.true_pose()) is not None and (claimed := self.state.pending_claim):
                within_m = self.parts.mazes.distance_m(self.state.maze, claimed.target, pose)
                return self.apply(replace(act, now=replace(now, within_m=within_m)))
        return self.apply(replace(act, now=now))

    async def _move(self, act: c.Act) -> list[ev.Event]:
        assert isinstance(act.action, c.RequestMove)  # a socket names its move; one is drawn for an agent's
        request = replace(act.action, move_id=act.action.move_id or uuid.uuid4().hex[:12])
        act = replace(act, action=request)
        asked = decide(self.state, act)
        if isinstance(refusal := asked[0], ev.MovesRefused):  # the Driver hears why now, the log with its run
            self.refusals.hold(refusal)
            self.audience.move_refused(request, refusal.reason, act.now.t_ns)
            return asked
        self.apply(act)
        outcome, reason = await self.robot.execute(request.move)
        self.apply(c.FinishMove(str(request.move_id), outcome, reason))
        if outcome != Outcome.REFUSED:
            self.robot.moved()
        return asked

    # -- experimenter -------------------------------------------------------------
    def pause(self, note: str | None = None) -> None:
        self.apply(c.Pause(note))

    def resume(self) -> None:
        self.apply(c.Resume())

    def abort(self, reason: str | None = None) -> None:
        self.apply(c.Abort(reason))

    def snapshot(self) -> TrialSnapshot:
        now_ns = self.parts.clock.now_ns()
        return views.snapshot(self.trial_id, self.state, now_ns, self.audience.seats, self.watching.message)
