"""A scripted server on loopback: the other end of the wire protocol, written from
docs/protocol.md, so the rover client is tested over a real websocket without the app."""

from __future__ import annotations

import asyncio
import json

from robot_client.protocol import CLOSE_REFUSED, unpack_frame


class ScriptedServer:
    """Accepts robots with token `good`, welcomes them, pings every `ping_s` while `pinging`,
    and records everything it receives."""

    def __init__(self, ping_s: float = 0.1) -> None:
        self.ping_s = ping_s
        self.pinging = True
        self.hellos: list[dict] = []
        self.messages: asyncio.Queue[dict] = asyncio.Queue()
        self.frames: list = []
        self.connections = []
        self.connected = asyncio.Event()
        self.url = ""

    async def handler(self, ws) -> None:
        hello = json.loads(await ws.recv())
        self.hellos.append(hello)
        if hello.get("token") != "good":
            await ws.send(json.dumps({"type": "error", "code": "auth", "error": "unknown robot token"}))
            await ws.close(CLOSE_REFUSED, "unknown robot token")
            return
        await ws.send(
            json.dumps(
                {
                    "type": "welcome",
                    "robot": {"id": 1, "name": "r1", "role": hello["role"]},
                    "ping_interval_s": self.ping_s,
                }
            )
        )
        self.connections.append(ws)
        self.connected.set()
        pinger = asyncio.create_task(self._ping(ws))
        try:
            async for raw in ws:
                if isinstance(raw, bytes):
                    self.frames.append(unpack_frame(raw)[0])
                else:
                    await self.messages.put(json.loads(raw))
        finally:
            pinger.cancel()

    async def _ping(self, ws) -> None:
        n = 0
        while True:
            if self.pinging:
                n += 1
                await ws.send(json.dumps({"type": "ping", "id": n, "server_ns": 0}))
            await asyncio.sleep(self.ping_s)

    async def send(self, message: dict | str | bytes) -> None:
        await self.connections[-1].send(json.dumps(message) if isinstance(message, dict) else message)

    async def next(self, kind: str, timeout: float = 3.0) -> dict:
        """The next received message of this type (others are skipped)."""
        async with asyncio.timeout(timeout):
            while True:
                message = await self.messages.get()
                if message["type"] == kind:
                    return message
