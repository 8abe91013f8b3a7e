"""Takeover time: two `robotslang serve` processes on PostgreSQL + Redis, one trial owned by the
first (the Commander's), the Driver on the second. The owner is killed with SIGKILL; printed: the
time from the kill until the Driver's open socket is served again (its new `welcome`) and until a
chat message from the Driver, sent right after the kill, has reached the log.

    python -m bench.failover
"""

from __future__ import annotations

import argparse
import asyncio
import os
import signal
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from sqlalchemy import func, select

from app.db.models import Event
from app.main import build_services
from app.settings import Settings
from bench.live import SeatClient, ServerProcess, settings_env, team_trial
from bench.load import database
from bench.report import load_average

console = Console()
TIMEOUT_S = 60.0  # a takeover that has not happened by then is reported as a failure


def welcome(message: dict) -> bool:
    return message.get("type") == "welcome"


async def one_run(services, trial_id: int, first: ServerProcess, second: ServerProcess) -> tuple[float, float]:
    async with SeatClient(first.ws_url, services.seats.issue(trial_id, "commander")) as commander:
        await commander.wait_for(welcome, TIMEOUT_S)  # the Commander's process owns the trial
        async with SeatClient(second.ws_url, services.seats.issue(trial_id, "driver")) as driver:
            await driver.wait_for(welcome, TIMEOUT_S)
            await driver.event("phase", TIMEOUT_S)
            await asyncio.sleep(1.0)

            def count() -> int:
                query = select(func.count(Event.id)).where(Event.trial_id == trial_id, Event.kind == "chat")
                with services.db() as db:  # closed at once: an open transaction would block the schema's drop
                    return db.execute(query).scalar_one()

            before, heard = count(), len(driver.received)
            killed = time.perf_counter()
            os.kill(first.proc.pid, signal.SIGKILL)
            await driver.send("chat", text="still there?")
            await driver.wait_for(welcome, TIMEOUT_S, start=heard)
            served = time.perf_counter() - killed
            # the chat sent into the dead owner is lost with it; send again once served
            while count() == before and time.perf_counter() - killed < TIMEOUT_S:
                await driver.send("chat", text="still there?")
                await asyncio.sleep(0.05)
            logged = time.perf_counter() - killed
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
            env = {**settings_env(settings), "ROBOTSLANG_REDIS_URL": args.redis_url}
            services = build_services(settings)
            names = services.mazes.names()
            with services.db.begin() as db:
                trial_id = team_trial(
                    db, "failover", names[0], names, services.clock.now_ns(), ("jar", "mug", "paddle")
                )
            servers = ServerProcess(env), ServerProcess(env)
            try:
                s, lg = asyncio.run(one_run(services, trial_id, servers[0].start(), servers[1].start()))
                served.append(s)
                logged.append(lg)
                console.print(
                    f"run {run + 1}: Driver served again {s:.2f} s after the kill, its chat logged at {lg:.2f} s"
                )
            finally:
                for server in servers:
                    server.stop()
                services.engine.dispose()
    console.print(
        f"[bold]bench.failover[/]: {args.runs} runs, takeover (kill -> Driver served) median "
        f"{np.median(served):.2f} s, max {max(served):.2f} s; chat logged median {np.median(logged):.2f} s "
        f"(load average {load_average()})"
    )


if __name__ == "__main__":
    main()
