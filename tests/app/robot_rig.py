"""The rover's link end to end: a robot and a trial on it on the test server (in a thread, with
`robotslang serve`'s transport limit), and the rover's real client (`python -m robot_client`) as a
process."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

from sqlalchemy import select

from app.db.models import Event
from app.rover.records import create_robot
from bench.live import team_trial
from robot_client.calibration import Calibration
from tests.app.live import ServerThread, TrialHandle

ROBOT = [sys.executable, "-m", "robot_client"]
CALIBRATION = Calibration(forward_s=0.3, left_s=0.2, right_s=0.25)
WATCHDOG_S = 0.5
ROBOT_START_S = 60.0  # bound on waits that include starting a client process (seconds when idle)


def new_robot_trial(server: ServerThread, name: str, role: str = "driver") -> tuple[int, str, TrialHandle | None]:
    """A robot on `server`, and (for a rover) a trial of a new team on it: (robot id, token, trial)."""
    services = server.services
    with services.db.begin() as db:
        robot, token = create_robot(db, name, role)
        if role != "driver":
            return robot.id, token, None
        trial_id = team_trial(
            db,
            f"{name} team",
            "table",
            ["table"],
            services.clock.now_ns(),
            targets=["jar", "mug", "paddle"],
            backend=f"robot:{robot.id}",
        )
    return robot.id, token, TrialHandle.on(server, trial_id)


def trial_events(server: ServerThread, trial: TrialHandle, kind: str | None = None) -> list[Event]:
    """The trial's events (of `kind`), in order."""
    with server.services.db() as db:
        query = select(Event).where(Event.trial_id == trial.id).order_by(Event.seq)
        return [e for e in db.scalars(query) if kind is None or e.kind == kind]


def robot_status(server: ServerThread, robot_id: int) -> dict:
    return next(r for r in server.services.robots.status() if r["id"] == robot_id)


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
