"""`RobotLink` is one connected robot as the server sees it: clock offset from pings, frames
mapped onto the server clock, moves awaiting their acknowledgement, and the figures the
experimenter's dashboard shows. `RobotLinks` holds the links of this server by robot id and
tells the trials that use a robot when it comes and goes. Overhead cameras (`role: overhead`)
are recorded into every live trial on a real robot, never shown to a seat; each trial's tracker
(`app.rover.tracker_seat`) turns them into `pose` events."""

from __future__ import annotations

import asyncio
import time
from collections import deque
from collections.abc import Callable
from typing import Any, Protocol

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from app.backends.base import BackendUnavailable, Frame
from app.clock import ServerClock
from app.db.models import Robot
from robot_client.protocol import FrameHeader
from sim.trial.specs import BackendSpec
from sim.trial.vocabulary import Move, Role

PING_INTERVAL_S = 0.1  # well under the rover's 0.5 s watchdog, so a live link never trips it
MAX_FRAME_BYTES = 1024 * 1024  # a 1280x720 JPEG at quality 95 is about 300 KB
ACK_TIMEOUT_S = 12.0  # the longest pulse a calibration allows (10 s) plus slack
OFFSET_SAMPLES = 32
RATE_WINDOW_S = 2.0


class RobotLink:
    """The server's end of one robot's websocket. `send` queues a JSON message for the writer."""

    def __init__(
        self, robot_id: int, name: str, role: str, send: Callable[[dict[str, Any]], None], clock: ServerClock
    ) -> None:
        self.robot_id, self.name, self.role = robot_id, name, role
        self._send = send
        self._clock = clock
        self.connected_ns = clock.now_ns()
        self._offsets: deque[tuple[int, int]] = deque(maxlen=OFFSET_SAMPLES)  # (rtt, offset)
        self._ping_id = 0
        self._pings: dict[int, int] = {}
        self._pending: dict[str, asyncio.Future[dict[str, Any]]] = {}
        self._move_seq = 0
        self._arrivals: deque[int] = deque()
        self.last_capture_ns = 0  # the latest frame's stamp: the next one comes after it
        self.frames_received = 0
        self.last_ack: dict[str, Any] | None = None
        self.last_heard_ns = time.monotonic_ns()
        self.closed = False
        self.replaced = False  # closed because the same robot connected again

    # clock
    def ping(self) -> None:
        self._ping_id += 1
        sent = time.monotonic_ns()
        self._pings[self._ping_id] = sent
        if len(self._pings) > 4 * OFFSET_SAMPLES:  # pongs that never came
            self._pings.pop(min(self._pings))
        self._send({"type": "ping", "id": self._ping_id, "server_ns": sent})

    def on_pong(self, message: dict[str, Any], received_ns: int) -> None:
        sent = self._pings.pop(message.get("id", 0), None)  # ping ids start at 1
        robot_ns = message.get("robot_ns")
        if sent is None or not isinstance(robot_ns, int):
            return
        # NTP's estimate: the robot read its clock halfway through the round trip.
        self._offsets.append((received_ns - sent, robot_ns - (sent + received_ns) // 2))

    @property
    def offset_ns(self) -> int | None:
        """Robot monotonic clock minus server monotonic clock, from the fastest recent round trip."""
        return min(self._offsets)[1] if self._offsets else None

    @property
    def latency_ms(self) -> float | None:
        return min(self._offsets)[0] / 2e6 if self._offsets else None

    def server_time(self, robot_ns: int, received_ns: int) -> int:
        """A robot timestamp on the server clock, never later than the message's arrival
        (before the first pong, the arrival itself)."""
        offset = self.offset_ns
        mono = received_ns if offset is None else min(robot_ns - offset, received_ns)
        return int(self._clock.now_ns() - (time.monotonic_ns() - mono))

    def capture_time(self, robot_ns: int, received_ns: int) -> int:
        """A frame's capture time on the server clock, strictly after the previous frame's
        (of this link, and of the robot's links before it: `RobotLinks.last_capture_ns`)."""
        t_ns = max(self.server_time(robot_ns, received_ns), self.last_capture_ns + 1)
        self.last_capture_ns = t_ns
        return t_ns

    # frames
    def on_frame(self, header: FrameHeader, jpeg: bytes, received_ns: int) -> Frame:
        self.frames_received += 1
        self._arrivals.append(received_ns)
        while self._arrivals and received_ns - self._arrivals[0] > RATE_WINDOW_S * 1e9:
            self._arrivals.popleft()
        return Frame(jpeg, self.capture_time(header.capture_ns, received_ns), header.width, header.height)

    @property
    def fps(self) -> float:
        now = time.monotonic_ns()
        recent = [t for t in self._arrivals if now - t <= RATE_WINDOW_S * 1e9]
        return len(recent) / RATE_WINDOW_S

    # moves
    async def move(self, action: Move) -> dict[str, Any]:
        """Send one move and return the robot's acknowledgement (ack times on the server clock)."""
        if self.closed:
            raise BackendUnavailable(f"robot {self.name!r} is not connected")
        self._move_seq += 1
        move_id = f"{self.connected_ns:x}-{self._move_seq}"
        future = asyncio.get_running_loop().create_future()
        self._pending[move_id] = future
        self._send({"type": "move", "id": move_id, "action": str(action)})
        try:
            return await asyncio.wait_for(future, ACK_TIMEOUT_S)
        except TimeoutError:
            raise BackendUnavailable(
                f"robot {self.name!r} did not acknowledge the move within {ACK_TIMEOUT_S:.0f} s"
            ) from None
        finally:
            self._pending.pop(move_id, None)

    def on_ack(self, message: dict[str, Any], received_ns: int) -> None:
        ack = dict(message)
        for key in ("started_ns", "finished_ns"):
            if isinstance(ack.get(key), int):
                ack[key] = self.server_time(ack[key], received_ns)
        ack["received_ns"] = self._clock.now_ns()
        self.last_ack = ack
        future = self._pending.get(str(message.get("id")))
        if future is not None and not future.done():
            future.set_result(ack)

    def send_error(self, error: str) -> None:
        self._send({"type": "error", "code": "bad_message", "error": error})

    def stop(self) -> None:
        if not self.closed:
            self._send({"type": "stop"})

    def close(self) -> None:
        self.closed = True
        for future in self._pending.values():
            if not future.done():
                future.set_exception(BackendUnavailable(f"robot {self.name!r} lost its link during the move"))

    def status(self) -> dict[str, Any]:
        ack = self.last_ack
        if ack is not None:
            ack = {k: ack[k] for k in ("id", "action", "status", "reason", "received_ns") if k in ack}
            ack["age_s"] = round((self._clock.now_ns() - ack["received_ns"]) / 1e9, 1)
        return {
            "connected": not self.closed,
            "connected_ns": self.connected_ns,
            "fps": round(self.fps, 1),
            "latency_ms": None if self.latency_ms is None else round(self.latency_ms, 1),
            "frames": self.frames_received,
            "last_ack": ack,
        }


class FrameSlot:
    """The newest frame of one robot; waiters wake on each new one (older ones are dropped)."""

    def __init__(self) -> None:
        self.frame: Frame | None = None
        self._changed = asyncio.Condition()

    async def put(self, frame: Frame) -> None:
        async with self._changed:
            self.frame = frame
            self._changed.notify_all()

    async def newer_than(self, frame: Frame | None, stop: Callable[[], bool]) -> Frame | None:
        """The next frame after `frame`, or None once `stop()` is true (checked on `wake`)."""
        async with self._changed:
            await self._changed.wait_for(lambda: stop() or (self.frame is not None and self.frame is not frame))
            return None if stop() else self.frame

    async def captured_after(self, t_ns: int, timeout: float) -> Frame | None:
        try:
            async with self._changed:
                await asyncio.wait_for(
                    self._changed.wait_for(lambda: self.frame is not None and self.frame.capture_ns >= t_ns), timeout
                )
                return self.frame
        except TimeoutError:
            return None

    async def wake(self) -> None:
        async with self._changed:
            self._changed.notify_all()


# -- all robots of this server ------------------------------------------------------
class RobotTrialLink(Protocol):
    """A live trial on a robot (its backend), as the links tell it what its robot sends."""

    def link_up(self, link: RobotLink) -> None: ...

    def link_down(self, link: RobotLink) -> None: ...

    def record_overhead(self, frame: Frame) -> None: ...

    def record_bad_message(self, role: Role, error: str) -> None: ...


class RobotLinks:
    """Connected robots by id, the trials that use them, and the dashboard's view of both."""

    def __init__(self, db: sessionmaker[Session]) -> None:
        self.db = db  # the registered robots, for the dashboard
        self.links: dict[int, RobotLink] = {}
        self.slots: dict[int, FrameSlot] = {}
        self.backends: dict[int, set[RobotTrialLink]] = {}
        self._stamps: dict[int, int] = {}  # robot id -> last capture stamp of its links that are gone

    def slot(self, robot_id: int) -> FrameSlot:
        return self.slots.setdefault(robot_id, FrameSlot())

    def last_capture_ns(self, robot_id: int) -> int:
        """The robot's latest frame stamp over all its links: a new link's stamps come after it."""
        link, frame = self.links.get(robot_id), self.slot(robot_id).frame
        return max(
            link.last_capture_ns if link is not None else 0,
            frame.capture_ns if frame is not None else 0,
            self._stamps.get(robot_id, 0),
        )

    def attach(self, link: RobotLink) -> None:
        """Make `link` the robot's link; an older one is closed (its socket notices and ends)."""
        # Stamps of one robot never go back, even when its link is new (a frame buffered across
        # the reconnection, a different clock offset): frames are ordered and named by them.
        link.last_capture_ns = max(link.last_capture_ns, self.last_capture_ns(link.robot_id))
        previous = self.links.get(link.robot_id)
        if previous is not None:
            previous.replaced = True
            previous.close()
        self.links[link.robot_id] = link
        for backend in list(self.backends.get(link.robot_id, ())):
            backend.link_up(link)

    def detach(self, link: RobotLink) -> None:
        link.close()
        self._stamps[link.robot_id] = max(self._stamps.get(link.robot_id, 0), link.last_capture_ns)
        if self.links.get(link.robot_id) is not link:
            return  # already replaced by a newer connection
        del self.links[link.robot_id]
        for backend in list(self.backends.get(link.robot_id, ())):
            backend.link_down(link)

    def trials_of(self, link: RobotLink) -> list[RobotTrialLink]:
        """The backends (one per live trial) a link's data belongs to: a rover's own trials, or,
        for the overhead camera over the table, every trial on a real robot."""
        if link.role == Role.DRIVER:
            return list(self.backends.get(link.robot_id, ()))
        return [backend for backends in self.backends.values() for backend in backends]

    async def frame(self, link: RobotLink, frame: Frame) -> None:
        if link.role == Role.DRIVER:
            await self.slot(link.robot_id).put(frame)
            return
        for backend in self.trials_of(link):
            backend.record_overhead(frame)

    def bad_message(self, link: RobotLink, error: str) -> None:
        # In the log the rover is the `robot` seat; its `driver` role would read as the participant.
        role = Role.ROBOT if link.role == Role.DRIVER else Role(link.role)
        for backend in self.trials_of(link):
            backend.record_bad_message(role, error)

    def status(self) -> list[dict[str, Any]]:
        """Every registered robot with its link figures: what the experimenter's dashboard shows."""
        with self.db() as db:
            robots = db.scalars(select(Robot).order_by(Robot.name)).all()
        rows = []
        for robot in robots:
            link = self.links.get(robot.id)
            row = {"id": robot.id, "name": robot.name, "role": robot.role, "backend": str(BackendSpec.robot(robot.id))}
            row.update(
                link.status()
                if link is not None
                else {"connected": False, "fps": 0.0, "latency_ms": None, "frames": 0, "last_ack": None}
            )
            rows.append(row)
        return rows
