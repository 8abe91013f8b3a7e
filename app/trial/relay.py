"""Several server processes, one trial: Redis pub/sub between them (`ROBOTSLANG_REDIS_URL`).

Each trial runs in exactly one process, its owner (a Redis key with a lease, claimed by the
first process a seat of the trial reaches and renewed while it runs the trial). A seat that
reaches another process gets a `RemoteTrial`: its messages go to the owner, and the owner's
`RelayedSeat` sends back what that seat may hear, filtered by the owner as for local seats.
Each process listens on one channel; messages on it keep their order.
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import json
import logging
import uuid
from typing import Any

from app.security import Seat
from app.trial.views import EXPERIMENTER
from app.trial.vocabulary import Role

logger = logging.getLogger(__name__)
OWNER_TTL_S = 30
RENEW_EVERY_S = 10


def _channel(process: str) -> str:
    return f"robotslang:process:{process}"


class RedisRelay:
    def __init__(self, services, url: str) -> None:
        import redis.asyncio as redis

        self.services = services
        self.redis = redis.from_url(url, decode_responses=True)
        self.id = uuid.uuid4().hex
        # Trial ids are per database: processes share owners only when they share the database.
        self._keys = f"robotslang:{hashlib.sha256(services.settings.url.encode()).hexdigest()[:12]}"
        self.local: dict[str, Any] = {}  # connection id -> this process's seat of a trial owned elsewhere
        self.relayed: dict[str, RelayedSeat] = {}  # connection id -> a remote seat of a trial owned here
        self._outbox: asyncio.Queue = asyncio.Queue()
        self._tasks: list[asyncio.Task] = []

    async def start(self) -> None:
        self._pubsub = self.redis.pubsub()
        await self._pubsub.subscribe(_channel(self.id))
        loop = asyncio.get_running_loop()
        self._tasks = [loop.create_task(self._listen()), loop.create_task(self._send()),
                       loop.create_task(self._renew())]

    async def close(self) -> None:
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        for runtime in self.services.hub.live():
            with contextlib.suppress(Exception):
                if await self.redis.get(self._owner_key(runtime.trial_id)) == self.id:
                    await self.redis.delete(self._owner_key(runtime.trial_id))
        await self._pubsub.aclose()
        await self.redis.aclose()

    def _owner_key(self, trial_id: int) -> str:
        return f"{self._keys}:trial:{trial_id}:owner"

    async def owner(self, trial_id: int) -> str:
        """The process running the trial; this one when no process does yet."""
        if await self.redis.set(self._owner_key(trial_id), self.id, nx=True, ex=OWNER_TTL_S):
            return self.id
        return await self.redis.get(self._owner_key(trial_id)) or await self.owner(trial_id)

    def send(self, process: str, message: dict[str, Any]) -> None:
        self._outbox.put_nowait((process, json.dumps(message, separators=(",", ":"))))

    async def _send(self) -> None:
        while True:  # one publisher: messages to a process arrive in the order they were sent
            process, data = await self._outbox.get()
            try:
                await self.redis.publish(_channel(process), data)
            except Exception:
                logger.exception("relay: publish to %s failed", process)

    async def _renew(self) -> None:
        while True:
            await asyncio.sleep(RENEW_EVERY_S)
            for runtime in self.services.hub.live():
                with contextlib.suppress(Exception):
                    await self.redis.set(self._owner_key(runtime.trial_id), self.id, ex=OWNER_TTL_S)

    async def _listen(self) -> None:
        async for item in self._pubsub.listen():
            if item.get("type") != "message":
                continue
            try:
                await self._dispatch(json.loads(item["data"]))
            except Exception:
                logger.exception("relay: message not handled")

    async def _dispatch(self, msg: dict[str, Any]) -> None:
        op, conn_id = msg["op"], msg.get("conn")
        if op == "deliver":
            conn = self.local.get(conn_id)
            if conn is not None:
                conn.deliver(msg["message"])
            return
        runtime = await self.services.hub.local(msg["trial"])
        if op == "join":
            seat = RelayedSeat(self, conn_id, msg["role"], msg["from"])
            self.relayed[conn_id] = seat
            runtime.watch(seat) if seat.role == EXPERIMENTER else runtime.join(seat)
        elif op == "text" and conn_id in self.relayed:
            seat = self.relayed[conn_id]
            await runtime.receive(seat, Seat(msg["trial"], seat.role), msg["text"])
        elif op == "bad_message" and conn_id in self.relayed:
            runtime.report_bad_message(Role(self.relayed[conn_id].role), msg["error"])
        elif op == "leave" and conn_id in self.relayed:
            seat = self.relayed.pop(conn_id)
            runtime.unwatch(seat) if seat.role == EXPERIMENTER else runtime.leave(seat)
        elif op == "control":
            getattr(runtime, msg["action"])()


class RelayedSeat:
    """On the owner: a seat whose socket is in another process."""

    def __init__(self, relay: RedisRelay, conn_id: str, role: str, process: str) -> None:
        self.relay, self.conn_id, self.role, self.process = relay, conn_id, role, process

    def deliver(self, message: dict[str, Any]) -> None:
        self.relay.send(self.process, {"op": "deliver", "conn": self.conn_id, "message": message})


class RemoteTrial:
    """On a process that does not own the trial: forwards its seats to the owner."""

    def __init__(self, relay: RedisRelay, trial_id: int, owner: str) -> None:
        self.relay, self.trial_id, self.owner = relay, trial_id, owner
        self._ids: dict[int, str] = {}

    def _command(self, op: str, **fields) -> None:
        self.relay.send(self.owner, {"op": op, "trial": self.trial_id, "from": self.relay.id, **fields})

    def join(self, conn) -> None:
        conn_id = uuid.uuid4().hex
        self._ids[id(conn)] = conn_id
        self.relay.local[conn_id] = conn
        self._command("join", conn=conn_id, role=conn.role)

    def leave(self, conn) -> None:
        conn_id = self._ids.pop(id(conn), None)
        if conn_id is not None:
            self.relay.local.pop(conn_id, None)
            self._command("leave", conn=conn_id)

    async def receive(self, conn, seat: Seat, text: str | None) -> None:
        self._command("text", conn=self._ids[id(conn)], text=text)

    def report_bad_message(self, role: Role, error: str) -> None:
        conn_id = next((c for c in self._ids.values() if getattr(self.relay.local.get(c), "role", None) == role),
                       None)
        if conn_id is not None:
            self._command("bad_message", conn=conn_id, error=error)

    def watch(self, conn) -> None:
        self.join(conn)

    def unwatch(self, conn) -> None:
        self.leave(conn)

    def pause(self) -> None:
        self._command("control", action="pause")

    def resume(self) -> None:
        self._command("control", action="resume")

    def abort(self) -> None:
        self._command("control", action="abort")
