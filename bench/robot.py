"""The rover's camera path on loopback: `python -m bench.robot [--seconds S] [--fps F ...]`.

Starts `robotslang serve` and a `robotslang-robot` process (synthetic camera at 640x480, mock
motors) as separate processes, joins a trial on that robot as Commander and Driver, and measures
at the Driver's socket what a browser would get: frames per second delivered, and the latency
added between the camera's capture and the Driver receiving the frame (median and 95th
percentile). It checks that the event log holds a `frame` event for every frame delivered.
Target: at least 15 frames per second with under 150 ms added latency.

Latency needs no clock sync: server, rover and this process share the machine's clocks; the
server stamps with monotonic time offset to wall time, which `time.time_ns()` reads here.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import websockets
from rich.console import Console
from rich.table import Table
from sqlalchemy import func, select
from tqdm import tqdm

from app.db.engine import make_engine, make_sessionmaker, upgrade
from app.db.models import Event
from app.rover.records import create_robot
from app.security import SeatTokens
from app.settings import Settings
from bench.live import free_port, team_trial

REPO = Path(__file__).resolve().parent.parent
SECRET = "bench-robot"
TARGET_FPS, TARGET_LATENCY_MS = 15.0, 150.0


def prepare(settings: Settings, runs: int) -> list[tuple[str, int]]:
    """A rover and a trial on it per run: (robot token, trial id)."""
    engine = make_engine(settings)
    upgrade(settings, engine)
    db = make_sessionmaker(engine)
    runs_made = []
    for run in range(runs):
        with db.begin() as session:
            robot, token = create_robot(session, f"bench rover {run}")
            trial_id = team_trial(
                session,
                f"team {run}",
                "table",
                ["table"],
                time.time_ns(),
                targets=["jar", "mug", "paddle"],
                backend=f"robot:{robot.id}",
            )
            runs_made.append((token, trial_id))
    engine.dispose()
    return runs_made


def start_server(env: dict, port: int) -> subprocess.Popen:
    proc = subprocess.Popen(
        [sys.executable, "-c", "from app.cli import main; main()", "serve", "--port", str(port)],
        env=env,
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.time() + 60
    while time.time() < deadline:
        if proc.poll() is not None:
            raise SystemExit(f"server exited: {proc.stderr.read()}")
        try:
            httpx.get(f"http://127.0.0.1:{port}/", timeout=1)
            return proc
        except httpx.HTTPError:
            time.sleep(0.2)
    raise SystemExit("server did not start within 60 s")


async def measure(port: int, trial_id: int, seats: SeatTokens, seconds: float) -> tuple[list[float], float, float]:
    """Added latencies (ms) of the frames the Driver received in `seconds`, the frame rate and the
    mean JPEG size (KB)."""
    url = f"ws://127.0.0.1:{port}/ws/play?token="
    async with (
        websockets.connect(url + seats.issue(trial_id, "commander")),
        websockets.connect(url + seats.issue(trial_id, "driver"), max_size=2**24) as driver,
    ):
        latencies: list[float] = []
        jpeg_bytes = 0
        first_ns = last_ns = None
        deadline = time.monotonic() + seconds + 30  # includes waiting for the robot to connect
        with tqdm(total=int(seconds), desc="frames at the Driver", unit="s", leave=False) as bar:
            while time.monotonic() < deadline:
                message = json.loads(await asyncio.wait_for(driver.recv(), 30))
                received_ns = time.time_ns()
                if message.get("kind") != "frame" or "jpeg" not in message:
                    continue
                if first_ns is None:  # the clock starts at the first frame: startup is not measured
                    first_ns = received_ns
                    deadline = time.monotonic() + seconds
                    continue
                latencies.append((received_ns - message["payload"]["capture_ns"]) / 1e6)
                jpeg_bytes += len(message["jpeg"]) * 3 // 4
                last_ns = received_ns
                elapsed = min(int((received_ns - first_ns) / 1e9), int(seconds))
                if elapsed > bar.n:
                    bar.update(elapsed - bar.n)
        fps = len(latencies) / ((last_ns - first_ns) / 1e9) if latencies else 0.0
        return latencies, fps, jpeg_bytes / max(1, len(latencies)) / 1000


def logged_frames(settings: Settings, trial_id: int) -> int:
    engine = make_engine(settings)
    with make_sessionmaker(engine)() as db:
        count = db.scalar(
            select(func.count()).select_from(Event).where(Event.trial_id == trial_id, Event.kind == "frame")
        )
    engine.dispose()
    return count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="measuring time per camera rate")
    parser.add_argument("--fps", type=float, nargs="+", default=[15.0, 30.0], help="camera rates to try")
    parser.add_argument("--quality", type=int, default=80)
    parser.add_argument("--camera", default="synthetic", help="synthetic, or a video file for real-looking JPEGs")
    args = parser.parse_args()

    console = Console(width=100)
    with tempfile.TemporaryDirectory(prefix="bench-robot-") as tmp:
        settings = Settings(data_dir=Path(tmp) / "var", secret_key=SECRET, database_url=None)
        runs = prepare(settings, len(args.fps))
        port = free_port()
        env = {**os.environ, "ROBOTSLANG_DATA_DIR": str(settings.data_dir), "ROBOTSLANG_SECRET_KEY": SECRET}
        env.pop("ROBOTSLANG_DATABASE_URL", None)
        server = start_server(env, port)
        rows = []
        try:
            for fps, (token, trial_id) in zip(args.fps, runs):
                robot = subprocess.Popen(
                    [
                        sys.executable,
                        "-m",
                        "robot_client",
                        "--server",
                        f"http://127.0.0.1:{port}",
                        "--token",
                        token,
                        "--camera",
                        args.camera,
                        "--motors",
                        "mock",
                        "--width",
                        "640",
                        "--height",
                        "480",
                        "--fps",
                        str(fps),
                        "--quality",
                        str(args.quality),
                    ],
                    cwd=REPO,
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
                try:
                    console.print(f"camera at {fps:g} fps: measuring {args.seconds:g} s at the Driver's socket")
                    latencies, delivered, kb = asyncio.run(measure(port, trial_id, SeatTokens(SECRET), args.seconds))
                finally:
                    robot.terminate()
                    robot.wait(timeout=10)
                if len(latencies) < 2:
                    raise SystemExit(f"camera at {fps:g} fps: fewer than two frames reached the Driver")
                logged = logged_frames(settings, trial_id)
                p95 = statistics.quantiles(latencies, n=20)[-1]
                rows.append(
                    (fps, kb, delivered, statistics.median(latencies), p95, max(latencies), len(latencies), logged)
                )
        finally:
            server.terminate()
            server.wait(timeout=10)

    table = Table(title="Rover camera -> Driver socket, 640x480 JPEG, loopback")
    for column in (
        "camera fps",
        "KB/frame",
        "delivered fps",
        "median ms",
        "p95 ms",
        "max ms",
        "frames",
        "logged",
        "target",
    ):
        table.add_column(column, justify="right")
    for fps, kb, delivered, median, p95, worst, received, logged in rows:
        met = delivered >= min(fps, TARGET_FPS) * 0.95 and p95 < TARGET_LATENCY_MS and logged >= received
        table.add_row(
            f"{fps:g}",
            f"{kb:.0f}",
            f"{delivered:.1f}",
            f"{median:.1f}",
            f"{p95:.1f}",
            f"{worst:.1f}",
            str(received),
            str(logged),
            "met" if met else "MISSED",
        )
    console.print(table)
    console.print(
        f"target: >= {TARGET_FPS:g} frames/s with < {TARGET_LATENCY_MS:g} ms added latency (p95), "
        "every delivered frame in the event log"
    )


if __name__ == "__main__":
    main()
