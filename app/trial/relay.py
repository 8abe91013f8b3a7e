"""Several server processes, one trial: Redis pub/sub between them (`ROBOTSLANG_REDIS_URL`).

Each trial runs in exactly one process, its owner (a Redis key naming the process, claimed by
the first process a seat of the trial reaches). A seat that reaches another process gets a
`RemoteTrial`: its messages go to the owner, and the owner's `RelayedSeat` sends back what that
seat may hear, filtered by the owner as for local seats. Each process listens on one channel;
messages on it keep their order.

The experimenter's dashboard lists every process's trials: each process publishes the snapshots
of the trials it owns every `SNAPSHOTS_EVERY_S` (a Redis hash by process), and the process that
answers adds the others', as last published, to its own.

Failover: every process keeps a heartbeat key alive (`HEARTBEAT_TTL_S`, renewed every
`HEARTBEAT_EVERY_S` by a thread of its own, so that a loaded event loop that falls seconds behind
is not taken for a dead process). An owner whose heartbeat has lapsed is dead: the next process that needs
the trial (a seat reconnecting, or a `RemoteTrial` whose owner it watches) takes the owner key
over with a compare-and-set, reopens the trial from its log and serves the seats itself. The
log stays the one order: an owner taken over by mistake (stalled, not dead) finds its next
`seq` taken, and its events are refused by the database (`EventLog.on_lost`).
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import json
import logging
import os
import socket
import threading
import uuid
from typing import TYPE_CHECKING, Any, Protocol, cast

from app.trial import messages as m
from app.trial.messages import Message, SeatMessage, TrialSnapshot
from app.trial.views import EXPERIMENTER
from sim.trial.vocabulary import Role

if TYPE_CHECKING:
    from redis import Redis

    from app.settings import Settings
    from app.trial.port import Connection
    from app.trial.runtime import TrialRuntime

logger = logging.getLogger(__name__)
HEARTBEAT_TTL_S = 2.0  # a process silent this long is taken for dead and its trials are taken over
HEARTBEAT_EVERY_S = 0.5
SNAPSHOTS_EVERY_S = 1.0  # how often a process publishes its live trials for the others' dashboards
CONNECTIONS = 32  # to Redis per process; a command waits for a free one (400 seats joining at once)
# Take the owner key from a dead process, unless another process already did.
TAKE_OVER = "if redis.call('get', KEYS[1]) == ARGV[1] then redis.call('set', KEYS[1], ARGV[2]) return 1 end return 0"


def key_prefix(settings: Settings) -> str:
    """Trial ids are per database: processes share owners only when they share the database."""
    return f"robotslang:{hashlib.sha256(settings.url.encode()).hexdigest()[:12]}"


def owner_key(settings: Settings, trial_id: int) -> str:
    """The Redis key naming the process that runs the trial (`host-pid-random`)."""
    return f"{key_prefix(settings)}:trial:{trial_id}:owner"


def _channel(process: str) -> str:
    return f"robotslang:process:{process}"


class LocalTrials(Protocol):
    """The trials this process runs, as the relay reaches them (the hub, passed in)."""

    def live(self) -> list[TrialRuntime]: ...

    def peek(self, trial_id: int) -> TrialRuntime | None: ...

    async def local(self, trial_id: int) -> TrialRuntime: ...


class RedisRelay:
    def __init__(self, hub: LocalTrials, url: str, settings: Settings) -> None:
        import redis.asyncio as redis

        self.hub, self.settings = hub, settings
        pool = redis.BlockingConnectionPool.from_url(
            url, max_connections=CONNECTIONS, timeout=None, decode_responses=True
        )
        self.redis = redis.Redis.from_pool(pool)  # closed with the client
        self._url = url
        self._stop_beating = threading.Event()
        self._beater: threading.Thread | None = None
        self.id = f"{socket.gethostname()}-{os.getpid()}-{uuid.uuid4().hex[:8]}"  # names the process
        self._keys = key_prefix(settings)
        self.local: dict[str, Connection] = {}  # connection id -> this process's seat of a trial owned elsewhere
        self.relayed: dict[str, RelayedSeat] = {}  # connection id -> a remote seat of a trial owned here
        self.remotes: set[RemoteTrial] = set()  # trials owned elsewhere that seats here use
        self._outbox: asyncio.Queue[tuple[str, str]] = asyncio.Queue()
        self._tasks: list[asyncio.Task[None]] = []
        self._opening: dict[int, list[dict[str, Any]]] = {}  # trial id -> its messages while it opens here

    async def start(self) -> None:
        self._pubsub = self.redis.pubsub()
        await self._pubsub.subscribe(_channel(self.id))
        import redis

        beats = redis.Redis.from_url(self._url)
        await asyncio.to_thread(self._beat, beats)
        self._beater = threading.Thread(target=self._beat_until_closed, args=(beats,), name="heartbeat", daemon=True)
        self._beater.start()
        loop = asyncio.get_running_loop()
        self._tasks = [
            loop.create_task(self._listen()),
            loop.create_task(self._send()),
            loop.create_task(self._watch_owners()),
            loop.create_task(self._publish_snapshots()),
        ]

    async def close(self) -> None:
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        for runtime in self.hub.live():
            with contextlib.suppress(Exception):
                if await self.redis.get(self._owner_key(runtime.trial_id)) == self.id:
                    await self.redis.delete(self._owner_key(runtime.trial_id))
        with contextlib.suppress(Exception):
            await self.redis.delete(self._alive_key(self.id))
            await self.redis.hdel(self._snapshots_key, self.id)
        await self._pubsub.aclose()  # type: ignore[no-untyped-call]  # redis-py leaves PubSub.aclose unannotated
        await self.redis.aclose()

    def _owner_key(self, trial_id: int) -> str:
        return owner_key(self.settings, trial_id)

    def _alive_key(self, process: str) -> str:
        return f"{self._keys}:process:{process}:alive"

    @property
    def _snapshots_key(self) -> str:
        return f"{self._keys}:snapshots"

    async def _publish_snapshots(self) -> None:
        while True:
            await asyncio.sleep(SNAPSHOTS_EVERY_S)
            try:
                snapshots = [runtime.snapshot() for runtime in self.hub.live()]
                await self.redis.hset(self._snapshots_key, self.id, json.dumps(snapshots, separators=(",", ":")))
            except Exception:
                logger.exception("relay: publishing the dashboard's snapshots failed")

    async def others_snapshots(self) -> list[TrialSnapshot]:
        """The live trials of the other live processes, as each last published them (up to
        `SNAPSHOTS_EVERY_S` old); a dead process's are dropped."""
        published = cast(dict[str, str], await self.redis.hgetall(self._snapshots_key))
        snapshots: list[TrialSnapshot] = []
        for process, data in published.items():
            if process == self.id:
                continue
            if await self.redis.exists(self._alive_key(process)):
                snapshots.extend(json.loads(data))
            else:
                await self.redis.hdel(self._snapshots_key, process)
        return snapshots

    async def owner(self, trial_id: int) -> str:
        """The process running the trial: a live one, or this one when none is (taking the trial
        over from a dead owner)."""
        key = self._owner_key(trial_id)
        while True:
            if await self.redis.set(key, self.id, nx=True):
                return self.id
            # decode_responses=True: str, which redis-py's annotations (bytes | str) cannot say.
            current = cast(str | None, await self.redis.get(key))
            if current is None:
                continue  # released in between
            if current == self.id or await self.redis.exists(self._alive_key(current)):
                return current
            if await self.redis.eval(TAKE_OVER, 1, key, current, self.id):
                logger.warning("trial %s: taken over from %s, whose heartbeat lapsed", trial_id, current)
                return self.id

    def send(self, process: str, message: dict[str, Any]) -> None:
        self._outbox.put_nowait((process, json.dumps(message, separators=(",", ":"))))

    async def _send(self) -> None:
        """One publisher, so messages to a process arrive in the order they were sent. What queued
        meanwhile goes in one pipeline, in that order: awaited one by one, each publish's round
        trip held up the next, and the relay's queue grew with the load."""
        while True:
            batch = [await self._outbox.get()]
            while not self._outbox.empty():
                batch.append(self._outbox.get_nowait())
            try:
                async with self.redis.pipeline(transaction=False) as pipe:
                    for process, data in batch:
                        pipe.publish(_channel(process), data)
                    await pipe.execute()
            except Exception:
                logger.exception("relay: publishing %d messages failed", len(batch))

    def _beat(self, beats: Redis) -> None:
        beats.set(self._alive_key(self.id), "1", px=int(HEARTBEAT_TTL_S * 1000))

    def _beat_until_closed(self, beats: Redis) -> None:
        """Say this process lives (its own thread and connection)."""
        with beats:
            while not self._stop_beating.wait(HEARTBEAT_EVERY_S):
                try:
                    self._beat(beats)
                except Exception:
                    logger.exception("relay: heartbeat failed")

    async def _watch_owners(self) -> None:
        """Watch the owners of the trials that seats here use; take over from a dead one."""
        while True:
            await asyncio.sleep(HEARTBEAT_EVERY_S)
            try:
                owners = {remote.owner for remote in self.remotes}
                for owner in owners:
                    if not await self.redis.exists(self._alive_key(owner)):
                        for remote in [r for r in self.remotes if r.owner == owner]:
                            await remote.fail_over()
            except Exception:
                logger.exception("relay: watching owners failed")

    async def _listen(self) -> None:
        async for item in self._pubsub.listen():
            if item.get("type") != "message":
                continue
            try:
                await self._dispatch(json.loads(item["data"]))
            except Exception:
                logger.exception("relay: message not handled")

    async def _dispatch(self, msg: dict[str, Any]) -> None:
        if msg["op"] == "deliver":
            conn = self.local.get(msg["conn"])
            if conn is not None:
                conn.deliver(msg["message"])
            return
        trial_id = msg["trial"]
        runtime = self.hub.peek(trial_id)
        if runtime is not None and trial_id not in self._opening:
            await self._apply(runtime, msg)
        elif trial_id in self._opening:
            self._opening[trial_id].append(msg)
        else:
            self._opening[trial_id] = [msg]
            self._tasks.append(asyncio.get_running_loop().create_task(self._open_then_apply(trial_id)))

    async def _open_then_apply(self, trial_id: int) -> None:
        """Open a trial (its log read, its maze loaded: a while) beside the listener, and then
        apply what came for it meanwhile, in order: opened in the listener, each trial a crowd
        opened through the relay held up every other trial's moves and frames to this process."""
        try:
            runtime = await self.hub.local(trial_id)
            waiting = self._opening[trial_id]
            while waiting:  # messages that come while one is applied join the queue
                try:
                    await self._apply(runtime, waiting.pop(0))
                except Exception:
                    logger.exception("relay: message not handled")
        except Exception:
            logger.exception("relay: trial %s not opened here", trial_id)
        finally:
            del self._opening[trial_id]
            self._tasks = [task for task in self._tasks if not task.done()]

    async def _apply(self, runtime: TrialRuntime, msg: dict[str, Any]) -> None:
        op, conn_id = msg["op"], msg.get("conn", "")  # control messages name no connection
        if op == "join":
            seat = RelayedSeat(self, conn_id, msg["role"], msg["from"])
            self.relayed[conn_id] = seat
            runtime.watch(seat) if seat.role == EXPERIMENTER else runtime.join(seat)
        elif op == "message" and conn_id in self.relayed:
            seat = self.relayed[conn_id]
            await runtime.receive(seat, seat.role, m.seat_message.validate_json(msg["message"]))
        elif op == "unread" and conn_id in self.relayed:
            seat = self.relayed[conn_id]
            runtime.refuse_unread(seat, seat.role, msg["error"])
        elif op == "bad_message" and conn_id in self.relayed:
            runtime.report_bad_message(Role(self.relayed[conn_id].role), msg["error"])
        elif op == "leave" and conn_id in self.relayed:
            seat = self.relayed.pop(conn_id)
            runtime.unwatch(seat) if seat.role == EXPERIMENTER else runtime.leave(seat)
        elif op == "control":  # as RemoteTrial._control sent it: an abort's reason, a pause's note
            getattr(runtime, msg["action"])(**{why: msg[why] for why in ("reason", "note") if why in msg})


