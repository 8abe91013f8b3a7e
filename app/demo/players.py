"""The scripted Commander and Driver, each on its own websocket exactly as a browser is.

Both know the robot's true start pose (the demo reads it from the log, as the experimenter
could): the Commander turns the shortest route into words, and the Driver follows it by dead
reckoning on the move outcomes the server reports, with a few deliberate mistakes and
questions so that the recordings look like people's.
"""

from __future__ import annotations

import asyncio
import json
import random
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

from websockets.asyncio.client import ClientConnection, connect

from app.demo.script import OBJECT_WORDS, describe_view, plan_leg
from sim.core.dynamics import Action, Pose, teacher_action
from sim.core.geometry import TABLE_HEIGHT_M, TABLE_WIDTH_M, heading_angle
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.trial.vocabulary import Phase, Role

# A message from the server as it arrives on the socket (decoded JSON; app.trial.views builds them).
ServerMessage = dict[str, Any]

WAIT_S = 60.0  # longest a player waits for its partner or the server before giving up
QUESTIONS = ("should i keep going this way?", "is this the right way?", "which way now?", "do i turn here?")
ANSWERS = ("yes, keep going", "yes, you're on the right track", "keep following the walls as i said")


class DemoError(RuntimeError):
    """A scripted trial that could not go on; the message names the trial and what was missing."""


@dataclass
class Seat:
    """One player's socket: sends messages with its token, and waits for the events it hears."""

    role: str
    trial_id: int
    token: str
    ws: ClientConnection
    message_interval_s: float = 0.0  # the server takes a seat's messages (moves too) this far apart at most
    inbox: asyncio.Queue[ServerMessage] = field(default_factory=asyncio.Queue)
    reader: asyncio.Task[None] | None = None
    last_sent: float = float("-inf")

    @classmethod
    async def open(cls, server: str, trial_id: int, role: str, token: str, message_interval_s: float = 0.0) -> Seat:
        url = server.replace("http://", "ws://").replace("https://", "wss://").rstrip("/")
        ws = await connect(f"{url}/ws/play?token={token}", max_size=2**24)
        seat = cls(role=role, trial_id=trial_id, token=token, ws=ws, message_interval_s=message_interval_s)
        seat.reader = asyncio.get_running_loop().create_task(seat._read())
        return seat

    async def _read(self) -> None:
        try:
            async for text in self.ws:
                await self.inbox.put(json.loads(text))
        finally:
            await self.inbox.put({"type": "closed"})

    async def send(self, type_: str, **fields: Any) -> None:
        # No faster than the seat's rate limit lets the server take them, as a person plays.
        loop = asyncio.get_running_loop()
        await asyncio.sleep(max(0.0, self.last_sent + self.message_interval_s - loop.time()))
        self.last_sent = loop.time()
        await self.ws.send(json.dumps({"type": type_, "token": self.token, **fields}))

    async def say(self, text: str) -> None:
        await self.send("chat", text=text)

    async def until(self, accept: Callable[[ServerMessage], bool], what: str) -> ServerMessage:
        """The next message for which `accept(message)` is true."""
        try:
            async with asyncio.timeout(WAIT_S):
                while True:
                    message = await self.inbox.get()
                    if message.get("type") == "closed":
                        raise DemoError(
                            f"trial {self.trial_id}: the server closed the {self.role}'s "
                            f"socket while waiting for {what}"
                        )
                    if accept(message):
                        return message
        except TimeoutError:
            raise DemoError(f"trial {self.trial_id}: the {self.role} waited {WAIT_S:.0f} s for {what}") from None

    async def event(self, kind: str, what: str | None = None, **match: Any) -> ServerMessage:
        """The next logged event of this kind whose payload has the values `match` gives."""
        return await self.until(
            partial(_is_event, kind=kind, **match), what or f"a {kind!r} event {match or ''}".strip()
        )

    async def move_outcome(self, move_id: str) -> str:
        """`ok`, `collision` or `refused`: its `move_executed` event, or the `move_refused` reply
        to a move refused as it was asked for."""

        def accept(m: ServerMessage) -> bool:
            if m.get("type") == "move_refused":
                return bool(m["move_id"] == move_id)
            return _is_event(m, "move_executed", move_id=move_id)

        done = await self.until(accept, f"the outcome of move {move_id!r}")
        return "refused" if done["type"] == "move_refused" else str(done["payload"]["outcome"])

    async def close(self) -> None:
        await self.ws.close()
        if self.reader is not None:
            await asyncio.gather(self.reader, return_exceptions=True)


