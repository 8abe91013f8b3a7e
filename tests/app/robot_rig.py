"""The rover's link end to end: the server in a thread with `robotslang serve`'s transport limit,
and the rover's real client (`python -m robot_client`) as a process."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import uvicorn
from sqlalchemy import select

from app.db.models import Event
from app.main import create_app
from app.rover.records import create_robot
from app.serving import uvicorn_options
from bench.live import SeatClient, free_port, team_trial
from robot_client.calibration import Calibration

ROBOT = [sys.executable, "-m", "robot_client"]
CALIBRATION = Calibration(forward_s=0.3, left_s=0.2, right_s=0.25)
WATCHDOG_S = 0.5
ROBOT_START_S = 60.0  # bound on waits that include starting a client process (seconds when idle)


class RobotServer:
    """`create_app` under uvicorn in a thread, with the transport limit `robotslang serve` uses."""

    def __init__(self, settings) -> None:
        self.app = create_app(settings)
        self.services = self.app.state.services
        self.port = free_port()
        config = uvicorn.Config(
            self.app, host="127.0.0.1", port=self.port, log_level="warning", lifespan="on", **uvicorn_options(settings)
        )
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, daemon=True)
        self.thread.start()
        deadline = time.time() + 20
        while not self.server.started:
            assert time.time() < deadline and self.thread.is_alive(), "test server did not start"
            time.sleep(0.02)

    url = property(lambda self: f"http://127.0.0.1:{self.port}")
    play_url = property(lambda self: f"ws://127.0.0.1:{self.port}/ws/play")

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=20)
        self.services.engine.dispose()

    def new_robot_trial(self, name: str, role: str = "driver") -> tuple[int, str, int | None]:
        """A robot, and (for a rover) a trial of a new team on it: (robot id, token, trial id)."""
        with self.services.db.begin() as db:
            robot, token = create_robot(db, name, role)
            if role != "driver":
                return robot.id, token, None
            trial_id = team_trial(
                db,
                f"{name} team",
                "table",
                ["table"],
                self.services.clock.now_ns(),
                targets=["jar", "mug", "paddle"],
                backend=f"robot:{robot.id}",
            )
            return robot.id, token, trial_id

    def seat(self, trial_id: int, role: str) -> SeatClient:
        return SeatClient(self.play_url, self.services.seats.issue(trial_id, role))

    def events(self, trial_id: int, kind: str | None = None) -> list[Event]:
        with self.services.db() as db:
            query = select(Event).where(Event.trial_id == trial_id).order_by(Event.seq)
            return [e for e in db.scalars(query) if kind is None or e.kind == kind]

    def status(self, robot_id: int) -> dict:
        return next(r for r in self.services.robots.status() if r["id"] == robot_id)


class RobotProcess:
    """`robotslang-robot` as a separate process with mock motors writing a pin log."""

    def __init__(
        self,
        tmp_path: Path,
        url: str,
        token: str,
        role: str = "driver",
        calibration: Calibration = CALIBRATION,
        fps: float = 15,
    ) -> None:
        self.pins = tmp_path / f"pins-{time.monotonic_ns()}.jsonl"
        cal = tmp_path / "calibration.json"
        calibration.save(cal)
        self.proc = subprocess.Popen(
            ROBOT
            + [
                "--server",
                url,
                "--token",
                token,
                "--role",
                role,
                "--camera",
                "synthetic",
                "--motors",
                "mock",
                "--calibration",
                str(cal),
                "--pin-log",
                str(self.pins),
                "--fps",
                str(fps),
                "--width",
                "320",
                "--height",
                "240",
                "--watchdog",
                str(WATCHDOG_S),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )

    def pin_log(self) -> list[dict]:
        if not self.pins.exists():
            return []
        return [json.loads(line) for line in self.pins.read_text().splitlines()]

    def stop(self) -> str:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            _, err = self.proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            _, err = self.proc.communicate()
        return err
