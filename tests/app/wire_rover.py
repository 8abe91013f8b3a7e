"""A rover in the test's own process that speaks the wire protocol, and a trial on it."""

from __future__ import annotations

import asyncio
import contextlib
import json
import time

import cv2
import numpy as np
import websockets

from app.rover.records import create_robot
from app.trial.setup import create_participant, create_team, create_trial
from robot_client.protocol import pack_frame

JPEG = cv2.imencode(".jpg", np.zeros((240, 320, 3), np.uint8))[1].tobytes()  # what Rover.frame's header says


class Rover:
    """A rover that speaks the wire protocol: hello, pongs on its own clock, frames; and moves it
    never acknowledges unless told to (so a test can hold a move in flight)."""

    def __init__(self, url: str, token: str, clock_offset_ns: int = 0) -> None:
        self.url, self.token, self.offset = url.replace("/ws/play", "/ws/robot"), token, clock_offset_ns
        self.moves: list[dict] = []
        self.errors: list[dict] = []

    def now(self) -> int:
        return time.monotonic_ns() + self.offset

    async def __aenter__(self) -> Rover:
        self.ws = await websockets.connect(self.url, max_size=2**22)
        await self.ws.send(json.dumps({"type": "hello", "protocol": 1, "token": self.token, "role": "driver"}))
        welcome = json.loads(await self.ws.recv())
        assert welcome["type"] == "welcome", welcome
        self.pongs = 0
        self._reader = asyncio.get_running_loop().create_task(self._read())
        return self

    async def _read(self) -> None:
        with contextlib.suppress(websockets.ConnectionClosed):
            async for raw in self.ws:
                message = json.loads(raw)
                if message["type"] == "ping":
                    await self.ws.send(json.dumps({"type": "pong", "id": message["id"], "robot_ns": self.now()}))
                    self.pongs += 1
                elif message["type"] == "move":
                    self.moves.append(message)
                elif message["type"] == "error":
                    self.errors.append(message)

    async def frame(self, seq: int, capture_ns: int) -> None:
        await self.ws.send(pack_frame(seq, capture_ns, 320, 240, JPEG))

    async def __aexit__(self, *exc) -> None:
        self._reader.cancel()
        await self.ws.close()


def rover_trial(services) -> tuple[int, str]:
    """A registered rover and a trial on it; returns (trial id, the rover's token)."""
    with services.db.begin() as db:
        robot, token = create_robot(db, "rover")
        a, b = create_participant(db, "ann"), create_participant(db, "bob")
        team = create_team(db, "Team R", a.id, b.id)
        trial = create_trial(
            db,
            team_id=team.id,
            maze=services.mazes.names()[0],
            targets=["jar", "mug", "paddle"],
            backend=f"robot:{robot.id}",
            driver="human",
            commander_id=a.id,
            layouts=services.mazes.layouts(),
            now_ns=services.clock.now_ns(),
        )
        return trial.id, token