class RelayedSeat:
    """On the owner: a seat whose socket is in another process."""

    def __init__(self, relay: RedisRelay, conn_id: str, role: str, process: str) -> None:
        self.relay, self.conn_id, self.role, self.process = relay, conn_id, role, process

    def deliver(self, message: Message) -> None:
        self.relay.send(self.process, {"op": "deliver", "conn": self.conn_id, "message": message})


class RemoteTrial:
    """On a process that does not own the trial: forwards its seats to the owner. When the owner
    dies (`fail_over`), the seats are served by the trial's new owner, this process or another."""

    def __init__(self, relay: RedisRelay, trial_id: int, owner: str) -> None:
        self.relay, self.trial_id, self.owner = relay, trial_id, owner
        self._ids: dict[int, str] = {}
        self.runtime: TrialRuntime | None = None  # the trial's runtime here, once this process has taken it over

    def _command(self, op: str, **fields: Any) -> None:
        self.relay.send(self.owner, {"op": op, "trial": self.trial_id, "from": self.relay.id, **fields})

    def join(self, conn: Connection) -> None:
        if self.runtime is not None:
            return _attach(self.runtime, conn)
        conn_id = uuid.uuid4().hex
        self._ids[id(conn)] = conn_id
        self.relay.local[conn_id] = conn
        self.relay.remotes.add(self)
        self._command("join", conn=conn_id, role=conn.role)

    def leave(self, conn: Connection) -> None:
        if self.runtime is not None:
            self.runtime.unwatch(conn) if conn.role == EXPERIMENTER else self.runtime.leave(conn)
            return
        conn_id = self._ids.pop(id(conn), None)
        if conn_id is not None:
            self.relay.local.pop(conn_id, None)
            self._command("leave", conn=conn_id)
        if not self._ids:
            self.relay.remotes.discard(self)

    async def fail_over(self) -> None:
        """The owner is dead: take the trial here, or follow the process that already has."""
        owner = await self.relay.owner(self.trial_id)
        conns = [(conn_id, self.relay.local[conn_id]) for conn_id in self._ids.values() if conn_id in self.relay.local]
        if owner != self.relay.id:
            self.owner = owner
            for conn_id, conn in conns:
                self._command("join", conn=conn_id, role=conn.role)
            return
        self.runtime = await self.relay.hub.local(self.trial_id)
        self.relay.remotes.discard(self)
        self._ids.clear()
        for conn_id, conn in conns:
            self.relay.local.pop(conn_id, None)
            _attach(self.runtime, conn)

    async def receive(self, conn: Connection, role: str, message: SeatMessage) -> None:
        if self.runtime is not None:
            return await self.runtime.receive(conn, role, message)
        self._command("message", conn=self._ids[id(conn)], message=message.model_dump_json())

    def refuse_unread(self, conn: Connection, role: str, error: str) -> None:
        if self.runtime is not None:
            return self.runtime.refuse_unread(conn, role, error)
        self._command("unread", conn=self._ids[id(conn)], error=error)

    def report_bad_message(self, role: Role, error: str) -> None:
        if self.runtime is not None:
            return self.runtime.report_bad_message(role, error)
        conn_id = next((c for c in self._ids.values() if getattr(self.relay.local.get(c), "role", None) == role), None)
        if conn_id is not None:
            self._command("bad_message", conn=conn_id, error=error)

    def watch(self, conn: Connection) -> None:
        self.join(conn)

    def unwatch(self, conn: Connection) -> None:
        self.leave(conn)

    def _control(self, action: str, **why: str | None) -> None:
        if self.runtime is not None:
            getattr(self.runtime, action)(**why)
            return
        self._command("control", action=action, **why)

    def pause(self, note: str | None = None) -> None:
        self._control("pause", note=note)

    def resume(self) -> None:
        self._control("resume")

    def abort(self, reason: str | None = None) -> None:
        self._control("abort", reason=reason)


def _attach(runtime: TrialRuntime, conn: Connection) -> None:
    runtime.watch(conn) if conn.role == EXPERIMENTER else runtime.join(conn)