def _is_event(message: ServerMessage, kind: str, **match: Any) -> bool:
    return (
        message.get("type") == "event"
        and message.get("kind") == kind
        and all(message["payload"].get(k) == v for k, v in match.items())
    )


_driver_chat = partial(_is_event, kind="chat", role=Role.DRIVER)
_claim = partial(_is_event, kind="target_claimed")


@dataclass
class Player:
    """What both scripted players know: the maze, its graph, the targets; and their own dice."""

    maze: Maze
    graph: NavGraph
    targets: list[str]
    rng: random.Random
    pace_s: float = 0.0


class ScriptedCommander(Player):
    async def play(self, seat: Seat, start: Pose) -> None:
        await seat.event("phase", "the localizing phase", phase=Phase.LOCALIZING)
        await seat.say("hi! what do you see around you?")
        await seat.until(_driver_chat, "the driver's description")
        await self._localize(seat, start)
        pose = start
        for k, target in enumerate(self.targets):
            await seat.event("phase", f"navigating to target {k}", phase=Phase.NAVIGATING, target_index=k)
            leg = plan_leg(self.maze, self.graph, pose, target)
            await seat.say(f"now find the {OBJECT_WORDS[target]}")
            for line in leg.instructions:
                await asyncio.sleep(self.pace_s)
                await seat.say(line)
            pose = leg.end
            while True:  # answer questions until the Driver claims the target
                message = await seat.until(
                    lambda m: _driver_chat(m) or _claim(m), f"the driver's claim of the {target}"
                )
                if _claim(message):
                    break
                if message["payload"]["text"].endswith("?"):
                    await seat.say(self.rng.choice(ANSWERS))
            await seat.send("confirm")
        await seat.event("phase", "the end of the trial", phase=Phase.FINISHED)

    async def _localize(self, seat: Seat, start: Pose) -> None:
        # The Commander's estimate: close to the truth, as a good team's is.
        x, y = self.graph.nodes[start.node]
        x = min(max(x + self.rng.gauss(0.0, 0.04), 0.0), TABLE_WIDTH_M)
        y = min(max(y + self.rng.gauss(0.0, 0.04), 0.0), TABLE_HEIGHT_M)
        heading = float(heading_angle(start.heading)) if self.rng.random() < 0.7 else None
        await seat.say("ok, i think i know where you are")
        await seat.send("localize", x=float(x), y=float(y), heading=heading)


@dataclass
class ScriptedDriver(Player):
    """Follows the shortest path, with a wrong move now and then (`mistake_rate` per move) and a
    question now and then (`question_rate` per move)."""

    mistake_rate: float = 0.03
    question_rate: float = 0.03
    moves: int = field(default=0, init=False)

    async def play(self, seat: Seat, start: Pose) -> None:
        await seat.event("phase", "the localizing phase", phase=Phase.LOCALIZING)
        await seat.event("chat", role=Role.COMMANDER)
        await seat.say(describe_view(self.maze, self.graph, start))
        pose = start
        for k, target in enumerate(self.targets):
            await seat.event("phase", f"navigating to target {k}", phase=Phase.NAVIGATING, target_index=k)
            pose = await self._drive_to(seat, pose, self.graph.nearest_node(*self.maze.objects[target]))
            await seat.say(f"i think i found the {OBJECT_WORDS[target]}")
            await seat.send("claim")
            await seat.event("target_confirmed", target_index=k)

    async def _drive_to(self, seat: Seat, pose: Pose, goal: int) -> Pose:
        for _ in range(4 * self.graph.n):
            action = teacher_action(self.graph, pose, goal)
            if action == Action.STOP:
                return pose
            if self.rng.random() < self.question_rate:
                await seat.say(self.rng.choice(QUESTIONS))
            if self.rng.random() < self.mistake_rate:
                action = self.rng.choice([a for a in (Action.FORWARD, Action.LEFT, Action.RIGHT) if a != action])
            pose = await self._move(seat, pose, action)
        raise DemoError(f"trial {seat.trial_id}: the driver could not reach node {goal}")

    async def _move(self, seat: Seat, pose: Pose, action: Action) -> Pose:
        while True:
            await asyncio.sleep(self.pace_s)
            move_id = f"d{self.moves}"
            self.moves += 1
            await seat.send("move", action=action.word, move_id=move_id)
            outcome = await seat.move_outcome(move_id)
            if outcome == "ok":
                return self.graph.moves.step(pose, action)[0]
            if outcome == "collision":
                await seat.say("oops, i bumped into a wall")
                return pose
            # Refused (too soon, or paused): wait a moment and try again, as a person would.
            await asyncio.sleep(max(self.pace_s, 0.3))
