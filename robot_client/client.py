"""The rover's link to the server: one websocket, reconnected with backoff, and the safety rules.

Safety, in one place:
- motors are stopped whenever a connection starts or ends, so the rover always starts stopped;
- the watchdog stops them when nothing was heard from the server for `watchdog_s`;
- a move is one bounded pulse (calibration.max_move_s); a move arriving while one runs is
  refused as `busy`, never queued;
- the CLI stops them on SIGINT/SIGTERM before anything else.
"""

from __future__ import annotations

import asyncio
import logging
import random
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from urllib.parse import urlsplit, urlunsplit

from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed, InvalidHandshake

from robot_client import __version__
from robot_client.camera import CameraError, FrameGrabber
from robot_client.motors import MotorDriver
from robot_client.protocol import (
    CLOSE_REFUSED,
    CLOSE_REPLACED,
    DEFAULT_MAX_FRAME_BYTES,
    PROTOCOL_VERSION,
    SERVER_TYPES,
    Move,
    ProtocolError,
    decode,
    encode,
    pack_frame,
)

log = logging.getLogger("robotslang.robot")


class Pulse:
    """One move's pulse: started, held for its calibrated time, ended exactly once.

    `end` may come from the timer thread (the time is up) or the loop (stopped, link lost),
    whichever is first; the other finds the pulse over and leaves the motors, which may by
    then run the next move, alone.
    """

    def __init__(self, motors: MotorDriver, duration_s: float) -> None:
        self._motors = motors
        self._duration_s = duration_s
        self._lock = threading.Lock()
        self._over = threading.Event()
        self.started_ns = 0
        self.finished_ns = 0

    def start(self, action: str) -> None:
        self.started_ns = time.monotonic_ns()
        self._motors.start(action)

    def hold(self) -> None:
        if not self._over.wait(self._duration_s):
            self.end()

    def end(self) -> None:
        with self._lock:
            if self._over.is_set():
                return
            self._motors.stop()
            self.finished_ns = time.monotonic_ns()
            self._over.set()


class LinkRefused(RuntimeError):
    """The server will not take this robot (wrong token, wrong role, replaced): retrying is useless."""


@dataclass(frozen=True)
class LinkSettings:
    server: str
    token: str
    role: str = "driver"
    watchdog_s: float = 0.5
    backoff_initial_s: float = 0.25
    backoff_max_s: float = 8.0
    hello_timeout_s: float = 5.0

    @property
    def url(self) -> str:
        return robot_url(self.server)

    @property
    def dead_link_s(self) -> float:
        # After this much silence the connection is given up and reopened; the motors were
        # already stopped by the watchdog long before.
        return max(2.0, 5 * self.watchdog_s)


def robot_url(server: str) -> str:
    """`http://host:8000` or `ws://host:8000` -> `ws://host:8000/ws/robot`."""
    parts = urlsplit(server)
    scheme = {"http": "ws", "https": "wss", "ws": "ws", "wss": "wss"}.get(parts.scheme)
    if scheme is None or not parts.netloc:
        raise ValueError(f"--server must be a URL like http://HOST:PORT, got {server!r}")
    path = parts.path if parts.path not in ("", "/") else "/ws/robot"
    return urlunsplit((scheme, parts.netloc, path, "", ""))


