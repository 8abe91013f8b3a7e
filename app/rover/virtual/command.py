"""`robotslang robot virtual`: a software rover (or overhead camera) on the real client's link.

The networking is `robot_client`'s own `RobotClient` and `serve` (hello, pings, acks, RSF1
frames, watchdog, reconnect, exit statuses), so on the wire the software rover is the real
client; only the motors and the camera source are simulated.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from app.rover.virtual.devices import FrontCameraSource, OverheadCameraSource, VirtualMotors
from app.rover.virtual.truth import TruthLog
from robot_client.calibration import Calibration
from robot_client.camera import CameraSettings, FrameGrabber
from robot_client.cli import run as run_client
from robot_client.client import LinkSettings, RobotClient, robot_url
from sim.core.geometry import world_to_pixel
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.robot.rover import BODY_RADIUS_M, MotionNoise, Rover, RoverPose, clearance_map

if TYPE_CHECKING:
    from sim.robot.camera import FrontCamera
    from sim.robot.overhead import OverheadCamera

CAMERA_SOURCE = "virtual"  # the hello's camera.source, where the real client names its camera


@dataclass(frozen=True)
class VirtualRoverSpec:
    server: str
    token: str
    maze: Maze
    role: str = "driver"
    seed: int = 0
    noise: MotionNoise = MotionNoise()
    truth: Path | None = None
    start: RoverPose | None = None
    fps: float = 15.0
    calibration: Calibration = Calibration()
    watchdog_s: float = 0.5


def parse_start(text: str) -> RoverPose:
    """`X,Y,THETA` (metres, metres, radians) -> a pose."""
    try:
        x, y, theta = (float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"expected X,Y,THETA in metres and radians like 0.7,1.05,1.5708, got {text!r}") from None
    if not all(math.isfinite(v) for v in (x, y, theta)):
        raise ValueError(f"X,Y,THETA must be finite numbers, got {text!r}")
    return RoverPose(x, y, theta % (2 * math.pi))


def random_start(maze: Maze, graph: NavGraph, seed: int) -> RoverPose:
    """A navigation-graph node where the rover's body fits, and one of the 8 headings."""
    cols, rows = world_to_pixel(graph.nodes[:, 0], graph.nodes[:, 1])
    clearance = clearance_map(maze)[np.rint(rows).astype(int), np.rint(cols).astype(int)]
    free = np.flatnonzero(clearance >= BODY_RADIUS_M)
    if free.size == 0:
        raise ValueError(f"maze {maze.name!r} has no node where the rover fits; give --start")
    rng = np.random.default_rng(seed)
    x, y = graph.nodes[int(rng.choice(free))]
    return RoverPose(float(x), float(y), float(rng.integers(8)) * math.pi / 4)


def build(spec: VirtualRoverSpec, graph: NavGraph | None = None) -> RobotClient:
    """The real client with simulated devices; raises ValueError naming a bad input."""
    robot_url(spec.server)
    link = LinkSettings(server=spec.server, token=spec.token, role=spec.role, watchdog_s=spec.watchdog_s)
    motors = None
    camera: FrontCamera | OverheadCamera
    source: FrontCameraSource | OverheadCameraSource
    if spec.role == "driver":
        from sim.robot.camera import FrontCamera

        camera = FrontCamera()
        start = spec.start
        if start is None:
            if graph is None:
                raise ValueError("a start pose (--start) or the maze's navigation graph is needed")
            start = random_start(spec.maze, graph, spec.seed)
        rover = Rover(spec.maze, start, spec.noise, seed=spec.seed)
        truth = TruthLog(spec.truth) if spec.truth is not None else None
        motors = VirtualMotors(rover, spec.calibration, truth)
        source = FrontCameraSource(spec.maze, motors, camera, seed=spec.seed)
        p = rover.pose
        logging.getLogger("robotslang.robot").info(
            "virtual rover on %s at (%.3f, %.3f) m, heading %.3f rad", spec.maze.name, p.x, p.y, p.theta
        )
    else:
        from sim.robot.overhead import OverheadCamera

        if spec.truth is None:
            raise ValueError("--role overhead needs --truth FILE: the driver rover's truth file, whose poses it films")
        camera = OverheadCamera()
        source = OverheadCameraSource(spec.maze, spec.truth, camera, seed=spec.seed)
    settings = CameraSettings(camera.width, camera.height, spec.fps)  # the real client's JPEG quality
    return RobotClient(link, FrameGrabber(source, settings), motors, settings.info(CAMERA_SOURCE))


def run(spec: VirtualRoverSpec, graph: NavGraph | None = None) -> int:
    """Serve until a signal (0), a refusal by the server (3) or a camera failure (4)."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    return run_client(build(spec, graph))
