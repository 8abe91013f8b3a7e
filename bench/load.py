"""Load on loopback: N concurrent simulator trials, each with a scripted Commander and Driver
over websockets sending a chat message and a move every second.

Prints p50/p99 of chat fan-out latency (Commander sends -> Driver receives) and of
move-to-frame latency (Driver sends a move -> receives the new camera frame), and events
committed per second. The server runs as its own process (`robotslang serve`), as in use.

    python -m bench.load --trials 50 --duration 30
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
import websockets
from rich.console import Console
from rich.progress import Progress
from sqlalchemy import func, select

from app.db.models import Event
from app.main import build_services
from app.settings import Settings
from app.trial.setup import create_participant, create_team, create_trial

console = Console()


def setup_trials(settings: Settings, n: int) -> tuple[list[tuple[str, str]], object]:
    services = build_services(settings)
    maze_names = services.mazes.names()
    tokens = []
    with services.db.begin() as db:
        for i in range(n):
            a, b = create_participant(db, f"load-c{i}"), create_participant(db, f"load-d{i}")
            team = create_team(db, f"load-team-{i}", a.id, b.id)
            trial = create_trial(db, team_id=team.id, maze=maze_names[i % len(maze_names)],
                                 targets=["jar", "mug", "paddle"], backend="sim", driver="human",
                                 commander_id=a.id, maze_names=maze_names, now_ns=services.clock.now_ns())
            tokens.append((services.seats.issue(trial.id, "commander"), services.seats.issue(trial.id, "driver")))
    for name in set(maze_names[i % len(maze_names)] for i in range(n)):
        services.mazes.graph(name)  # warm the graph cache so the server does not build them under load
    return tokens, services


class Figures:
    def __init__(self) -> None:
        self.chat_ms: list[float] = []
        self.frame_ms: list[float] = []
        self.recording = False


async def run_trial(ws_url: str, tokens: tuple[str, str], figures: Figures, stop: asyncio.Event) -> None:
    commander_token, driver_token = tokens
    async with websockets.connect(f"{ws_url}?token={commander_token}", max_size=2**22) as commander, \
               websockets.connect(f"{ws_url}?token={driver_token}", max_size=2**22) as driver:
        chats: dict[str, float] = {}
        move_sent: list[float] = []

        async def driver_reader():
            async for raw in driver:
                now = time.perf_counter()
                message = json.loads(raw)
                if message.get("type") != "event":
                    continue
                if message["kind"] == "chat" and message["payload"]["text"] in chats:
                    sent = chats.pop(message["payload"]["text"])
                    if figures.recording:
                        figures.chat_ms.append((now - sent) * 1e3)
                elif message["kind"] == "frame" and move_sent:
                    if figures.recording:
                        figures.frame_ms.append((now - move_sent.pop()) * 1e3)
                    move_sent.clear()

        async def commander_reader():
            async for _ in commander:  # the Commander hears its own echo; nothing to measure
                pass

        readers = [asyncio.create_task(driver_reader()), asyncio.create_task(commander_reader())]
        rng = random.Random()
        await asyncio.sleep(rng.random())  # spread the trials over the second
        await commander.send(json.dumps({"type": "localize", "token": commander_token, "x": 1.2, "y": 1.0}))
        i = 0
        while not stop.is_set():
            text = f"where are you now? {id(chats)}-{i}"
            chats[text] = time.perf_counter()
            await commander.send(json.dumps({"type": "chat", "token": commander_token, "text": text}))
            await asyncio.sleep(0.5)
            move_sent[:] = [time.perf_counter()]
            action = rng.choice(["forward", "forward", "left", "right"])
            await driver.send(json.dumps({"type": "move", "token": driver_token, "action": action}))
            await asyncio.sleep(0.5)
            i += 1
        for task in readers:
            task.cancel()


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


async def drive(ws_url: str, tokens, warmup: float, duration: float, services) -> tuple[Figures, int, float]:
    figures, stop = Figures(), asyncio.Event()
    tasks = [asyncio.create_task(run_trial(ws_url, t, figures, stop)) for t in tokens]
    await asyncio.sleep(warmup)
    count = lambda: services.db().execute(select(func.count(Event.id))).scalar_one()  # noqa: E731
    before, t0 = count(), time.perf_counter()
    figures.recording = True
    with Progress(console=console, transient=True) as progress:
        bar = progress.add_task(f"{len(tokens)} trials under load", total=duration)
        while (elapsed := time.perf_counter() - t0) < duration:
            await asyncio.sleep(0.5)
            progress.update(bar, completed=min(elapsed, duration))
    figures.recording = False
    committed, window = count() - before, time.perf_counter() - t0
    stop.set()
    await asyncio.gather(*tasks, return_exceptions=True)
    return figures, committed, window


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=50)
    parser.add_argument("--duration", type=float, default=30.0, help="measured seconds")
    parser.add_argument("--warmup", type=float, default=5.0)
    parser.add_argument("--port", type=int, default=8765)
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="robotslang-load-") as tmp:
        env = {**os.environ, "ROBOTSLANG_DATA_DIR": str(Path(tmp) / "var"), "ROBOTSLANG_SECRET_KEY": "load"}
        env.pop("ROBOTSLANG_DATABASE_URL", None)  # the bench measures the embedded SQLite setup
        settings = Settings(data_dir=Path(tmp) / "var", secret_key="load")
        tokens, services = setup_trials(settings, args.trials)
        server = subprocess.Popen([sys.executable, "-c", "from app.cli import main; main()", "serve",
                                   "--port", str(args.port)], env=env, stdout=subprocess.DEVNULL)
        try:
            url = f"http://127.0.0.1:{args.port}"
            for _ in range(300):
                try:
                    httpx.get(url + "/leaderboard", timeout=1)
                    break
                except httpx.HTTPError:
                    if server.poll() is not None:
                        raise SystemExit(f"robotslang serve exited with status {server.returncode}")
                    time.sleep(0.1)
            else:
                raise SystemExit(f"robotslang serve did not answer on {url} within 30 s")
            figures, committed, window = asyncio.run(
                drive(f"ws://127.0.0.1:{args.port}/ws/play", tokens, args.warmup, args.duration, services))
        finally:
            server.terminate()
            server.wait(timeout=20)

    console.print(f"[bold]bench.load[/]: {args.trials} concurrent simulator trials, 1 chat + 1 move per second "
                  f"each, {window:.0f} s measured on loopback ({os.cpu_count()} CPUs, SQLite WAL)")
    console.print(f"chat fan-out    p50 {percentile(figures.chat_ms, 50):7.1f} ms   "
                  f"p99 {percentile(figures.chat_ms, 99):7.1f} ms   ({len(figures.chat_ms)} messages)")
    console.print(f"move-to-frame   p50 {percentile(figures.frame_ms, 50):7.1f} ms   "
                  f"p99 {percentile(figures.frame_ms, 99):7.1f} ms   ({len(figures.frame_ms)} moves)")
    console.print(f"events committed {committed / window:7.1f} /s   ({committed} events)")


if __name__ == "__main__":
    main()
