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
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import websockets
from rich.console import Console
from rich.table import Table
from sqlalchemy import func, select
from tqdm import tqdm

from app.db.models import Event
from app.main import build_services
from app.rover.records import create_robot
from app.settings import Settings
from bench.live import REPO, ServerProcess, settings_env, team_trial
from bench.report import percentile

SECRET = "bench-robot"
TARGET_FPS, TARGET_LATENCY_MS = 15.0, 150.0
COLUMNS = ("camera fps", "KB/frame", "delivered fps", "median ms", "p95 ms", "max ms", "frames", "logged", "target")


def prepare(services, runs: int) -> list[tuple[str, int]]:
    """A rover and a trial on it per run: (robot token, trial id)."""
    runs_made = []
    for run in range(runs):
        with services.db.begin() as db:
            robot, token = create_robot(db, f"bench rover {run}")
            trial_id = team_trial(
                db, f"team {run}", "table", ["table"], time.time_ns(), ("jar", "mug", "paddle"), f"robot:{robot.id}"
            )
        runs_made.append((token, trial_id))
    return runs_made


async def measure(server: ServerProcess, tokens: tuple[str, str], seconds: float) -> tuple[list[float], float, float]:
    """Added latencies (ms) of the frames the Driver received in `seconds`, the frame rate and the
    mean JPEG size (KB)."""
    url = f"{server.ws_url}?token="
    async with (
        websockets.connect(url + tokens[0]),
        websockets.connect(url + tokens[1], max_size=2**24) as driver,
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
        services = build_services(settings)
        runs = prepare(services, len(args.fps))
        server = ServerProcess(settings_env(settings)).start()
        rows = []
        try:
            for fps, (token, trial_id) in zip(args.fps, runs):
                robot = subprocess.Popen(
                    [sys.executable, "-m", "robot_client", "--server", server.url, "--token", token]
                    + ["--camera", args.camera, "--motors", "mock", "--width", "640", "--height", "480"]
                    + ["--fps", str(fps), "--quality", str(args.quality)],
                    cwd=REPO,
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
                try:
                    console.print(f"camera at {fps:g} fps: measuring {args.seconds:g} s at the Driver's socket")
                    seats = tuple(services.seats.issue(trial_id, role) for role in ("commander", "driver"))
                    latencies, delivered, kb = asyncio.run(measure(server, seats, args.seconds))
                finally:
                    robot.terminate()
                    robot.wait(timeout=10)
                if len(latencies) < 2:
                    raise SystemExit(f"camera at {fps:g} fps: fewer than two frames reached the Driver")
                with services.db() as db:
                    logged = db.scalar(
                        select(func.count(Event.id)).where(Event.trial_id == trial_id, Event.kind == "frame")
                    )
                ms = [percentile(latencies, 50), percentile(latencies, 95), max(latencies)]
                rows.append((fps, kb, delivered, *ms, len(latencies), logged))
        finally:
            server.stop()
            services.engine.dispose()

    table = Table(title="Rover camera -> Driver socket, 640x480 JPEG, loopback")
    for column in COLUMNS:
        table.add_column(column, justify="right")
    for fps, kb, delivered, median, p95, worst, received, logged in rows:
        met = delivered >= min(fps, TARGET_FPS) * 0.95 and p95 < TARGET_LATENCY_MS and logged >= received
        ms = (f"{v:.1f}" for v in (delivered, median, p95, worst))
        table.add_row(f"{fps:g}", f"{kb:.0f}", *ms, str(received), str(logged), "met" if met else "MISSED")
    console.print(table)
    console.print(
        f"target: >= {TARGET_FPS:g} frames/s with < {TARGET_LATENCY_MS:g} ms added latency (p95), "
        "every delivered frame in the event log"
    )


if __name__ == "__main__":
    main()
