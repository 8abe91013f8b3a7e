"""`TrialRuntime`: one live trial in this process. It only does input and output.

Everything that happens becomes a command for `sim.trial.decide`; the events it returns are
appended to the log (`EventLog`, committed at the end of this event-loop turn) and folded into
the state, and what each seat may hear of them (`app.trial.views`) is sent once they are committed. The runtime holds the sockets, the robot backend and the grace
timers, and the timers are derived from the log (`TrialState.away`), so they survive a restart.
Commands are applied without awaiting between reading the state and recording, so the events
of a trial are totally ordered without locks.
"""

from __future__ import annotations

import asyncio
import base64
import logging
import math
import uuid
from collections.abc import Callable, Coroutine
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from sqlalchemy.orm import Session, sessionmaker

from app.backends.base import BackendUnavailable, Frame, RobotBackend
from app.backends.registry import BackendParts, create_backend
from app.clock import ServerClock
from app.mazes import Mazes
from app.perception.belief import FilterWorker
from app.seats.seat import AgentSeat, AgentSeats
from app.settings import Settings
from app.trial import messages as m
from app.trial import views
from app.trial.frames_store import FrameStore
from app.trial.ldh_belief import BeliefModel, LiveBelief
from app.trial.log import EventLog
from app.trial.messages import ServerMessage
from app.trial.port import Connection
from app.trial.throttle import Throttle
from app.trial.views import EXPERIMENTER, status_of, view
from sim.core.geometry import wrap_angle
from sim.core.rays import RayObservation
from sim.trial import commands as c
from sim.trial import events as ev
from sim.trial.decide import Refused, decide
from sim.trial.events import LoggedEvent
from sim.trial.specs import HUMAN
from sim.trial.state import TrialState, fold
from sim.trial.vocabulary import PARTICIPANTS, FrameSource, Outcome, Phase, PoseSource, Role

if TYPE_CHECKING:
    from app.perception.belief import TrialBelief
    from app.seats.registry import AgentParts

logger = logging.getLogger(__name__)
AWAY_MARK_S = 1.0  # how much of a participant's time away a crash can lose from the grace period
REFUSED_RUN_S = 1.0  # a run of refused move requests is logged at the latest this long after its first


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
    filters: FilterWorker  # every trial's particle filter turns
    frames: FrameStore  # the camera images' files
    backends: BackendParts
    agents: AgentParts
    ldh: BeliefModel  # the watch page's LDH belief
    over: Callable[[int, Phase], None]  # told once, as a trial of this process becomes over (a study's webhook)