class RobotClient:
    """Keeps one websocket to the server open and serves it: frames out, moves in."""

    def __init__(
        self,
        settings: LinkSettings,
        grabber: FrameGrabber | None,
        motors: MotorDriver | None,
        camera_info: dict | None = None,
    ) -> None:
        self.settings = settings
        self.grabber = grabber
        self.motors = motors
        self.camera_info = camera_info or {}
        self._frame_ready = asyncio.Event()
        self._move: asyncio.Task | None = None
        self._pulse_timer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="pulse")
        self._last_heard = time.monotonic()
        self._max_frame_bytes = DEFAULT_MAX_FRAME_BYTES

    def frame_captured(self) -> None:
        """Called from the grabber thread: wake the sender."""
        self._loop.call_soon_threadsafe(self._frame_ready.set)

    def stop_motors(self, why: str) -> None:
        if self.motors is not None and self.motors.running:
            log.warning("motors stopped: %s", why)
        if self.motors is not None:
            self.motors.stop()
        if self._move is not None and not self._move.done():
            self._move.cancel()

    async def run(self) -> None:
        """Connect, serve, and reconnect with exponential backoff until cancelled or refused."""
        self._loop = asyncio.get_running_loop()
        if self.grabber is not None:
            self.grabber.start(on_frame=self.frame_captured)
        s = self.settings
        backoff = s.backoff_initial_s
        while True:
            self.stop_motors("connecting")
            try:
                async with connect(
                    s.url,
                    compression=None,
                    proxy=None,
                    ping_interval=None,
                    open_timeout=s.hello_timeout_s,
                    close_timeout=1,
                    max_size=1 << 20,
                ) as ws:
                    await self._hello(ws)
                    backoff = s.backoff_initial_s
                    await self._serve(ws)
            except LinkRefused:
                raise
            except (OSError, asyncio.TimeoutError, ConnectionClosed, InvalidHandshake, ProtocolError) as exc:
                log.warning("no link to %s: %s", s.url, exc or type(exc).__name__)
            finally:
                self.stop_motors("link closed")
            delay = backoff * random.uniform(0.8, 1.2)
            log.info("reconnecting in %.2f s", delay)
            await asyncio.sleep(delay)
            backoff = min(backoff * 2, s.backoff_max_s)

    async def _hello(self, ws: ClientConnection) -> None:
        s = self.settings
        await ws.send(
            encode(
                {
                    "type": "hello",
                    "protocol": PROTOCOL_VERSION,
                    "token": s.token,
                    "role": s.role,
                    "client": f"robotslang-robot {__version__}",
                    "camera": self.camera_info,
                    "watchdog_s": s.watchdog_s,
                    "robot_ns": time.monotonic_ns(),
                }
            )
        )
        try:
            reply = decode(await asyncio.wait_for(ws.recv(), s.hello_timeout_s), SERVER_TYPES)
        except ConnectionClosed as exc:
            if exc.rcvd is not None and exc.rcvd.code in (CLOSE_REFUSED, CLOSE_REPLACED):
                raise LinkRefused(exc.rcvd.reason or "refused by the server") from None
            raise
        if reply["type"] == "error":
            raise LinkRefused(f"{reply.get('code')}: {reply.get('error')}")
        if reply["type"] != "welcome":
            raise ProtocolError(f"expected a welcome from the server, got {reply['type']!r}")
        self._max_frame_bytes = int(reply.get("max_frame_bytes", DEFAULT_MAX_FRAME_BYTES))
        robot = reply.get("robot", {})
        log.info("connected to %s as robot %r (%s)", s.url, robot.get("name"), robot.get("role"))

    async def _serve(self, ws: ClientConnection) -> None:
        self._last_heard = time.monotonic()
        tasks = [
            asyncio.create_task(self._receive(ws), name="receive"),
            asyncio.create_task(self._watchdog(ws), name="watchdog"),
        ]
        if self.grabber is not None:
            tasks.append(asyncio.create_task(self._send_frames(ws, self.grabber), name="frames"))
        try:
            done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
            for task in done:
                task.result()  # re-raise what ended the session
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)

    async def _receive(self, ws: ClientConnection) -> None:
        try:
            async for raw in ws:
                self._last_heard = time.monotonic()
                if isinstance(raw, bytes):
                    await self._error(ws, "the server sends no binary messages")
                    continue
                try:
                    message = decode(raw, SERVER_TYPES)
                    await self._handle(ws, message)
                except ProtocolError as exc:
                    await self._error(ws, str(exc))
        except ConnectionClosed as exc:
            if exc.rcvd is not None and exc.rcvd.code in (CLOSE_REFUSED, CLOSE_REPLACED):
                raise LinkRefused(exc.rcvd.reason or "closed by the server") from None
            raise
        raise ConnectionError("the server closed the connection")

    async def _handle(self, ws: ClientConnection, message: dict) -> None:
        kind = message["type"]
        if kind == "ping":
            await ws.send(
                encode(
                    {
                        "type": "pong",
                        "id": message.get("id"),
                        "server_ns": message.get("server_ns"),
                        "robot_ns": time.monotonic_ns(),
                    }
                )
            )
        elif kind == "move":
            self._start_move(ws, message)
        elif kind == "stop":
            self.stop_motors("stop requested by the server")
        elif kind == "error":
            log.warning("server reports: %s", message.get("error"))
        else:  # a second welcome
            raise ProtocolError(f"unexpected {kind!r} message after the welcome")

    def _start_move(self, ws: ClientConnection, message: dict) -> None:
        move_id = message.get("id")
        if not isinstance(move_id, (str, int)) or isinstance(move_id, bool):
            raise ProtocolError(f"move message needs an 'id' (string or integer), got {move_id!r}")
        action = message.get("action")
        if self._move is not None and not self._move.done():
            self._send_later(ws, ack(move_id, action, "refused", "busy"))
        elif self.motors is None or action not in tuple(Move):
            self._send_later(ws, ack(move_id, action, "refused", "unknown"))
        else:
            self._move = asyncio.create_task(self._run_move(ws, self.motors, move_id, action))

    async def _run_move(self, ws: ClientConnection, motors: MotorDriver, move_id, action: str) -> None:
        pulse = Pulse(motors, motors.calibration.duration(action))
        pulse.start(action)
        try:
            # The pulse is timed on a thread of its own: when it is due to end, the loop may be
            # busy packing a frame, and every millisecond late is distance the rover drives on.
            await asyncio.get_running_loop().run_in_executor(self._pulse_timer, pulse.hold)
            status, reason = "done", None
        except asyncio.CancelledError:
            status, reason = "refused", "stopped"
        finally:
            pulse.end()
        self._send_later(
            ws, ack(move_id, action, status, reason, started_ns=pulse.started_ns, finished_ns=pulse.finished_ns)
        )

    def _send_later(self, ws: ClientConnection, message: dict) -> None:
        # Acks must not wait behind a frame being written; a failed send means the link is
        # gone, which the receive task reports.
        task = asyncio.create_task(ws.send(encode(message)))
        task.add_done_callback(lambda t: t.cancelled() or t.exception())

    async def _error(self, ws: ClientConnection, text: str) -> None:
        log.warning("bad message from the server: %s", text)
        await ws.send(encode({"type": "error", "code": "bad_message", "error": text}))

    async def _watchdog(self, ws: ClientConnection) -> None:
        s = self.settings
        tripped = False
        while True:
            silence = time.monotonic() - self._last_heard
            if silence >= s.watchdog_s and not tripped:
                tripped = True
                self.stop_motors(f"watchdog: nothing from the server for {silence:.2f} s")
            elif silence < s.watchdog_s:
                tripped = False
            if silence >= s.dead_link_s:
                raise ConnectionError(f"nothing from the server for {silence:.1f} s")
            # Wake exactly when the silence would reach the limit, or soon after a trip.
            await asyncio.sleep(max(0.0, s.watchdog_s - silence) if not tripped else 0.05)

    async def _send_frames(self, ws: ClientConnection, grabber: FrameGrabber) -> None:
        sent = 0
        while True:
            await self._frame_ready.wait()
            self._frame_ready.clear()
            if grabber.error is not None:
                raise CameraError(f"camera failed: {grabber.error}")
            frame = grabber.latest()
            if frame is None or frame.seq == sent:
                continue
            data = pack_frame(frame.seq, frame.capture_ns, frame.width, frame.height, frame.jpeg)
            if len(data) > self._max_frame_bytes:
                log.warning(
                    "frame %d is %d bytes, over the server's limit of %d: skipped (lower --quality or the size)",
                    frame.seq,
                    len(data),
                    self._max_frame_bytes,
                )
                continue
            # Waits while the link drains; newer frames overwrite the grabber's slot meanwhile.
            await ws.send(data)
            sent = frame.seq


def ack(move_id, action, status: str, reason: str | None = None, **times) -> dict:
    message = {"type": "ack", "id": move_id, "action": action, "status": status}
    if reason is not None:
        message["reason"] = reason
    message.update(times)
    return message
