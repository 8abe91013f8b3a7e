"""Simulated motors and cameras with the interfaces `robot_client` drives.

`VirtualMotors` is what `robot_client.motors.Motors` is to `RobotClient`: `calibration`,
`start(action)`, `stop()`, `running`, `close()`. A pulse moves the `sim.robot.rover.Rover` over the
calibrated pulse length, so the pose at any instant is the part of the move done by then: a
`stop` (the server's, the watchdog's, a shutdown's) leaves the rover part way, exactly as the
client's safety rules cut a real pulse. The cameras are sources for `robot_client`'s
`FrameGrabber` (`read_stamped() -> (BGR, when it was exposed)`, `close()`): the front camera
renders through the lens model at the true pose of that instant; the overhead camera renders the
table with the rover at the newest pose of the driver rover's truth file.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from app.rover.virtual.truth import SAMPLE_S, TruthFollower, TruthLog, TruthSample
from robot_client.calibration import Calibration
from robot_client.protocol import Move
from sim.core.maze import Maze
from sim.robot.rover import Pulse, Rover, RoverPose

if TYPE_CHECKING:  # the renderers load on first use
    from sim.robot.camera import FrontCamera
    from sim.robot.overhead import OverheadCamera


class VirtualMotors:
    """A rover's motors: each pulse advances the simulated pose over its calibrated duration."""

    def __init__(self, rover: Rover, calibration: Calibration, truth: TruthLog | None = None) -> None:
        self.rover = rover
        self.calibration = calibration
        self._truth = truth
        self._lock = threading.Lock()
        self._pulse: Pulse | None = None
        self._started_ns = 0
        self._duration_ns = 1
        self.moves_started = 0
        self._action: str | None = None  # of the newest pulse, for the truth lines after it
        self._closed = threading.Event()
        self._moving = threading.Event()
        self._record(self.rover.pose, moving=False, collision=False)
        self._sampler = threading.Thread(target=self._sample, name="truth-sampler", daemon=True)
        if truth is not None:
            self._sampler.start()

    @property
    def running(self) -> bool:
        return self._pulse is not None

    def start(self, action: str) -> None:
        move = Move(action)  # ValueError for anything but the three moves, as Motors.start
        with self._lock:
            self._finish(time.monotonic_ns())
            self._pulse = self.rover.plan(move)
            self._started_ns = time.monotonic_ns()
            self._duration_ns = max(1, int(self.calibration.duration(move.value) * 1e9))
            self.moves_started += 1
            self._record(self.rover.pose, moving=True, collision=False)
            self._moving.set()

    def stop(self) -> None:
        with self._lock:
            self._finish(time.monotonic_ns())

    def pose(self) -> RoverPose:
        """The true pose now (part way through a running pulse)."""
        with self._lock:
            if self._pulse is None:
                return self.rover.pose
            return self._pulse.pose_at(self._fraction(time.monotonic_ns()))

    def close(self) -> None:
        self.stop()
        self._closed.set()
        self._moving.set()
        if self._sampler.is_alive():
            self._sampler.join(timeout=2)

    def _fraction(self, now_ns: int) -> float:
        return min(1.0, (now_ns - self._started_ns) / self._duration_ns)

    def _finish(self, now_ns: int) -> None:
        if self._pulse is None:
            return
        result = self.rover.finish(self._pulse, self._fraction(now_ns))
        self._pulse = None
        self._moving.clear()
        self._record(result.pose, moving=False, collision=result.collided)

    def _record(self, pose: RoverPose, moving: bool, collision: bool) -> None:
        if self._truth is not None:
            if self._pulse is not None:
                self._action = self._pulse.move.value
            self._truth.write(
                TruthSample(
                    time.monotonic_ns(), pose.x, pose.y, pose.theta, self.moves_started, self._action, moving, collision
                )
            )

    def _sample(self) -> None:
        """While a pulse runs, the pose every SAMPLE_S: the overhead camera renders from these."""
        while not self._closed.is_set():
            self._moving.wait()
            with self._lock:
                if self._pulse is not None:
                    fraction = self._fraction(time.monotonic_ns())
                    self._record(self._pulse.pose_at(fraction), moving=True, collision=self._pulse.touched_by(fraction))
            self._closed.wait(SAMPLE_S)


class FrontCameraSource:
    """The rover's webcam: `sim.robot.camera.capture` at the true pose of the moment it is read."""

    def __init__(self, maze: Maze, motors: VirtualMotors, camera: FrontCamera, seed: int | None) -> None:
        from sim.robot.camera import capture

        self._capture = capture
        self.maze, self.motors, self.camera = maze, motors, camera
        self._rng = np.random.default_rng(seed)

    def read_stamped(self) -> tuple[np.ndarray, int]:
        # Exposed at the instant of the pose, not when the render is done (tens of ms later).
        t_ns = time.monotonic_ns()
        p = self.motors.pose()
        return self._capture(self.maze, p.x, p.y, p.theta, self.camera, self._rng), t_ns

    def close(self) -> None:
        pass


class OverheadCameraSource:
    """The camera over the table: the driver rover's newest true pose, seen from above.

    The two processes share nothing but the truth file: the driver rover writes it, this
    camera follows it (no rover on the table until it has a first line)."""

    def __init__(self, maze: Maze, truth_path: Path, camera: OverheadCamera, seed: int) -> None:
        from sim.robot.overhead import render_overhead

        self._render = render_overhead
        self.maze, self.camera = maze, camera
        self._truth = TruthFollower(truth_path)
        self._seed, self._count = seed, 0

    def read_stamped(self) -> tuple[np.ndarray, int]:
        # Exposed when the pose was read: a render takes a few hundred ms, and the rover moves
        # on meanwhile, so stamping the finished render would put the picture late.
        t_ns = time.monotonic_ns()
        sample: TruthSample | None = self._truth.poll()
        self._count += 1
        pose = None if sample is None else (sample.x, sample.y, sample.theta)
        return self._render(self.maze, pose, self.camera, seed=self._seed * 1_000_003 + self._count), t_ns

    def close(self) -> None:
        self._truth.close()
