"""`/ws/play`: the Commander's and the Driver's socket.

The token is checked at the upgrade and again on every message (`TrialRuntime.receive`).
The trial may run in this process or, with Redis, in another (`app.trial.relay`).
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
from app.security import InvalidToken
from app.trial.runtime import UnknownTrial

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
        if trial is not None and (reason := over_reason(trial)) is not None:
            raise InvalidToken(reason)
        runtime = await services.hub.get(seat.trial_id)
    except (InvalidToken, UnknownTrial) as err:
        await ws.close(code=1008, reason=str(err)[:120])
        return
    except Exception as err:  # e.g. its maze left the library: say so instead of dropping the socket
        logger.exception("trial could not be opened")
        await ws.close(code=1011, reason=f"the trial could not be opened: {err}"[:120])
        return
    await ws.accept()
    conn = SocketSeat(ws, seat.role)
    runtime.join(conn)
    try:
        while True:
            raw = await ws.receive()
            if raw["type"] == "websocket.disconnect":
                break
            await runtime.receive(conn, seat, raw.get("text"))
    except WebSocketDisconnect:
        pass
    finally:
        runtime.leave(conn)
        await conn.close()
