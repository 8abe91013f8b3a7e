"""Scripted demo trials: set up as an experimenter would, played over the server's sockets.

Participants, a team and a trial are created in the configured database with the same
functions the experimenter's pages use; then a scripted Commander and Driver join with their
signed links and play the trial to the end through `/ws/play`. Without a server URL the demo
serves the app itself on a free loopback port for as long as it runs.
"""

from __future__ import annotations

import asyncio
import contextlib
import random
import socket
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass

from sqlalchemy import func, select

from app.clock import ServerClock
from app.db.engine import open_database
from app.db.models import Team, Trial
from app.demo.players import WAIT_S, DemoError, ScriptedCommander, ScriptedDriver, Seat
from app.mazes import Mazes
from app.security import SeatTokens
from app.settings import Settings
from app.trial.log import EventLog
from app.trial.setup import create_participant, create_team, create_trial, parse_targets, suggest_maze
from sim.core.dynamics import Pose, snap_pose
from sim.trial import events as ev
from sim.trial.vocabulary import PARTICIPANTS

DEMO_TEAM = "demo team {k}"


@dataclass(frozen=True)
class DemoResult:
    trial_id: int
    maze: str
    targets: tuple[str, ...]
    phase: str
    moves: int
    error: str | None = None


class Demo:
    """Creates and plays scripted trials on the data directory of `settings`."""

    def __init__(self, settings: Settings, seed: int = 0, pace_s: float | None = None) -> None:
        self.settings = settings
        self.db = open_database(settings)
        self.log = EventLog(self.db)
        self.mazes = Mazes(settings)
        self.seats = SeatTokens(settings.signing_key())
        self.rng = random.Random(seed)
        # Moves closer together than the server allows are refused, so pace just above it.
        self.pace_s = settings.min_move_interval_s * 1.2 if pace_s is None else pace_s

    def create_trial(self) -> Trial:
        """A fresh demo team (so any maze is new to it) and a trial on its least-used maze."""
        layouts = self.mazes.layouts()
        with self.db.begin() as db:
            k = (db.scalar(select(func.count()).select_from(Team).where(Team.name.like("demo team %"))) or 0) + 1
            while db.scalar(select(Team.id).where(Team.name == DEMO_TEAM.format(k=k))) is not None:
                k += 1
            a = create_participant(db, f"demo commander {k}")
            b = create_participant(db, f"demo driver {k}")
            team = create_team(db, DEMO_TEAM.format(k=k), a.id, b.id)
            maze = suggest_maze(db, team, layouts)
            if maze is None:
                raise DemoError("the maze library is empty: no maze to run a demo trial in")
            return create_trial(
                db,
                team_id=team.id,
                maze=maze,
                targets=parse_targets("random", self.rng),
                backend="sim",
                driver="human",
                commander_id=a.id,
                layouts=layouts,
                now_ns=ServerClock().now_ns(),
            )

    async def start_pose(self, trial: Trial) -> Pose:
        """Where the simulator put the robot: the first pose in the log, written as the server
        opens the trial (after it has answered the seats' sockets)."""
        for _ in range(int(WAIT_S / 0.05)):
            poses = [e for e in self.log.load(trial.id) if e.is_(ev.PoseSampled)]
            if poses:
                p = poses[0].payload
                return snap_pose(self.mazes.graph(trial.maze), p["x"], p["y"], p["heading"])
            await asyncio.sleep(0.05)
        raise DemoError(
            f"trial {trial.id}: the server logged no robot pose in {WAIT_S:.0f} s; is it a simulator trial?"
        )

    async def play(self, server: str, trial: Trial) -> DemoResult:
        maze, graph = self.mazes.load(trial.maze), self.mazes.graph(trial.maze)
        # One generator per player: their draws interleave differently from run to run.
        commander = ScriptedCommander(maze, graph, list(trial.targets), random.Random(self.rng.random()), self.pace_s)
        driver = ScriptedDriver(maze, graph, list(trial.targets), random.Random(self.rng.random()), self.pace_s)
        seats: list[Seat] = []
        error = None
        try:
            for role in PARTICIPANTS:
                seats.append(
                    await Seat.open(
                        server,
                        trial.id,
                        role,
                        self.seats.issue(trial.id, role),
                        message_interval_s=1.0 / self.settings.seat_message_rate_per_s,
                    )
                )
            start = await self.start_pose(trial)
            await asyncio.gather(commander.play(seats[0], start), driver.play(seats[1], start))
        except (DemoError, OSError) as err:
            error = str(err)
        finally:
            for seat in seats:
                await seat.close()
        with self.db() as db:
            row = db.get_one(Trial, trial.id)
            return DemoResult(trial.id, trial.maze, tuple(trial.targets), row.phase, row.moves, error)

    async def run(
        self,
        trials: int,
        server: str | None = None,
        parallel: int = 1,
        on_done: Callable[[DemoResult], None] = lambda r: None,
    ) -> list[DemoResult]:
        async with serving(self.settings, server) as url:
            gate = asyncio.Semaphore(max(1, parallel))

            async def one() -> DemoResult:
                async with gate:
                    result = await self.play(url, self.create_trial())
                    on_done(result)
                    return result

            return list(await asyncio.gather(*(one() for _ in range(trials))))


@contextlib.asynccontextmanager
async def serving(settings: Settings, server: str | None) -> AsyncIterator[str]:
    """`server` as is, or the app served in this event loop on a free loopback port."""
    if server:
        server = server.rstrip("/")
        await _check_reachable(server)
        yield server
        return
    import uvicorn

    from app.main import create_app

    port = free_port()
    from app.serving import uvicorn_options

    config = uvicorn.Config(
        create_app(settings),
        host="127.0.0.1",
        port=port,
        log_level="warning",
        lifespan="on",
        **uvicorn_options(settings),
    )
    server_ = uvicorn.Server(config)
    task = asyncio.get_running_loop().create_task(server_.serve())
    while not server_.started:
        if task.done():
            task.result()  # raises the server's own error
            raise DemoError(f"the demo server on 127.0.0.1:{port} stopped before it started")
        await asyncio.sleep(0.05)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server_.should_exit = True
        await task


async def _check_reachable(server: str) -> None:
    """Fail before creating any trial when nothing answers at `server`."""
    import httpx

    try:
        async with httpx.AsyncClient(timeout=5) as client:
            (await client.get(f"{server}/leaderboard")).raise_for_status()
    except httpx.HTTPError as err:
        raise DemoError(f"--server {server}: no RobotSlang server answers there ({err})") from None


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port