class TrialRuntime:
    def __init__(self, trial_id: int, parts: TrialParts, forget: Callable[[int], None]) -> None:
        self.trial_id = trial_id
        self.parts = parts
        self.settings = parts.settings
        self._forget = forget  # lets the hub drop a trial that is over and that nobody holds
        self.state = TrialState()
        self.backend: RobotBackend | None = None
        self.seats: dict[str, Connection] = {}
        self.watchers: set[Connection] = set()  # the experimenter's live views
        self._grace: dict[Role, asyncio.TimerHandle] = {}
        self._join_timer: asyncio.TimerHandle | None = None  # a lobby's trial: seats unopened by its deadline
        self._away_marks: asyncio.Task[None] | None = None  # `still_away` events while anyone is away
        self._tasks: set[asyncio.Task[Any]] = set()
        self._status: dict[str, Any] | None = None  # the last status sent, less the clock
        self._ending = False
        self.agents: AgentSeats | None = None  # the seats agents hold
        # The particle filter runs only while someone watches: its belief is for the watch page alone,
        # and a crowd's unwatched trials would otherwise give it a core and most of the memory.
        self.belief: TrialBelief | None = None  # `TrialBelief` once built for a watcher
        self._belief_task: asyncio.Task[None] | None = None
        self._belief_message: dict[str, Any] | None = None  # the latest, for the watch page
        self._last_frame: Frame | None = None  # the Driver camera's latest, for a filter built after it
        self.ldh = LiveBelief(self, parts.ldh)  # the LDH model's belief, for the watchers only
        self._throttles: dict[str, Throttle] = {}  # per seat: how often its messages may be recorded
        self._refused_run: ev.MovesRefused | None = None  # move requests refused since the last event
        self._refused_timer: asyncio.TimerHandle | None = None  # logs that run at the latest
        # The dialog so far (`views.HISTORY` events), kept from the log: a crowd joining at once
        # read the whole log back, after a synchronous commit, for every welcome.
        self.history: list[LoggedEvent] = []

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
        self._expect_joins()
        self.agents = AgentSeats.of(self, self.parts.agents)  # before the backend: the first frame is seen
        await self._start_backend()
        if self.agents is not None:
            self.agents.start()

    async def _start_backend(self) -> None:
        self.backend = await create_backend(self.state.backend, self, self.parts.backends)
        pose = self.backend.pose()
        if pose is not None and self.state.pose is None:
            self.record_pose(pose)
        self.spawn(self._pump_frames(self.backend))
        self._want_belief()
        await self.backend.connect()

    def _want_belief(self) -> None:
        """Build the particle filter if someone watches a live trial and none is built or building."""
        if self.watchers and self.backend is not None and self.belief is None and self._belief_task is None:
            self._belief_task = self.spawn(self._start_belief())

    def _drop_belief(self) -> None:
        """The last watcher left: let go of the filter (its particles and free-space map are several MB)."""
        if self._belief_task is not None:
            self._belief_task.cancel()
            self._belief_task = None
        if self.belief is not None:
            belief, self.belief = self.belief, None
            self.parts.filters.forget(belief)
        self._belief_message = None

    async def _start_belief(self) -> None:
        """A live particle filter on the Driver camera (shown to the experimenter, never to a seat);
        built when the first watcher comes, from a uniform prior and the camera's latest frame."""
        from app.perception.belief import TrialBelief
        from app.perception.cameras import CameraUnknown, driver_calibration

        try:
            calibration = await asyncio.to_thread(driver_calibration, self.state.backend, self.settings)
            maze = self.parts.mazes.load(self.state.maze)
            self.belief = await self.parts.filters.start(lambda: TrialBelief(maze, calibration, seed=self.trial_id))
            # Built in the filters' share of a core, so frames may have come meanwhile: it starts
            # from what the camera sees now (its prior is uniform, so the moves before do not count).
            if self._last_frame is not None:
                self._offer(self._last_frame)
        except CameraUnknown as err:
            logger.info("trial %s: no particle filter: %s", self.trial_id, err)
        except Exception:  # no belief is a lesser trial, not a broken one
            logger.exception("trial %s: no particle filter", self.trial_id)
        finally:
            if self._belief_task is asyncio.current_task():  # not a newer one, after a drop
                self._belief_task = None

    async def close(self) -> None:
        for timer in self._grace.values():
            timer.cancel()
        self._grace.clear()
        if self._join_timer is not None:
            self._join_timer.cancel()
        self._log_refused_run()
        if self.state.over:
            self.apply(c.AbandonMoves(f"the trial is {self.state.phase}"))
        for task in list(self._tasks):
            if task is not asyncio.current_task():
                task.cancel()
        if self.agents is not None:
            await self.agents.stop()
            for role, conn in list(self.seats.items()):
                if isinstance(conn, AgentSeat):
                    del self.seats[role]
        # Let go of the filter now: its particles and free-space map (several MB, and the
        # maze) sit in reference cycles with this runtime that the collector frees only later.
        self._drop_belief()
        if self.backend is not None:
            backend, self.backend = self.backend, None
            await backend.close()

    async def _end(self) -> None:
        await self.close()
        if not self.seats and not self.watchers:
            self._forget(self.trial_id)

    def spawn(self, coro: Coroutine[Any, Any, Any]) -> asyncio.Task[Any]:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    # -- the log ------------------------------------------------------------------
    def apply(
        self,
        command: c.Command,
        attachments: dict[str, dict[str, Any]] | None = None,
        frame: dict[str, Any] | None = None,
    ) -> list[LoggedEvent]:
        """Decide, commit, fold and tell the seats; raises `Refused` (recording nothing)."""
        return self._commit(decide(self.state, command), attachments, frame)

    def _commit(
        self,
        events: list[ev.Event],
        attachments: dict[str, dict[str, Any]] | None = None,
        frame: dict[str, Any] | None = None,
    ) -> list[LoggedEvent]:
        if events:
            self._log_refused_run()  # the refusals came first: the log keeps them in order
        was_over = self.state.over
        logged = [self._record(event, attachments or {}, frame) for event in events]
        if logged:
            self._after_change()
            if self.state.over and not was_over:
                self.parts.over(self.trial_id, self.state.phase)
        return logged

    def _hold_refusal(self, refusal: ev.MovesRefused) -> None:
        """Count a refused move request in the run it belongs to: the same reason, nothing
        logged since. The run is logged as one event when it ends, or `REFUSED_RUN_S` after its
        first request, so a crash loses at most that much of the count."""
        run = self._refused_run
        if run is not None and run.reason != refusal.reason:
            self._log_refused_run()
            run = None
        if run is None:
            self._refused_run = refusal
            self._refused_timer = asyncio.get_running_loop().call_later(REFUSED_RUN_S, self._log_refused_run)
        else:
            self._refused_run = run.model_copy(update={"count": run.count + refusal.count})

    def _log_refused_run(self) -> None:
        if self._refused_timer is not None:
            self._refused_timer.cancel()
            self._refused_timer = None
        run, self._refused_run = self._refused_run, None
        if run is not None:
            self._record(run, {}, None)

    def _record(
        self, event: ev.Event, attachments: dict[str, dict[str, Any]], frame: dict[str, Any] | None
    ) -> LoggedEvent:
        t_ns = self.parts.clock.now_ns()
        if self.state.last_t_ns is not None:
            t_ns = max(t_ns, self.state.last_t_ns + 1)  # one trial's stamps never go back, even across restarts
        logged = LoggedEvent(self.state.last_seq + 1, event.kind, t_ns, event.payload())
        cache = None
        if isinstance(event, ev.PhaseChanged) and event.phase.running and event.target_index is not None:
            # The Commander learns each target as the trial reaches it.
            attachments = {**attachments, Role.COMMANDER: {"target": self.state.targets[event.target_index]}}
        if isinstance(event, ev.PhaseChanged):
            active = self.state.active_s(t_ns) if event.phase == Phase.FINISHED else None
            cache = {"phase": str(event.phase), "moves": self.state.moves, "active_s": active}
        self.parts.log.append(
            self.trial_id, logged, frame=frame if isinstance(event, ev.FrameRecorded) else None, trial_cache=cache
        )
        self.state.apply_event(event, logged.seq, logged.t_ns)
        if self.agents is not None:
            self.agents.see(event, logged.t_ns)
        if logged.is_(*views.HISTORY):
            self.history.append(logged)
        self._broadcast(logged, attachments)
        self.ldh.after(logged)
        return logged

    def _send(self, conn: Connection, message: dict[str, Any]) -> None:
        """What a seat hears of the log goes out once the log has committed it (group commit)."""
        self.parts.log.after_commit(self.trial_id, conn.deliver, message)

    def _broadcast(self, logged: LoggedEvent, attachments: dict[str, dict[str, Any]]) -> None:
        for role, conn in list(self.seats.items()):
            message = view(role, logged)
            if message is not None:
                message.update(attachments.get(role, {}))
                self._send(conn, message)
        for conn in list(self.watchers):
            message = view(EXPERIMENTER, logged)
            if message is not None:
                message.update(attachments.get(Role.DRIVER if logged.is_(ev.FrameRecorded) else EXPERIMENTER, {}))
                self._send(conn, message)

    def _after_change(self) -> None:
        status = self.status()
        if {k: v for k, v in status.items() if k not in views.CLOCK_FIELDS} != self._status:
            self._status = {k: v for k, v in status.items() if k not in views.CLOCK_FIELDS}
            for role, conn in list(self.seats.items()):
                if role in PARTICIPANTS:
                    self._send(conn, status)
            for conn in list(self.watchers):
                self._send(conn, status)
        self._sync_grace()
        if self.state.over and not self._ending:
            self._ending = True
            self.spawn(self._end())

    def status(self) -> dict[str, Any]:
        return status_of(self.state, self.parts.clock.now_ns())

    # -- grace timers, from the log -------------------------------------------------
    def _sync_grace(self) -> None:
        away = self.state.away
        for role in [r for r in self._grace if r not in away]:
            self._grace.pop(role).cancel()
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        for role in away:
            if role not in self._grace:
                self._grace[role] = loop.call_later(self._grace_left_s(role), self._grace_expired, role)
        if away and (self._away_marks is None or self._away_marks.done()):
            self._away_marks = self.spawn(self._mark_time_away())

    async def _mark_time_away(self) -> None:
        """A restart knows when the server was last up only from the log: while anyone is away,
        note it every `AWAY_MARK_S`, so their time away before a crash still counts."""
        while True:
            await asyncio.sleep(AWAY_MARK_S)
            if not self.state.away:
                return
            self.apply(c.Note(ev.StillAway(roles=sorted(self.state.away))))

    def _grace_left_s(self, role: Role) -> float:
        gone = self.state.away[role].away_ns(self.parts.clock.now_ns())
        return self.settings.grace_period_s - gone / 1e9

    def _grace_expired(self, role: Role) -> None:
        self._grace.pop(role, None)
        if role not in self.state.away:
            return
        left_s = self._grace_left_s(role)
        if left_s > 0:  # event loops may wake a little early (uvloop: to the millisecond)
            self._grace[role] = asyncio.get_running_loop().call_later(left_s, self._grace_expired, role)
            return
        self.apply(c.GraceExpired(role))

    # -- what the backend reports -------------------------------------------------
    def record_pose(self, pose: tuple[float, float, float]) -> None:
        x, y, theta = pose
        source = self.backend.pose_source if self.backend is not None else PoseSource.TRACKER
        self.apply(c.Note(ev.PoseSampled(x=x, y=y, heading=wrap_angle(theta), source=source)))

    async def _pump_frames(self, backend: RobotBackend) -> None:
        async for frame in backend.frames():
            try:
                rel = FrameStore.name(self.trial_id, frame.capture_ns, FrameSource.DRIVER)
                # The file is written off the event loop (slow disks must not delay other trials).
                await asyncio.to_thread(self.parts.frames.write, rel, frame.jpeg)
                self._commit_frame(
                    rel, frame.jpeg, frame.capture_ns, frame.width, frame.height, FrameSource.DRIVER, frame.observation
                )
            except Exception:  # a frame that cannot be stored must not stop the stream
                logger.exception("trial %s: frame not recorded", self.trial_id)
                continue
            self._last_frame = frame
            self._offer(frame)

    def _offer(self, frame: Frame) -> None:
        """A Driver frame for the particle filter, taken in at its next turn (not while a move runs)."""
        belief = self.belief
        if (
            belief is not None
            and not self.state.moves_in_flight
            and belief.offer(frame.jpeg, frame.capture_ns, frame.observation)
        ):
            self.parts.filters.due(belief, self._believed)

    def _believed(self) -> None:
        """The filter has taken in a frame: the watchers see the new belief."""
        if self.belief is None or (message := self.belief.message()) is None:
            return
        self._belief_message = message
        for conn in list(self.watchers):
            conn.deliver(message)

    def record_frame(self, jpeg: bytes, capture_ns: int, width: int, height: int, source: FrameSource) -> int:
        rel = FrameStore.name(self.trial_id, capture_ns, source)
        self.parts.frames.write(rel, jpeg)
        return self._commit_frame(rel, jpeg, capture_ns, width, height, source)

    def _commit_frame(
        self,
        rel: str,
        jpeg: bytes,
        capture_ns: int,
        width: int,
        height: int,
        source: FrameSource,
        rays: RayObservation | None = None,
    ) -> int:
        row = {"source": str(source), "path": rel, "capture_ns": capture_ns, "width": width, "height": height}
        frame_id = self.state.last_seq + 1  # the frame event's own seq
        seen = {"rays": rays, "jpeg": jpeg} if source == FrameSource.DRIVER else {}  # for the agent seats
        event = ev.FrameRecorded(
            frame_id=frame_id, source=source, path=rel, capture_ns=capture_ns, width=width, height=height, **seen
        )
        attach: dict[str, dict[str, Any]] = (
            {Role.DRIVER: {"jpeg": base64.b64encode(jpeg).decode()}} if source == FrameSource.DRIVER else {}
        )
        self.apply(c.Note(event), attachments=attach, frame=row)
        return frame_id

    def frame_jpeg(self, frame_id: int) -> bytes | None:
        return self.parts.frames.read(self.trial_id, frame_id)

    def report_bad_message(self, role: Role, error: str) -> None:
        self.apply(c.Note(ev.BadMessage(role=role, error=error[:500])))

    def true_pose(self) -> tuple[float, float, float] | None:
        return self.backend.pose() if self.backend is not None else None

    # -- seats --------------------------------------------------------------------
    def join(self, conn: Connection) -> None:
        role = conn.role
        previous = self.seats.get(role)
        self.seats[role] = conn
        if previous is not None:  # the same seat opened again (a second tab): the newest wins
            previous.deliver({"type": ServerMessage.REPLACED})
        else:
            self.apply(c.Join(Role(role)))
        self._send(conn, self.welcome(role))

    def leave(self, conn: Connection) -> None:
        if self.seats.get(conn.role) is not conn:
            return
        del self.seats[conn.role]
        self.apply(c.Leave(Role(conn.role)))
        if self.state.over and not self.seats and not self.watchers:
            self._forget(self.trial_id)  # nobody left: this process can let it go

    def watch(self, conn: Connection) -> None:
        """An experimenter's live view: every seat's events, the Driver's camera, the true pose
        and the particle filter's belief (`{"type": "belief", ...}`, after each perceived frame)."""
        self.watchers.add(conn)
        self._send(conn, self.welcome(EXPERIMENTER))
        self.ldh.welcome(conn)
        if self._belief_message is not None:
            conn.deliver(self._belief_message)
        if not self.state.over:
            self._want_belief()

    def unwatch(self, conn: Connection) -> None:
        self.watchers.discard(conn)
        if not self.watchers:
            self._drop_belief()
        if self.state.over and not self.seats and not self.watchers:
            self._forget(self.trial_id)

    def welcome(self, role: str) -> dict[str, Any]:
        """Sent as the seat's events are, once the log has committed what it tells."""
        return views.welcome(role, self.trial_id, self.state, self.seats, self.history, self.status(), self.frame_jpeg)

    # -- messages -----------------------------------------------------------------
    async def receive(self, conn: Connection, role: str, message: m.SeatMessage) -> None:
        """One message from a seat's socket, read and its token checked there. One not allowed
        now gets an error reply and a `bad_message` event, and never ends the trial. Moves run
        beside the socket's reader, so a move sent while one is executing is refused rather than queued.
        Every message but a ping counts against the seat's rate, a move whether executed or refused."""
        action = m.action_of(message)
        if action is None or not self._within_rate(conn, role):
            return
        acting = self._act_reporting(conn, c.Act(Role(role), action))
        if isinstance(action, c.RequestMove):
            self.spawn(acting)
        else:
            await acting

    def refuse_unread(self, conn: Connection, role: str, error: str) -> None:
        """A message its socket could not read (not JSON, too big, another seat's token): refused
        as any other, within the seat's rate."""
        if self._within_rate(conn, role):
            self.refuse(conn, role, error)

    async def _act_reporting(self, conn: Connection, act: c.Act) -> None:
        try:
            await self.act(act)
        except Refused as err:
            self.refuse(conn, act.role, str(err))

    def refuse(self, conn: Connection, role: str, error: str) -> None:
        """The documented error reply, and the refusal in the log (while the trial runs)."""
        conn.deliver({"type": ServerMessage.ERROR, "code": "bad_message", "error": error})
        if not self.state.over:
            self.report_bad_message(Role(role), error)

    def _within_rate(self, conn: Connection, role: str) -> bool:
        """Whether a seat's message may be recorded now; else neither the log nor the other seat
        hears of it, and the first of a run of such messages gets the `rate_limited` reply (one
        reply each would flood the sender's own socket)."""
        throttle = self._throttles.get(role)
        if throttle is None:
            throttle = self._throttles[role] = Throttle(
                self.settings.seat_message_rate_per_s, self.settings.seat_message_burst
            )
        wait_s = throttle.take()
        if not wait_s:
            throttle.told = False
        elif not throttle.told:
            throttle.told = True
            conn.deliver(
                {
                    "type": ServerMessage.ERROR,
                    "code": "rate_limited",
                    "error": f"too many messages at once (at most {throttle.rate_per_s:g} a second); "
                    "this one and any more before the pause were not sent",
                    "retry_after_s": math.ceil(wait_s * 1000) / 1000,
                }
            )
        return not wait_s

    async def act(self, act: c.Act, paced: bool = True) -> list[ev.Event]:
        """A seat's action, from its socket or its agent: decided, recorded and carried out (a
        move up to its outcome); returns the events decided. Raises `Refused`, recording nothing.
        `paced`: moves no sooner than `min_move_interval_s` after the last (two agents may be unpaced)."""
        now = c.Now(
            t_ns=self.parts.clock.now_ns(),
            robot_ready=self.backend is not None,
            min_move_interval_ns=int(self.settings.min_move_interval_s * 1e9) if paced else 0,
        )
        match act.action:
            case c.RequestMove():
                return await self._move(replace(act, now=now))
            case c.Claim() if self.state.last_frame_id is not None:
                claim = views.claim_attachment(self.state.last_frame_id, self.frame_jpeg)
                return self._decide(replace(act, now=now), {Role.COMMANDER: {"claim": claim}})
            case c.Judge():
                s, pose, within_m = self.state, self.true_pose(), None
                if pose is not None and s.pending_claim is not None:
                    within_m = self.parts.mazes.distance_m(s.maze, s.pending_claim["target"], pose)
                return self._decide(replace(act, now=replace(now, within_m=within_m)))
        return self._decide(replace(act, now=now))

    def _decide(self, command: c.Command, attachments: dict[str, dict[str, Any]] | None = None) -> list[ev.Event]:
        events = decide(self.state, command)
        self._commit(events, attachments)
        return events

    async def _move(self, act: c.Act) -> list[ev.Event]:
        assert isinstance(act.action, c.RequestMove)
        move_id = act.action.move_id or uuid.uuid4().hex[:12]
        asked = decide(self.state, replace(act, action=replace(act.action, move_id=move_id)))
        if isinstance(refusal := asked[0], ev.MovesRefused):  # the Driver hears why now, the log with its run
            self._hold_refusal(refusal)
            driver = self.seats.get(Role.DRIVER)
            if driver is not None:
                self._send(
                    driver,
                    {
                        "type": ServerMessage.MOVE_REFUSED,
                        "move_id": move_id,
                        "action": str(act.action.move),
                        "reason": refusal.reason,
                        "t_ns": act.now.t_ns,
                    },
                )
            return asked
        self._commit(asked)
        (requested,) = asked
        assert isinstance(requested, ev.MoveRequested)
        backend = self.backend
        assert backend is not None  # RequestMove refuses every move while there is no backend
        reason = None
        started_ns = self.parts.clock.now_ns()
        try:
            result = await backend.execute(requested.action)
            outcome, reason = result.outcome, result.reason
        except BackendUnavailable as err:
            outcome, reason = Outcome.REFUSED, str(err)
        if outcome != Outcome.REFUSED and self.belief is not None:
            # A collision on the simulator leaves the robot where it was; a rover cannot tell.
            self.belief.moved(requested.action if outcome == Outcome.OK else None, started_ns)
        self.apply(c.FinishMove(requested.move_id, outcome, reason))
        if (
            outcome != Outcome.REFUSED
            and self.backend is not None
            and not self.state.over
            and self.backend.pose_source == PoseSource.SIM
        ):  # a simulator knows where the move left it; a rover's tracker records its own poses
            pose = self.backend.pose()
            if pose is not None:
                self.record_pose(pose)
        return asked

    # -- experimenter -------------------------------------------------------------
    def pause(self) -> None:
        self.apply(c.Pause())

    def resume(self) -> None:
        self.apply(c.Resume())

    def abort(self, reason: str | None = None) -> None:
        self.apply(c.Abort(reason))

    def _expect_joins(self) -> None:
        """A trial a study's lobby paired: if a person's seat is still unopened at the logged
        deadline and the trial has not started, it is aborted, saying whose (the lobby re-pairs)."""
        s = self.state
        if s.join_by_ns is not None and s.phase == Phase.WAITING:
            left_s = max(0.0, (s.join_by_ns - self.parts.clock.now_ns()) / 1e9)
            self._join_timer = asyncio.get_running_loop().call_later(left_s, self._joins_due)

    def _joins_due(self) -> None:
        s = self.state
        people = [role for role, spec in ((Role.COMMANDER, s.commander), (Role.DRIVER, s.driver)) if spec == str(HUMAN)]
        absent = [role for role in people if role not in s.joined]
        if s.phase == Phase.WAITING and absent:
            self.apply(c.Abort(" and ".join(f"the {role}" for role in absent) + " never joined"))

    def snapshot(self) -> dict[str, Any]:
        now_ns = self.parts.clock.now_ns()
        return views.snapshot(self.trial_id, self.state, now_ns, self.seats, self._belief_message)
