"""A platform on loopback for the benchmarks (and the tests): `robotslang serve` as a separate
process, trials set up in its database, and seats as clients over real websockets."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import httpx
import websockets
from sqlalchemy.orm import Session

from app.seats.registry import offered_agents
from app.settings import Settings
from app.trial.setup import create_participant, create_team, create_trial
from bench.report import rss_mb
from sim.trial.vocabulary import Role

REPO = Path(__file__).resolve().parent.parent
CLI = [sys.executable, "-c", "from app.cli import main; main()"]  # `robotslang`, from this checkout


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until_up(url: str, server: subprocess.Popen, seconds: float = 60.0) -> None:
    """Until the server at `url` answers; RuntimeError if it exits or stays silent `seconds`."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if server.poll() is not None:
            raise RuntimeError(f"robotslang serve exited with status {server.returncode}")
        with contextlib.suppress(httpx.HTTPError):
            if httpx.get(url + "/leaderboard", timeout=1).status_code == 200:
                return
        time.sleep(0.1)
    raise RuntimeError(f"robotslang serve did not answer on {url} within {seconds:g} s")


def settings_env(settings: Settings) -> dict[str, str | None]:
    """The environment that gives `robotslang serve` the settings `settings` set (None: unset)."""
    env: dict[str, str | None] = {}
    for name, value in settings.model_dump(exclude_unset=True).items():
        text = json.dumps(value) if isinstance(value, list) else None if value is None else str(value)
        env[f"ROBOTSLANG_{name.upper()}"] = text
    return env


class ServerProcess:
    """`robotslang serve` as a separate process, so a test can kill it the hard way."""

    def __init__(
        self, env: Mapping[str, str | None], port: int | None = None, workers: int = 1, argv: list[str] | None = None
    ) -> None:
        # A variable given as None is unset for the server (a database URL of the caller's, say).
        self.env = {k: v for k, v in {**os.environ, **env}.items() if v is not None}
        self.port = port or free_port()
        self.workers = workers
        # `argv`: a command of its own that serves on 127.0.0.1:`port` (a deployment's, say).
        self.argv = argv
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def ws_url(self) -> str:
        return f"ws://127.0.0.1:{self.port}/ws/play"

    def start(self) -> ServerProcess:
        # Its output goes to a file open while it runs, not a pipe nobody reads: a full pipe would stall it.
        self.output = tempfile.TemporaryFile("w+")  # noqa: SIM115
        self.proc = subprocess.Popen(
            self.argv or [*CLI, "serve", "--port", str(self.port), "--workers", str(self.workers)],
            env=self.env,
            cwd=REPO,
            stdout=self.output,
            stderr=subprocess.STDOUT,
            text=True,
        )
        try:
            wait_until_up(self.url, self.proc)
        except RuntimeError as error:
            self.stop()
            raise RuntimeError(f"{error}: {self.log()}") from None
        return self

    def kill(self) -> None:
        self.proc.kill()
        self.proc.wait(timeout=10)

    def log(self) -> str:
        """What the server has printed so far. Read at an offset of its own: the server writes
        through the same open file, and a seek here would move where its next line lands."""
        fd = self.output.fileno()
        return os.pread(fd, os.fstat(fd).st_size, 0).decode(errors="replace")

    def stop(self) -> None:
        if self.proc and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()


def team_trial(
    db: Session,
    team: str,
    maze: str,
    maze_names: list[str],
    now_ns: int,
    targets: Sequence[str] = ("mug", "jar", "paddle"),
    backend: str = "sim",
    driver: str = "human",
    agents: Mapping[str, str | None] | None = None,
    commander: str = "human",
    commanders: Mapping[str, str | None] | None = None,
) -> int:
    """A team of two new participants and a trial for it, in the open session `db`: its id. With
    agents in both seats, no team: just the trial."""
    a_id = t_id = None
    if "human" in (commander, driver):
        a = create_participant(db, f"{team} commander")
        b = create_participant(db, f"{team} driver")
        t_id, a_id = create_team(db, team, a.id, b.id).id, a.id
    trial = create_trial(
        db,
        team_id=t_id,
        maze=maze,
        targets=list(targets),
        backend=backend,
        driver=driver,
        commander_id=a_id,
        layouts={name: name for name in maze_names},  # a new team has seen no layout: no grouping needed
        now_ns=now_ns,
        agents=agents,
        commander=commander,
        commanders=commanders,
    )
    return trial.id


def make_trial(
    services,
    maze: str,
    targets: Sequence[str] = ("mug", "jar", "paddle"),
    driver: str = "human",
    team: str = "Team A",
    backend: str = "sim",
    commander: str = "human",
) -> int:
    """`team_trial` on one of the server's mazes, in a transaction of its own; its maze is
    prepared next (`app.preparation`), as the experimenter's page has it."""
    with services.db.begin() as db:
        trial_id = team_trial(
            db,
            team,
            maze,
            services.mazes.names(),
            services.clock.now_ns(),
            targets=targets,
            backend=backend,
            driver=driver,
            agents=offered_agents(services.agents, Role.DRIVER, driver),
            commander=commander,
            commanders=offered_agents(services.agents, Role.COMMANDER, commander),
        )
    services.mazes.preparation.first(maze)
    return trial_id


