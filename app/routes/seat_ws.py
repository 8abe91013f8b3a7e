"""`/ws/play`: the Commander's and the Driver's socket; `/ws/watch/{trial_id}`: the experimenter's.

The token is checked at the upgrade and again on every message (`read_message`, which hands the
runtime typed messages only); the
watch socket needs the experimenter's login cookie, only listens, and is closed (4401) when
that login ends: at once at a logout here, within `LOGIN_RECHECK_S` of one elsewhere or of a
password change. The trial may run in this process or, with Redis, in another
(`app.trial.relay`).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from pydantic import ValidationError
from sqlalchemy import select

from app.cookies import read_cookie
from app.db.models import Trial
from app.deps import DbFactory, HubDep, LoginSocketsDep, SeatTokensDep, SessionsDep, SettingsDep
from app.guard import socket_origin_allowed
from app.security import SESSION_COOKIE, InvalidToken, Seat, SeatTokens, Sessions
from app.serving import MESSAGE_TOO_BIG
from app.trial import messages as m
from app.trial.messages import Message, ServerMessage
from app.trial.runtime import UnknownTrial
from app.trial.views import EXPERIMENTER
from app.web import over_reason
from sim.trial.decide import Refused
from sim.trial.vocabulary import Role

router = APIRouter()
logger = logging.getLogger(__name__)
OUTBOX_LIMIT = 512  # messages waiting for a slow browser before it is dropped
LOGIN_RECHECK_S = 1.0  # how often a watch socket checks that its login still stands
LOGGED_OUT = 4401  # the close code of a watch socket whose login ended
TRIAL_OVER = 4410  # the close code of a seat's socket whose trial has ended (the reason says how)
CLOSE_WAIT_S = 5.0  # how long a logged-out watch waits for the browser to answer its close


class SocketSeat:
    """A seat's websocket: messages go out through a queue so a slow browser never blocks a trial."""

    def __init__(self, ws: WebSocket, role: str) -> None:
        self.ws, self.role = ws, role
        self.outbox: asyncio.Queue[Message] = asyncio.Queue(OUTBOX_LIMIT)
        self.loop = asyncio.get_running_loop()
        self.writer = self.loop.create_task(self._write())
        self.dropped = False

    def deliver(self, message: Message) -> None:
        if self.dropped:
            return
        try:
            self.outbox.put_nowait(message)
        except asyncio.QueueFull:  # the browser reconnects and gets a fresh welcome
            logger.warning("%s socket too slow; closing it", self.role)
            self.dropped = True
            self.writer.cancel()
            asyncio.get_running_loop().create_task(self._close_slow())

    async def _close_slow(self) -> None:
        with contextlib.suppress(RuntimeError, WebSocketDisconnect):
            await self.ws.close(code=1013, reason="too slow")

    def log_out(self) -> None:
        """The experimenter's login ended: nothing more goes out (from the moment this returns),
        and the socket closes with `LOGGED_OUT`."""
        self.dropped = True
        self.loop.call_soon_threadsafe(self.writer.cancel)
        asyncio.run_coroutine_threadsafe(self._close_logged_out(), self.loop)

    async def _close_logged_out(self) -> None:
        with contextlib.suppress(RuntimeError, WebSocketDisconnect):
            await self.ws.close(code=LOGGED_OUT, reason="logged out: log in again to watch")

    async def _write(self) -> None:
        with contextlib.suppress(WebSocketDisconnect, RuntimeError, asyncio.CancelledError):
            while True:
                message = await self.outbox.get()
                await self.ws.send_text(json.dumps(message, separators=(",", ":")))
                if message.get("type") == ServerMessage.REPLACED:
                    await self.ws.close(code=4409, reason="seat opened elsewhere")
                    return

    async def close(self) -> None:
        self.writer.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self.writer


