"""`/ws/play`: the Commander's and the Driver's socket; `/ws/watch/{trial_id}`: the experimenter's.

The token is checked at the upgrade and again on every message (`TrialRuntime.receive`); the
watch socket needs the experimenter's login cookie and only listens. The trial may run in this
process or, with Redis, in another (`app.trial.relay`).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from app.db.models import Trial
from app.guard import socket_origin_allowed
from app.routes.pages import over_reason
from app.security import SESSION_COOKIE, InvalidToken
from app.serving import MESSAGE_TOO_BIG
from app.trial.runtime import UnknownTrial
from app.trial.views import EXPERIMENTER
from app.trial.vocabulary import Role

router = APIRouter()
logger = logging.getLogger(__name__)
OUTBOX_LIMIT = 512  # messages waiting for a slow browser before it is dropped


class SocketSeat:
    """A seat's websocket: messages go out through a queue so a slow browser never blocks a trial."""

    def __init__(self, ws: WebSocket, role: str) -> None:
        self.ws, self.role = ws, role
        self.outbox: asyncio.Queue = asyncio.Queue(OUTBOX_LIMIT)
        self.writer = asyncio.get_running_loop().create_task(self._write())
        self.dropped = False

    def deliver(self, message: dict) -> None:
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

    async def _write(self) -> None:
        with contextlib.suppress(WebSocketDisconnect, RuntimeError, asyncio.CancelledError):
            while True:
                message = await self.outbox.get()
                await self.ws.send_text(json.dumps(message, separators=(",", ":")))
                if message.get("type") == "replaced":
                    await self.ws.close(code=4409, reason="seat opened elsewhere")
                    return

    async def close(self) -> None:
        self.writer.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self.writer


@router.websocket("/ws/play")
async def play(ws: WebSocket, token: str = "") -> None:
    services = ws.app.state.services
    if not socket_origin_allowed(ws.headers, ws.url.scheme, services.settings):
        await ws.close(code=1008, reason="origin not allowed")
        return
    try:
        seat = services.seats.admit(token)
        with services.db() as db:
            trial = db.get(Trial, seat.trial_id)
        if trial is None:
            raise UnknownTrial(f"trial {seat.trial_id} does not exist")
        if (reason := over_reason(trial)) is not None:
            raise InvalidToken(reason)
    except (InvalidToken, UnknownTrial) as err:
        await ws.close(code=1008, reason=str(err)[:120])
        return
    # Answered before the trial opens (its log read, its maze loaded): a crowd arriving at once
    # is connected at once, and each seat's welcome follows as its trial opens.
    await ws.accept()
    try:
        runtime = await services.hub.get(seat.trial_id)
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
            await runtime.receive(conn, seat, raw.get("text"))
    except WebSocketDisconnect:
        pass
    finally:
        runtime.leave(conn)
        await conn.close()


@router.websocket("/ws/watch/{trial_id}")
async def watch(ws: WebSocket, trial_id: int) -> None:
    """The experimenter's live view of a trial: a `welcome` (with `status`, the last Driver frame
    and the pose), then every event but the overhead camera, frames with their JPEG, and `status`."""
    services = ws.app.state.services
    if not socket_origin_allowed(ws.headers, ws.url.scheme, services.settings):
        await ws.close(code=1008, reason="origin not allowed")
        return
    if services.sessions.verify(ws.cookies.get(SESSION_COOKIE)) is None:
        await ws.close(code=1008, reason="log in as an experimenter first")
        return
    try:
        runtime = await services.hub.get(trial_id)
    except UnknownTrial as err:
        await ws.close(code=1008, reason=str(err)[:120])
        return
    await ws.accept()
    conn = SocketSeat(ws, EXPERIMENTER)
    runtime.watch(conn)
    try:
        while (await ws.receive())["type"] != "websocket.disconnect":
            pass  # the watch socket only listens
    except WebSocketDisconnect:
        pass
    finally:
        runtime.unwatch(conn)
        await conn.close()
