"""The virtual rover's lab: `robotslang serve` as a process with the trial's services beside it, the
software rover (`robotslang robot virtual`) as more processes, and waits on the rover's truth file.
Tests take a lab from conftest's `lab` or `start_lab`."""

from __future__ import annotations

import asyncio
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from app.rover.virtual.truth import TruthSample, read_truth
from bench.live import REPO
from tests.app.live import PlatformProcess, cli

MAZE = "gen-000"
TARGETS = ("jar", "mug", "paddle")  # the rover trials' targets, in visiting order
START_S = 60.0  # bound on waits that include starting a process (seconds when the machine is idle)


class Lab:
    """A server process (started here), the trial's services beside it, rovers and the command
    line on the server's settings; its files under `tmp_path`."""

    def __init__(self, tmp_path: Path, server: PlatformProcess) -> None:
        self.tmp_path = tmp_path
        self.settings = server.settings
        self.env = server.env  # the server's environment: its settings
        self.services = server.services
        self.server = server.start()
        self.rovers: list[subprocess.Popen] = []

    def register(self, name: str, role: str = "driver") -> tuple[int, str]:
        made = cli("robot", "create", name, "--role", role, env=self.env)
        assert made.returncode == 0, made.stderr
        robot_id = int(made.stdout.split("robot:")[1].split()[0]) if role == "driver" else 0
        return robot_id, made.stdout.splitlines()[2]

    def rover(self, token: str, *args: str) -> subprocess.Popen:
        # The child keeps its own copy of the descriptor: this one closes once it has started.
        with open(self.tmp_path / f"rover-{len(self.rovers)}.log", "w") as log:
            proc = subprocess.Popen(
                [
                    sys.executable,
                    "-c",
                    "from app.cli import main; main()",
                    "robot",
                    "virtual",
                    "--server",
                    self.server.url,
                    "--token",
                    token,
                    "--maze",
                    MAZE,
                    *args,
                ],
                env={**os.environ, **self.env},
                cwd=REPO,
                stdout=log,
                stderr=subprocess.STDOUT,
            )
        self.rovers.append(proc)
        return proc

    def close(self) -> None:
        for proc in self.rovers:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        self.server.close()


async def until(predicate, what: str, timeout: float = START_S):
    deadline = time.monotonic() + timeout
    while not (value := predicate()):
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        await asyncio.sleep(0.02)
    return value


def settled(truth: Path) -> list[TruthSample]:
    """The truth at rest: the start, then the end of each pulse."""
    return [s for s in read_truth(truth) if not s.moving] if truth.exists() else []


def turned(a: float, b: float) -> float:
    """Signed angle from heading a to heading b, radians in (-pi, pi]."""
    return (b - a + math.pi) % (2 * math.pi) - math.pi
