"""`/ws/robot`: the rovers' and overhead cameras' socket (docs/protocol.md), and the
experimenter's robot API: register a robot (its token is shown once) and see each robot's link.

The first message must be a `hello` with the robot's token; a wrong token or role is answered
with an error and the close code 4401, so the client stops retrying. Afterwards the server
pings every 0.1 s (the rover's watchdog hears these), frames are checked to be the JPEG their
header says (`check_jpeg`) and mapped onto the server clock, and a malformed or oversized
message gets an error reply, is logged as `bad_message` in the trials using the robot, and
changes nothing else.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Mapping
from typing import Any

from fastapi import APIRouter, Depends, Form, HTTPException, WebSocket, WebSocketDisconnect
from sqlalchemy.orm import Session, sessionmaker

from app.deps import ClockDep, DbFactory, DbSession, RobotLinksDep, SettingsDep, experimenter_id
from app.guard import csrf_protect, socket_origin_allowed
from app.rover.links import MAX_FRAME_BYTES, PING_INTERVAL_S, RobotLink, RobotLinks
from app.rover.records import RobotSetupError, create_robot, robot_for_token
from app.serving import MESSAGE_TOO_BIG
from robot_client.protocol import (
    CLOSE_REFUSED,
    CLOSE_REPLACED,
    PROTOCOL_VERSION,
    ROBOT_TYPES,
    ROLES,
    ProtocolError,
    decode,
    encode,
    unpack_frame,
)
from sim.robot.frames import FrameError, check_jpeg
from sim.trial.specs import BackendSpec

router = APIRouter()
logger = logging.getLogger(__name__)
HELLO_TIMEOUT_S = 5.0
DEAD_LINK_S = 2.0  # nothing from the robot for this long (it answers 10 pings a second): drop it
OUTBOX_LIMIT = 256


class Refused(Exception):
    def __init__(self, code: str, error: str) -> None:
        super().__init__(error)
        self.code = code


@router.websocket("/ws/robot")
async def robot_socket(
    ws: WebSocket, links: RobotLinksDep, settings: SettingsDep, clock: ClockDep, db: DbFactory
) -> None:
    if not socket_origin_allowed(ws.headers, ws.url.scheme, settings):  # a page on another site
        await ws.close(code=1008, reason="origin not allowed")
        return
    await ws.accept()
    try:
        robot_id, name, role = await _hello(ws, db)
    except Refused as refused:
        with contextlib.suppress(RuntimeError, WebSocketDisconnect):
            await ws.send_text(encode({"type": "error", "code": refused.code, "error": str(refused)}))
        await ws.close(code=CLOSE_REFUSED, reason=str(refused)[:120])
        return
    except (WebSocketDisconnect, TimeoutError):
        return

    outbox: asyncio.Queue[str] = asyncio.Queue(OUTBOX_LIMIT)
    link = RobotLink(robot_id, name, role, lambda m: _queue(outbox, m), clock)
    links.attach(link)
    _queue(
        outbox,
        {
            "type": "welcome",
            "protocol": PROTOCOL_VERSION,
            "robot": {"id": robot_id, "name": name, "role": role},
            "ping_interval_s": PING_INTERVAL_S,
            "max_frame_bytes": MAX_FRAME_BYTES,
            "server_ns": clock.now_ns(),
        },
    )
    logger.info("robot %r (%s) connected", name, role)
    tasks = [
        asyncio.create_task(_write(ws, outbox, link)),
        asyncio.create_task(_ping(link)),
        asyncio.create_task(_read(ws, link, links)),
    ]
    try:
        await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        links.detach(link)
        logger.info("robot %r (%s) disconnected", name, role)
        with contextlib.suppress(RuntimeError, WebSocketDisconnect):
            if link.replaced:
                await ws.close(code=CLOSE_REPLACED, reason="the same robot connected again")
            else:
                await ws.close()


async def _hello(ws: WebSocket, sessions: sessionmaker[Session]) -> tuple[int, str, str]:
    raw = await asyncio.wait_for(ws.receive(), HELLO_TIMEOUT_S)
    if raw["type"] == "websocket.disconnect":
        raise WebSocketDisconnect(raw.get("code", 1000))
    try:
        hello = decode(raw.get("text") or "", ("hello",))
    except ProtocolError as err:
        raise Refused("bad_message", f"the first message must be a hello: {err}") from None
    if hello.get("protocol") != PROTOCOL_VERSION:
        raise Refused(
            "protocol",
            f"protocol {hello.get('protocol')!r} is not supported; this server speaks "
            f"{PROTOCOL_VERSION} (update robotslang-robot)",
        )
    token, role = hello.get("token"), hello.get("role")
    if role not in ROLES:
        raise Refused("role", f"role {role!r}: expected one of {', '.join(ROLES)}")
    with sessions() as db:
        robot = robot_for_token(db, token) if isinstance(token, str) else None
    if robot is None:
        raise Refused("auth", "unknown robot token (copy it from the experimenter page)")
    if robot.role != role:
        raise Refused("role", f"robot {robot.name!r} is registered as {robot.role}, but connected with --role {role}")
    return robot.id, robot.name, robot.role


def _queue(outbox: asyncio.Queue[str], message: dict[str, Any]) -> None:
    with contextlib.suppress(asyncio.QueueFull):  # a robot that stops reading is dropped by DEAD_LINK_S
        outbox.put_nowait(encode(message))


async def _write(ws: WebSocket, outbox: asyncio.Queue[str], link: RobotLink) -> None:
    with contextlib.suppress(RuntimeError, WebSocketDisconnect):
        while not link.closed:
            text = await outbox.get()
            await ws.send_text(text)


async def _ping(link: RobotLink) -> None:
    while not link.closed:
        if time.monotonic_ns() - link.last_heard_ns > DEAD_LINK_S * 1e9:
            logger.warning("robot %r: nothing heard for %.1f s; dropping the link", link.name, DEAD_LINK_S)
            return
        link.ping()
        await asyncio.sleep(PING_INTERVAL_S)


async def _read(ws: WebSocket, link: RobotLink, links: RobotLinks) -> None:
    with contextlib.suppress(WebSocketDisconnect):
        while not link.closed:
            raw = await ws.receive()
            if raw["type"] == "websocket.disconnect":
                if raw.get("code") == MESSAGE_TOO_BIG:  # answered by the server (app.serving); now logged
                    links.bad_message(link, raw.get("reason") or "message too big")
                return
            received_ns = link.last_heard_ns = time.monotonic_ns()
            try:
                await _dispatch(raw, link, links, received_ns)
            except ProtocolError as err:
                link.send_error(str(err))
                links.bad_message(link, str(err))


async def _dispatch(raw: Mapping[str, Any], link: RobotLink, links: RobotLinks, received_ns: int) -> None:
    data = raw.get("bytes")
    if data is not None:
        header, jpeg = unpack_frame(data, MAX_FRAME_BYTES)
        try:
            await asyncio.to_thread(check_jpeg, jpeg, header.width, header.height)  # a decode: off the loop
        except FrameError as err:
            raise ProtocolError(str(err)) from None
        await links.frame(link, link.on_frame(header, jpeg, received_ns))
        return
    message = decode(raw.get("text") or "", ROBOT_TYPES)
    match message["type"]:
        case "pong":
            link.on_pong(message, received_ns)
        case "ack":
            link.on_ack(message, received_ns)
        case "error":
            logger.warning("robot %r reports: %s", link.name, message.get("error"))
        case "hello":
            raise ProtocolError("hello was already received on this connection")


# -- the experimenter's robot API ------------------------------------------------------
@router.get("/experimenter/api/robots", dependencies=[Depends(experimenter_id)])
def robots_status(links: RobotLinksDep) -> dict[str, Any]:
    """Each registered robot: connected, frames per second, link latency, last acknowledgement."""
    return {"robots": links.status()}


@router.post("/experimenter/api/robots", dependencies=[Depends(experimenter_id), Depends(csrf_protect)])
def register_robot(db: DbSession, name: str = Form(max_length=80), role: str = Form("driver")) -> dict[str, Any]:
    """Register a robot. The answer holds its token: shown this once, stored only hashed."""
    try:
        with db.begin():
            robot, token = create_robot(db, name, role)
            return {
                "id": robot.id,
                "name": robot.name,
                "role": robot.role,
                "token": token,
                "backend": str(BackendSpec.robot(robot.id)),
            }
    except RobotSetupError as err:
        raise HTTPException(400, str(err)) from None
