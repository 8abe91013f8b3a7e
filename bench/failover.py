"""Takeover time: two `robotslang serve` processes on PostgreSQL + Redis, one trial owned by the
first (the Commander's), the Driver on the second. The owner is killed with SIGKILL; printed: the
time from the kill until the Driver's open socket is served again (its new `welcome`) and until a
chat message from the Driver, sent right after the kill, has reached the log.

    python -m bench.failover
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import websockets
from rich.console import Console
from sqlalchemy import func, select

from app.db.models import Event
from app.main import build_services
from app.settings import Settings
from app.trial.setup import create_participant, create_team, create_trial
from bench.live import free_port
from bench.load import database, wait_until_up

console = Console()
TIMEOUT_S = 60.0  # a takeover that has not happened by then is reported as a failure


def serve(env: dict[str, str], port: int) -> subprocess.Popen:
    server = subprocess.Popen(
        [sys.executable, "-c", "from app.cli import main; main()", "serve", "--port", str(port)],
        env=env,
        stdout=subprocess.DEVNULL,
    )
    wait_until_up(f"http://127.0.0.1:{port}", server)
    return server


async def until(ws, predicate) -> dict:
    while True:
        message = json.loads(await ws.recv())
        if predicate(message):
            return message


async def one_run(services, trial_id: int, first: subprocess.Popen, ports: tuple[int, int]) -> tuple[float, float]:
    commander_token, driver_token = (services.seats.issue(trial_id, r) for r in ("commander", "driver"))
    commander = await websockets.connect(f"ws://127.0.0.1:{ports[0]}/ws/play?token={commander_token}")
    await until(commander, lambda m: m.get("type") == "welcome")
    async with websockets.connect(f"ws://127.0.0.1:{ports[1]}/ws/play?token={driver_token}") as driver:
        seen: set[str] = set()  # the welcome and the trial's start, in whichever order they come
        await asyncio.wait_for(
            until(driver, lambda m: bool(seen.add(m.get("kind") or m["type"])) or {"welcome", "phase"} <= seen),
            TIMEOUT_S,
        )
        await asyncio.sleep(1.0)

        def count() -> int:
            query = select(func.count(Event.id)).where(Event.trial_id == trial_id, Event.kind == "chat")
            with services.db() as db:  # closed at once: an open transaction would block the schema's drop
                return db.execute(query).scalar_one()

        before = count()
        killed = time.perf_counter()
        os.kill(first.pid, signal.SIGKILL)
        await driver.send(json.dumps({"type": "chat", "token": driver_token, "text": "still there?"}))
        await asyncio.wait_for(until(driver, lambda m: m.get("type") == "welcome"), TIMEOUT_S)
        served = time.perf_counter() - killed
        # the chat sent into the dead owner is lost with it; send again once served
        while count() == before and time.perf_counter() - killed < TIMEOUT_S:
            await driver.send(json.dumps({"type": "chat", "token": driver_token, "text": "still there?"}))
            await asyncio.sleep(0.05)
        logged = time.perf_counter() - killed
    await commander.close()
    return served, logged


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--redis-url", default="redis://127.0.0.1:6379/0")
    parser.add_argument("--postgres-url", default="postgresql+psycopg://postgres@127.0.0.1:5432/test")
    args = parser.parse_args()
    served, logged = [], []
    for run in range(args.runs):
        with tempfile.TemporaryDirectory(prefix="robotslang-failover-") as tmp, database(2, args.postgres_url) as url:
            settings = Settings(data_dir=Path(tmp) / "var", secret_key="failover", database_url=url)
            env = {
                **os.environ,
                "ROBOTSLANG_DATA_DIR": str(settings.data_dir),
                "ROBOTSLANG_SECRET_KEY": "failover",
                "ROBOTSLANG_DATABASE_URL": url,
                "ROBOTSLANG_REDIS_URL": args.redis_url,
            }
            services = build_services(settings)
            names = services.mazes.names()
            with services.db.begin() as db:
                a, b = create_participant(db, "c"), create_participant(db, "d")
                team = create_team(db, "failover", a.id, b.id)
                trial_id = create_trial(
                    db,
                    team_id=team.id,
                    maze=names[0],
                    targets=["jar", "mug", "paddle"],
                    backend="sim",
                    driver="human",
                    commander_id=a.id,
                    layouts=services.mazes.layouts(),
                    now_ns=services.clock.now_ns(),
                ).id
            ports = (free_port(), free_port())
            first, second = serve(env, ports[0]), serve(env, ports[1])
            try:
                s, lg = asyncio.run(one_run(services, trial_id, first, ports))
                served.append(s)
                logged.append(lg)
                console.print(
                    f"run {run + 1}: Driver served again {s:.2f} s after the kill, its chat logged at {lg:.2f} s"
                )
            finally:
                for server in (first, second):
                    if server.poll() is None:
                        server.terminate()
                        server.wait(timeout=30)
                services.engine.dispose()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    console.print(
        f"[bold]bench.failover[/]: {args.runs} runs, takeover (kill -> Driver served) median "
        f"{np.median(served):.2f} s, max {max(served):.2f} s; chat logged median {np.median(logged):.2f} s "
        f"(load average {load})"
    )


if __name__ == "__main__":
    main()
