"""`TrialRuntime`: one live trial in this process: its state, robot backend and seats.

Every change goes through `record`, which commits the event, folds it into the state and
only then tells the seats (each through its own filter, `app.trial.views`). Handlers that
change state do so without awaiting between reading the state and recording, so events of a
trial are totally ordered without locks.
"""

from __future__ import annotations

import asyncio
import base64
import logging
import time
import uuid
from typing import Any, Protocol

from pydantic import ValidationError

from app.backends.base import BackendUnavailable, MoveOutcome, RobotBackend
from app.backends.registry import create_backend
from app.security import InvalidToken, Seat
from app.trial import messages as m
from app.trial.state import PARTICIPANT_ROLES, LoggedEvent, TrialState, fold
from app.trial.views import view
from sim.geometry import SUCCESS_RADIUS_M

logger = logging.getLogger(__name__)


class Connection(Protocol):
    role: str

    def deliver(self, message: dict[str, Any]) -> None:
        """Queue a message for this seat; never blocks."""


class TrialError(ValueError):
    """A message that is well formed but not allowed now; the reply names why."""


class UnknownTrial(LookupError):
    pass


class TrialRuntime:
    def __init__(self, trial_id: int, services) -> None:
        self.trial_id = trial_id
        self.services = services
        self.settings = services.settings
        self.state = TrialState()
        self.backend: RobotBackend | None = None
        self.seats: dict[str, Connection] = {}
        self._move_busy = False
        self._last_move_ns = 0
        self._grace: dict[str, asyncio.Task] = {}
        self._tasks: set[asyncio.Task] = set()
        self.agent = None
        self.belief = None  # `TrialBelief` once the Driver camera's calibration is loaded
        self._perceiving = False
        self.watch_messages: dict[str, dict[str, Any]] = {}  # the latest of each kind, for the watch page
        self._frame_dirs: set = set()

    # -- life cycle ---------------------------------------------------------------
    async def start(self) -> None:
        events = self.services.log.load(self.trial_id)
        if not events:
            raise UnknownTrial(f"trial {self.trial_id} does not exist")
        self.state = fold(events)
        # Seats the log still lists as connected belong to an earlier server process.
        for role in sorted(self.state.connected):
            self._seat_lost(role)
        if not self.state.over:
            await self._start_backend()
            if self.state.driver.startswith("agent:"):
                from app.drivers.seat import AgentSeat

                self.agent = AgentSeat(self)
                self.agent.start()

    async def _start_backend(self) -> None:
        self.backend = await create_backend(self.state.backend, self)
        pose = self.backend.pose()
        if pose is not None and self.state.pose is None:
            self.record_pose(pose)
        self._spawn(self._pump_frames(self.backend))
        self._spawn(self._start_belief())
        await self.backend.connect()

    async def _start_belief(self) -> None:
        """A live particle filter on the Driver camera (never shown to a participant)."""
        from app.perception.belief import TrialBelief
        from app.perception.cameras import driver_calibration

        try:
            calibration = await asyncio.to_thread(driver_calibration, self.state.backend, self.settings)
            maze = self.services.mazes.load(self.state.maze)
            self.belief = await asyncio.to_thread(TrialBelief, maze, calibration, seed=self.trial_id)
        except Exception:  # no belief is a lesser trial, not a broken one
            logger.exception("trial %s: no particle filter", self.trial_id)

    async def close(self) -> None:
        for task in list(self._grace.values()) + list(self._tasks):
            if task is not asyncio.current_task():
                task.cancel()
        if self.agent is not None:
            await self.agent.stop()
            if self.seats.get("driver") is self.agent:
                del self.seats["driver"]
        if self.backend is not None:
            backend, self.backend = self.backend, None
            await backend.close()

    def _spawn(self, coro) -> asyncio.Task:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    # -- the log ------------------------------------------------------------------
    def record(self, kind: str, payload: dict[str, Any], *, frame: dict[str, Any] | None = None,
               attachments: dict[str, dict[str, Any]] | None = None) -> LoggedEvent:
        """Commit one event, fold it into the state, then tell the seats."""
        t_ns = self.services.clock.now_ns()
        if self.state.last_t_ns is not None:
            t_ns = max(t_ns, self.state.last_t_ns + 1)  # one trial's stamps never go back, even across restarts
        event = LoggedEvent(self.state.last_seq + 1, kind, t_ns, payload)
        cache = None
        if kind == "phase":
            cache = {"phase": payload["phase"], "moves": self.state.moves,
                     "active_s": self.state.active_s(t_ns) if payload["phase"] == "finished" else None}
        self.services.log.append(self.trial_id, event, frame=frame, trial_cache=cache)
        self.state.apply(event)
        self._broadcast(event, attachments or {})
        return event

    def _broadcast(self, event: LoggedEvent, attachments: dict[str, dict[str, Any]]) -> None:
        for role, conn in list(self.seats.items()):
            message = view(role, event)
            if message is not None:
                message.update(attachments.get(role, {}))
                conn.deliver(message)

    def record_pose(self, pose: tuple[float, float, float]) -> None:
        x, y, theta = pose
        source = "sim" if self.state.backend == "sim" else "tracker"
        self.record("pose", {"x": x, "y": y, "heading": theta, "source": source})

    def record_phase(self, phase: str, target_index: int | None = None) -> None:
        payload: dict[str, Any] = {"phase": phase, "target_index": target_index}
        attachments = {}
        if phase in ("localizing", "navigating") and target_index is not None:
            attachments["commander"] = {"target": self.state.targets[target_index]}
        self.record("phase", payload, attachments=attachments)
        if phase in ("finished", "aborted"):
            self._spawn(self.close())

    # -- frames -------------------------------------------------------------------
    async def _pump_frames(self, backend: RobotBackend) -> None:
        async for frame in backend.frames():
            try:
                rel = self._frame_file(frame.capture_ns, "driver")
                # The file is written off the event loop (slow disks must not delay other trials).
                await asyncio.to_thread(self._write_frame_file, rel, frame.jpeg)
                self._commit_frame(rel, frame.jpeg, frame.capture_ns, frame.width, frame.height, "driver")
            except Exception:  # a frame that cannot be stored must not stop the stream
                logger.exception("trial %s: frame not recorded", self.trial_id)
                continue
            belief = self.belief
            if belief is not None and not self._move_busy and not self._perceiving and belief.wants(frame.capture_ns):
                self._perceiving = True
                self._spawn(self._perceive(belief, frame.jpeg, frame.capture_ns))

    async def _perceive(self, belief, jpeg: bytes, capture_ns: int) -> None:
        try:
            observed = await asyncio.to_thread(belief.observe, jpeg, capture_ns)
        finally:
            self._perceiving = False
        if observed is not None:
            self._watchers_hear(belief.message())

    def _watchers_hear(self, message: dict[str, Any]) -> None:
        """A message for the experimenter's view only (the seats never get it)."""
        self.watch_messages[message["type"]] = message

    def record_frame(self, jpeg: bytes, capture_ns: int, width: int, height: int, source: str) -> int:
        """Store one camera image and commit its row and `frame` event; returns the frame id."""
        rel = self._frame_file(capture_ns, source)
        self._write_frame_file(rel, jpeg)
        return self._commit_frame(rel, jpeg, capture_ns, width, height, source)

    def _frame_file(self, capture_ns: int, source: str) -> str:
        return f"{self.trial_id}/{capture_ns}-{source}.jpg"  # relative to frames_dir

    def _commit_frame(self, rel: str, jpeg: bytes, capture_ns: int, width: int, height: int, source: str) -> int:
        row = {"source": source, "path": rel, "capture_ns": capture_ns, "width": width, "height": height}
        frame_id = self.state.last_seq + 1  # the frame event's own seq
        payload = {"frame_id": frame_id, **row, "mime": "image/jpeg"}
        attach = {"driver": {"jpeg": base64.b64encode(jpeg).decode()}} if source == "driver" else {}
        self.record("frame", payload, frame=row, attachments=attach)
        return frame_id

    def _write_frame_file(self, rel: str, jpeg: bytes) -> None:
        path = self.settings.frames_dir / rel
        if path.parent not in self._frame_dirs:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._frame_dirs.add(path.parent)
        path.write_bytes(jpeg)

    def frame_jpeg(self, frame_id: int) -> bytes | None:
        from sqlalchemy import select

        from app.db.models import Frame

        with self.services.db() as db:
            rel = db.scalar(select(Frame.path).where(Frame.trial_id == self.trial_id, Frame.seq == frame_id))
        if rel is None:
            return None
        try:
            return (self.settings.frames_dir / rel).read_bytes()
        except OSError:
            return None

    # -- seats --------------------------------------------------------------------
    def join(self, conn: Connection) -> None:
        role = conn.role
        previous = self.seats.get(role)
        self.seats[role] = conn
        if previous is not None:  # the same seat opened again (a second tab): the newest wins
            previous.deliver({"type": "replaced"})
        else:
            grace = self._grace.pop(role, None)
            if grace is not None:
                grace.cancel()
            if not self.state.over:
                self.record("connect", {"role": role})
                if f"disconnect:{role}" in self.state.pause_reasons:
                    self.record("resumed", {"reason": f"disconnect:{role}"})
                self._maybe_start()
        conn.deliver(self.welcome(role))

    def leave(self, conn: Connection) -> None:
        if self.seats.get(conn.role) is not conn:
            return
        del self.seats[conn.role]
        if not self.state.over:
            self._seat_lost(conn.role)
        elif not self.seats:  # over and nobody left watching: this process can let it go
            self.services.hub.forget(self.trial_id)

    def _seat_lost(self, role: str) -> None:
        self.record("disconnect", {"role": role})
        if self.state.phase in ("localizing", "navigating"):
            reason = f"disconnect:{role}"
            if reason not in self.state.pause_reasons:
                self.record("paused", {"reason": reason})
            if role in PARTICIPANT_ROLES:
                self._grace[role] = self._spawn(self._grace_expires(role))

    async def _grace_expires(self, role: str) -> None:
        await asyncio.sleep(self.settings.grace_period_s)
        self._grace.pop(role, None)
        if role not in self.seats and not self.state.over:
            self.record_phase("aborted")

    def _maybe_start(self) -> None:
        if self.state.phase == "waiting" and not self.state.waiting_for:
            self.record_phase("localizing", 0)

    def welcome(self, role: str) -> dict[str, Any]:
        s = self.state
        message: dict[str, Any] = {
            "type": "welcome", "role": role, "trial_id": self.trial_id, "phase": s.phase,
            "target_index": s.target_index, "targets_total": len(s.targets),
            "connected": sorted(self.seats), "seats_needed": list(s.seats_needed), "paused": sorted(s.pause_reasons),
            "pending_claim": s.pending_claim is not None, "last_seq": s.last_seq,
            "history": [msg for e in self.services.log.load(self.trial_id)
                        if e.kind in ("chat", "phase", "target_confirmed", "target_rejected")
                        and (msg := view(role, e)) is not None],
        }
        if role == "commander":
            message["target"] = s.current_target
            if s.pending_claim is not None:
                message["claim"] = self._claim_attachment(s.pending_claim["frame_id"])
        if role == "driver" and s.last_frame_id is not None:
            jpeg = self.frame_jpeg(s.last_frame_id)
            if jpeg is not None:
                message["frame"] = {"frame_id": s.last_frame_id, "jpeg": base64.b64encode(jpeg).decode()}
        return message

    def _claim_attachment(self, frame_id: int) -> dict[str, Any]:
        jpeg = self.frame_jpeg(frame_id)
        return {"frame_id": frame_id, "jpeg": base64.b64encode(jpeg).decode() if jpeg else None}

    # -- messages -----------------------------------------------------------------
    async def receive(self, conn: Connection, seat: Seat, text: str | None) -> None:
        """One raw message from a seat's socket. A bad one gets an error reply and a
        `bad_message` event, and never ends the trial. Moves run beside the socket's reader,
        so a move sent while one is executing is refused rather than queued."""
        try:
            message = self._parse(seat, text)
            if isinstance(message, m.Move) and message.type in m.ALLOWED[seat.role]:
                self._spawn(self._handle_reporting(conn, seat.role, message))
            else:
                await self.handle(seat.role, message)
        except TrialError as err:
            self._refuse(conn, seat.role, err)

    async def _handle_reporting(self, conn: Connection, role: str, message) -> None:
        try:
            await self.handle(role, message)
        except TrialError as err:
            self._refuse(conn, role, err)

    def _refuse(self, conn: Connection, role: str, err: TrialError) -> None:
        conn.deliver({"type": "error", "error": str(err)})
        if not self.state.over:
            self.record("bad_message", {"role": role, "error": str(err)[:500]})

    def _parse(self, seat: Seat, text: str | None):
        limit = self.settings.max_message_bytes
        if text is None:
            raise TrialError("messages must be JSON text, not binary")
        size = len(text.encode())
        if size > limit:
            raise TrialError(f"message is {size} bytes; the limit is {limit}")
        try:
            message = m.seat_message.validate_json(text)
        except ValidationError as err:
            raise TrialError(f"invalid message: {_describe(err)}") from None
        try:
            if self.services.seats.verify(message.token) != seat:
                raise InvalidToken("token is for another seat")
        except InvalidToken as err:
            raise TrialError(f"token refused: {err}") from None
        return message

    async def handle(self, role: str, message) -> None:
        """Apply one validated message from a seat; raises TrialError when not allowed now."""
        if message.type not in m.ALLOWED[role]:
            raise TrialError(f"the {role} may not send {message.type!r} messages")
        if message.type == "ping":
            return
        if self.state.over:
            raise TrialError(f"the trial is {self.state.phase}")
        match message:
            case m.Chat(text=text):
                self.record("chat", {"role": role, "text": text})
            case m.Move(action=action, move_id=move_id):
                await self.move(action, move_id)
            case m.Localize(x=x, y=y, heading=heading):
                self.localize(x, y, heading)
            case m.Claim():
                self.claim()
            case m.Confirm():
                self.decide(confirmed=True)
            case m.Reject():
                self.decide(confirmed=False)

    async def move(self, action: str, move_id: str | None = None) -> MoveOutcome:
        move_id = move_id or uuid.uuid4().hex[:12]
        now = time.monotonic_ns()
        reason = None
        if not self.state.running:
            reason = self._why_not_running()
        elif self._move_busy:
            reason = "the previous move is still executing"
        elif now - self._last_move_ns < self.settings.min_move_interval_s * 1e9:
            reason = "too soon after the previous move"
        elif self.backend is None:
            reason = "the robot is not connected"
        self.record("move_requested", {"move_id": move_id, "action": action})
        if reason is not None:
            outcome = MoveOutcome(action, "refused", reason)
        else:
            self._move_busy, self._last_move_ns = True, now
            started_ns = self.services.clock.now_ns()
            try:
                outcome = await self.backend.execute(action)
            except BackendUnavailable as err:
                outcome = MoveOutcome(action, "refused", str(err))
            finally:
                self._move_busy = False
            if outcome.outcome != "refused" and self.belief is not None:
                # A collision on the simulator leaves the robot where it was; a rover cannot tell.
                self.belief.moved(action if outcome.outcome == "ok" else None, started_ns)
        payload = {"move_id": move_id, "action": action, "outcome": outcome.outcome,
                   "collision": outcome.collision}
        if outcome.reason:
            payload["reason"] = outcome.reason
        self.record("move_executed", payload)
        if outcome.outcome != "refused" and self.backend is not None and self.state.backend == "sim":
            # (a rover's tracker records its own poses, at the overhead camera's rate)
            pose = self.backend.pose()
            if pose is not None:
                self.record_pose(pose)
        return outcome

    def _why_not_running(self) -> str:
        s = self.state
        if s.waiting_for:
            return f"the trial is waiting for the {' and the '.join(s.waiting_for)} to connect"
        if "disconnect:robot" in s.pause_reasons:
            return "the trial is paused: the robot is not connected"
        return "the trial is paused" if s.pause_reasons else f"the trial is {s.phase}"

    def localize(self, x: float, y: float, heading: float | None) -> None:
        if self.state.phase not in ("localizing", "navigating"):
            raise TrialError(f"cannot mark the robot while the trial is {self.state.phase}")
        self.record("localization", {"x": x, "y": y, "heading": heading})
        if self.state.phase == "localizing":
            self.record_phase("navigating", 0)

    def claim(self) -> None:
        s = self.state
        if s.phase != "navigating" or s.pause_reasons:
            raise TrialError("a target can be claimed only while navigating")
        if s.pending_claim is not None:
            raise TrialError("the previous claim is still waiting for the Commander")
        if s.last_frame_id is None:
            raise TrialError("there is no camera frame to send yet")
        self.record("target_claimed", {"target": s.current_target, "target_index": s.target_index,
                                       "frame_id": s.last_frame_id},
                    attachments={"commander": {"claim": self._claim_attachment(s.last_frame_id)}})

    def decide(self, confirmed: bool) -> None:
        s = self.state
        if s.pending_claim is None:
            raise TrialError("there is no claimed target to confirm or reject")
        target, index = s.pending_claim["target"], s.pending_claim["target_index"]
        within_m = truly = None
        pose = self.backend.pose() if self.backend is not None else None
        if pose is not None:
            ox, oy = self.services.mazes.load(s.maze).objects[target]
            within_m = float(((pose[0] - ox) ** 2 + (pose[1] - oy) ** 2) ** 0.5)
            truly = within_m <= SUCCESS_RADIUS_M
        self.record("target_confirmed" if confirmed else "target_rejected",
                    {"target": target, "target_index": index, "within_m": within_m, "truly_within": truly})
        if confirmed:
            if index + 1 >= len(s.targets):
                self.record_phase("finished", index + 1)
            else:
                self.record_phase("navigating", index + 1)

    # -- experimenter -------------------------------------------------------------
    def pause(self) -> None:
        if self.state.over or "experimenter" in self.state.pause_reasons:
            return
        self.record("paused", {"reason": "experimenter"})

    def resume(self) -> None:
        if "experimenter" in self.state.pause_reasons:
            self.record("resumed", {"reason": "experimenter"})

    def abort(self) -> None:
        if not self.state.over:
            self.record_phase("aborted")

    def snapshot(self) -> dict[str, Any]:
        s = self.state
        return {"trial_id": self.trial_id, "phase": s.phase, "target_index": s.target_index,
                "target": s.current_target, "elapsed_s": round(s.active_s(self.services.clock.now_ns()), 1),
                "moves": s.moves, "collisions": s.collisions, "pose": s.pose,
                "paused": sorted(s.pause_reasons), "seats": {r: r in self.seats for r in s.seats_needed},
                "waiting_for": s.waiting_for, "backend": s.backend, "localization": s.localization,
                "maze": s.maze, "belief": self.watch_messages.get("belief")}


def _describe(err: ValidationError) -> str:
    parts = []
    for e in err.errors()[:3]:
        where = ".".join(str(p) for p in e["loc"]) or "message"
        parts.append(f"{where}: {e['msg']}")
    return "; ".join(parts)
