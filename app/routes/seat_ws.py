"""`/ws/play`: the Commander's and the Driver's socket.

The token is checked at the upgrade and again on every message; a bad message gets an
error reply and a `bad_message` event, and never ends the trial. Moves run beside the
reader, so a move sent while one is executing is refused rather than queued.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from urllib.parse import urlsplit

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from pydantic import ValidationError

from app.security import InvalidToken
from app.settings import Settings
from app.trial import messages as m
from app.trial.runtime import TrialError, TrialRuntime, UnknownTrial

router = APIRouter()
logger = logging.getLogger(__name__)
OUTBOX_LIMIT = 512  # messages waiting for a slow browser before it is dropped


def origin_allowed(ws: WebSocket, settings: Settings) -> bool:
    """Browsers always send Origin: it must be the page's own host or an allowed origin.
    Clients that are not browsers (scripts, the rover) send none and are judged by token alone."""
    origin = ws.headers.get("origin")
    if origin is None:
        return True
    if origin in settings.allowed_origins:
        return True
    return urlsplit(origin).netloc == ws.headers.get("host")


class SocketSeat:
    """A seat's websocket: messages go out through a queue so a slow browser never blocks a trial."""

    def __init__(self, ws: WebSocket, role: str) -> None:
        self.ws, self.role = ws, role
        self.outbox: asyncio.Queue = asyncio.Queue(OUTBOX_LIMIT)
        self.writer = asyncio.get_running_loop().create_task(self._write())

    def deliver(self, message: dict) -> None:
        try:
            self.outbox.put_nowait(message)
        except asyncio.QueueFull:
            logger.warning("%s socket too slow; closing it", self.role)
            self.writer.cancel()
            asyncio.get_running_loop().create_task(self.ws.close(code=1013))

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
    if not origin_allowed(ws, services.settings):
        await ws.close(code=1008, reason="origin not allowed")
        return
    try:
        seat = services.seats.verify(token)
        runtime = await services.hub.get(seat.trial_id)
    except (InvalidToken, UnknownTrial) as err:
        await ws.close(code=1008, reason=str(err)[:120])
        return
    await ws.accept()
    conn = SocketSeat(ws, seat.role)
    runtime.join(conn)
    moves: set[asyncio.Task] = set()
    try:
        while True:
            raw = await ws.receive()
            if raw["type"] == "websocket.disconnect":
                break
            text = raw.get("text")
            await receive(runtime, conn, seat, text, moves)
    except WebSocketDisconnect:
        pass
    finally:
        runtime.leave(conn)
        await conn.close()


async def receive(runtime: TrialRuntime, conn: SocketSeat, seat, text: str | None, moves: set) -> None:
    limit = runtime.settings.max_message_bytes
    try:
        if text is None:
            raise TrialError("messages must be JSON text, not binary")
        if len(text.encode()) > limit:
            raise TrialError(f"message is {len(text.encode())} bytes; the limit is {limit}")
        try:
            message = m.seat_message.validate_json(text)
        except ValidationError as err:
            raise TrialError(f"invalid message: {_describe(err)}") from None
        try:
            if runtime.services.seats.verify(message.token) != seat:
                raise InvalidToken("token is for another seat")
        except InvalidToken as err:
            raise TrialError(f"token refused: {err}") from None
        if isinstance(message, m.Move):
            if message.type not in m.ALLOWED[seat.role]:
                raise TrialError(f"the {seat.role} may not send 'move' messages")
            task = asyncio.get_running_loop().create_task(runtime.handle(seat.role, message))
            moves.add(task)
            task.add_done_callback(moves.discard)
            return
        await runtime.handle(seat.role, message)
    except TrialError as err:
        conn.deliver({"type": "error", "error": str(err)})
        if not runtime.state.over:
            runtime.record("bad_message", {"role": seat.role, "error": str(err)[:500]})


def _describe(err: ValidationError) -> str:
    parts = []
    for e in err.errors()[:3]:
        where = ".".join(str(p) for p in e["loc"]) or "message"
        parts.append(f"{where}: {e['msg']}")
    return "; ".join(parts)