def _stat(pid: int) -> list[str]:
    """/proc/PID/stat's fields after the command: [1] the parent, [11] and [12] user and system CPU."""
    return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()


class ServerProcesses:
    """CPU seconds and RSS of the server process and its children (workers, render processes),
    from /proc: the peak of their sum, and each one's own peak."""

    def __init__(self, pid: int, workers: int = 1) -> None:
        self.pid, self.workers = pid, workers
        self.peak_rss_mb = 0.0
        self._peaks: dict[int, tuple[str, float]] = {}  # pid -> (kind, peak MB)

    def pids(self) -> list[int]:
        children: dict[int, list[int]] = {}
        for entry in Path("/proc").iterdir():
            if entry.name.isdigit():
                try:
                    ppid = int(_stat(int(entry.name))[1])
                except (OSError, IndexError, ValueError):
                    continue
                children.setdefault(ppid, []).append(int(entry.name))
        found, todo = [], [self.pid]
        while todo:
            pid = todo.pop()
            found.append(pid)
            todo.extend(children.get(pid, []))
        return found

    def cpu_s(self) -> float:
        total = 0.0
        for pid in self.pids():
            try:
                fields = _stat(pid)
            except OSError:
                continue
            total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        return total

    def sample_rss(self) -> float:
        rss = 0.0
        for pid in self.pids():
            try:
                mb = rss_mb(pid)
                kind = self._peaks[pid][0] if pid in self._peaks else self._kind(pid)
            except (OSError, StopIteration):
                continue
            rss += mb
            self._peaks[pid] = (kind, max(mb, self._peaks.get(pid, (kind, 0.0))[1]))
        self.peak_rss_mb = max(self.peak_rss_mb, rss)
        return rss

    def _kind(self, pid: int) -> str:
        """`server` (the process started), `worker` (a server process it spawned, with several),
        `render` (a render process), `tracker` (multiprocessing's resource tracker)."""
        if pid == self.pid:
            return "server"
        command = Path(f"/proc/{pid}/cmdline").read_bytes()
        if b"resource_tracker" in command:
            return "tracker"
        return "worker" if int(_stat(pid)[1]) == self.pid and self.workers > 1 else "render"

    def peaks(self) -> list[dict[str, Any]]:
        """Each process seen: its pid, kind and peak RSS."""
        return [
            {"pid": pid, "kind": kind, "peak_rss_mb": round(mb, 1)} for pid, (kind, mb) in sorted(self._peaks.items())
        ]


class SeatClient:
    """One seat over a real websocket: every message received is kept, in order."""

    def __init__(self, ws_url: str, token: str, origin: str | None = None) -> None:
        self.url, self.token, self.origin = f"{ws_url}?token={token}", token, origin
        self.received: list[dict[str, Any]] = []
        self._new = asyncio.Event()
        self.ws = None

    async def __aenter__(self) -> SeatClient:
        self.ws = await websockets.connect(self.url, origin=self.origin, max_size=2**22)
        self._reader = asyncio.get_running_loop().create_task(self._read())
        return self

    async def __aexit__(self, *exc) -> None:
        await self.ws.close()
        self._reader.cancel()

    async def _read(self) -> None:
        try:
            async for raw in self.ws:
                self.received.append(json.loads(raw))
                self._new.set()
        except websockets.ConnectionClosed:
            pass

    async def send(self, type: str, token: str | None = None, **fields) -> None:
        await self.ws.send(json.dumps({"type": type, "token": token or self.token, **fields}))

    async def wait_for(self, predicate, timeout: float = 10.0, start: int = 0) -> dict[str, Any]:
        """The first message from index `start` on that satisfies `predicate`."""
        deadline = asyncio.get_running_loop().time() + timeout
        i = start
        while True:
            while i < len(self.received):
                if predicate(self.received[i]):
                    return self.received[i]
                i += 1
            remaining = deadline - asyncio.get_running_loop().time()
            if remaining <= 0:
                kinds = [m.get("kind", m.get("type")) for m in self.received[-15:]]
                raise AssertionError(f"no matching message in {timeout} s; last received: {kinds}")
            self._new.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._new.wait(), remaining)

    async def event(self, kind: str, timeout: float = 10.0, start: int = 0, **match) -> dict[str, Any]:
        return await self.wait_for(
            lambda m: m.get("type") == "event"
            and m["kind"] == kind
            and all(m["payload"].get(k) == v for k, v in match.items()),
            timeout,
            start,
        )

    async def moved(self, move_id: str, timeout: float = 10.0, start: int = 0) -> dict[str, Any]:
        """A move's outcome as its `move_executed` payload (`outcome`: ok, collision or refused,
        `reason`); a move refused as it was asked for is answered `move_refused` instead of logged."""
        message = await self.wait_for(
            lambda m: (m.get("type") == "move_refused" and m["move_id"] == move_id)
            or (m.get("type") == "event" and m["kind"] == "move_executed" and m["payload"]["move_id"] == move_id),
            timeout,
            start,
        )
        if message["type"] == "move_refused":
            return {"move_id": move_id, "action": message["action"], "outcome": "refused", "reason": message["reason"]}
        return message["payload"]

    def kinds(self) -> set[str]:
        return {m["kind"] for m in self.received if m.get("type") == "event"}