@router.websocket("/ws/play")
async def play(
    ws: WebSocket, settings: SettingsDep, seats: SeatTokensDep, db: DbFactory, hub: HubDep, token: str = ""
) -> None:
    if not socket_origin_allowed(ws.headers, ws.url.scheme, settings):
        await ws.close(code=1008, reason="origin not allowed")
        return
    try:
        seat = seats.admit(token)
        with db() as session:  # the phase alone: a crowd's handshakes wait on this loop for each other
            phase = session.scalar(select(Trial.phase).where(Trial.id == seat.trial_id))
        if phase is None:
            raise UnknownTrial(f"trial {seat.trial_id} does not exist")
    except (InvalidToken, UnknownTrial) as err:
        await ws.close(code=1008, reason=str(err)[:120])
        return
    if (reason := over_reason(phase)) is not None:
        # Accepted to be closed: a close before the upgrade is a bare 403 the browser cannot read, and
        # a seat page whose trial ended while it connected would reconnect forever. With this code
        # and the reason it loads its link again, which now shows the trial over and the way on.
        await ws.accept()
        await ws.close(code=TRIAL_OVER, reason=reason[:120])
        return
    # Answered before the trial opens (its log read, its maze loaded): a crowd arriving at once
    # is connected at once, and each seat's welcome follows as its trial opens.
    await ws.accept()
    try:
        runtime = await hub.get(seat.trial_id)
    except UnknownTrial as err:
        await ws.close(code=1008, reason=str(err)[:120])
        return
    except Exception as err:  # e.g. its maze left the library: say so instead of dropping the socket
        logger.exception("trial could not be opened")
        await ws.close(code=1011, reason=f"the trial could not be opened: {err}"[:120])
        return
    conn = SocketSeat(ws, seat.role)
    runtime.join(conn)
    try:
        while True:
            raw = await ws.receive()
            if raw["type"] == "websocket.disconnect":
                if raw.get("code") == MESSAGE_TOO_BIG:  # answered by the server (app.serving); now logged
                    runtime.report_bad_message(Role(seat.role), raw.get("reason") or "message too big")
                break
            try:
                message = read_message(raw.get("text"), seat, seats, settings.max_message_bytes)
            except Refused as err:
                runtime.refuse_unread(conn, seat.role, str(err))
                continue
            await runtime.receive(conn, seat.role, message)
    except WebSocketDisconnect:
        pass
    finally:
        runtime.leave(conn)
        await conn.close()


@router.websocket("/ws/watch/{trial_id}")
async def watch(
    ws: WebSocket,
    trial_id: int,
    settings: SettingsDep,
    sessions: SessionsDep,
    hub: HubDep,
    login_sockets: LoginSocketsDep,
) -> None:
    """The experimenter's live view of a trial: a `welcome` (with `status`, the last Driver frame
    and the pose), then every event but the overhead camera, frames with their JPEG, and `status`."""
    if not socket_origin_allowed(ws.headers, ws.url.scheme, settings):
        await ws.close(code=1008, reason="origin not allowed")
        return
    cookie = read_cookie(ws, SESSION_COOKIE)
    login = sessions.verify(cookie)
    if login is None:
        await ws.close(code=1008, reason="log in as an experimenter first")
        return
    try:
        runtime = await hub.get(trial_id)
    except UnknownTrial as err:
        await ws.close(code=1008, reason=str(err)[:120])
        return
    await ws.accept()
    conn = SocketSeat(ws, EXPERIMENTER)
    runtime.watch(conn)
    login_sockets.add(login, conn)
    listening = asyncio.create_task(_until_closed(ws))
    logged_in = asyncio.create_task(_while_logged_in(sessions, cookie))
    try:
        await asyncio.wait((listening, logged_in), return_when=asyncio.FIRST_COMPLETED)
        if logged_in.done():
            conn.log_out()
            await asyncio.wait((listening,), timeout=CLOSE_WAIT_S)  # the client answers the close
    finally:
        listening.cancel()
        logged_in.cancel()
        login_sockets.discard(login, conn)
        runtime.unwatch(conn)
        await conn.close()


def read_message(text: str | None, seat: Seat, seats: SeatTokens, limit: int) -> m.SeatMessage:
    """One socket message as the seat's typed message; `Refused` saying why it cannot be read:
    binary, over `limit` bytes, not a valid message, or not carrying this seat's token (each
    message carries it, so a token that is revoked or for another seat stops working at once)."""
    if text is None:
        raise Refused("messages must be JSON text, not binary")
    size = len(text.encode())
    if size > limit:
        raise Refused(f"message is {size} bytes; the limit is {limit}")
    try:
        message = m.seat_message.validate_json(text)
    except ValidationError as err:
        raise Refused(f"invalid message: {_describe(err)}") from None
    try:
        if seats.verify(message.token) != seat:
            raise InvalidToken("token is for another seat")
    except InvalidToken as err:
        raise Refused(f"token refused: {err}") from None
    return message


def _describe(err: ValidationError) -> str:
    parts = []
    for e in err.errors()[:3]:
        where = ".".join(str(p) for p in e["loc"]) or "message"
        parts.append(f"{where}: {e['msg']}")
    return "; ".join(parts)


async def _until_closed(ws: WebSocket) -> None:
    with contextlib.suppress(WebSocketDisconnect):
        while (await ws.receive())["type"] != "websocket.disconnect":
            pass  # the watch socket only listens


async def _while_logged_in(sessions: Sessions, cookie: str | None) -> None:
    """Returns once the login the socket opened with has ended in the database: a logout in
    another process, or a password change (both bump the account's session version)."""
    while await asyncio.to_thread(sessions.verify, cookie) is not None:
        await asyncio.sleep(LOGIN_RECHECK_S)
