"""Which backend fills a trial's robot seat, by the kind of the trial's `backend` spec: the
simulator (`sim`) or the rover (`robot:<id>`, its module imported on the first rover trial). A
backend gets the trial (as a `RobotTrial`: its state, its seats, its cameras) and `BackendParts`
(what backends use of the server), and is not yet connected.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from sqlalchemy.orm import Session, sessionmaker

from app.backends.base import RobotBackend
from app.backends.render import FrameRenderer
from app.clock import ServerClock
from app.db.models import Robot
from app.mazes import Mazes
from app.trial.port import RobotTrial
from sim.trial.specs import BackendKind, BackendSpec
from sim.trial.vocabulary import Role

if TYPE_CHECKING:
    from app.rover.links import RobotLinks


@dataclass(frozen=True)
class BackendParts:
    """What the backends use of the server: the simulator its mazes, clock and renderer; the
    rover the robots' records, their links and the overhead camera's calibration."""

    mazes: Mazes
    clock: ServerClock
    renderer: FrameRenderer
    db: sessionmaker[Session]
    robots: RobotLinks
    overhead_calibration: Path | None


async def create_backend(spec: str, trial: RobotTrial, parts: BackendParts) -> RobotBackend:
    parsed = BackendSpec.parse(spec)
    if parsed.kind == BackendKind.SIM:
        return await simulator_backend(trial, parts)
    if parsed.kind == BackendKind.ROBOT:
        return robot_backend(spec, parsed.robot_id, trial, parts)
    raise LookupError(f"unknown robot backend {spec!r}; known kinds: {', '.join(sorted(BackendKind))}")


async def simulator_backend(trial: RobotTrial, parts: BackendParts) -> RobotBackend:
    from app.backends.sim import SimulatorBackend
    from sim.core.dynamics import snap_pose

    mazes, state = parts.mazes, trial.state
    # Reading a maze and its graph take a while: off the loop, other trials keep moving. The maze
    # is prepared first (its decoded maps among what is cached), then held, so that the graph, the
    # rays and the backend read it once: read before, on a fresh install each seat's server thread
    # decoded the PNGs its builder was decoding too.
    await mazes.preparation.ready(state.maze)  # built, if it is not yet, without holding a thread
    maze = await asyncio.to_thread(mazes.load, state.maze)
    graph = await asyncio.to_thread(mazes.graph, state.maze)  # hashes the maze too, off the loop
    parts.renderer.prepare(maze)  # the render process reads its scene while the rest loads here
    if state.pose is not None:  # resuming: the robot is where the log last saw it
        start = snap_pose(graph, *state.pose)
    elif state.start is not None:  # the start the trial was created with
        start = snap_pose(graph, *state.start)
    else:
        start = await asyncio.to_thread(mazes.start_pose, state.maze, state.targets[0], trial.trial_id)
    rays = await asyncio.to_thread(mazes.rays, state.maze)
    return SimulatorBackend(maze, graph, rays, start, parts.clock, parts.renderer)


def robot_backend(spec: str, robot_id: int | None, trial: RobotTrial, parts: BackendParts) -> RobotBackend:
    """`robot:<id>`: the registered driver robot with that id."""
    from app.rover.backend import RemoteRobotBackend

    with parts.db() as db:
        robot = db.get(Robot, robot_id)
    if robot is None:
        raise LookupError(f"robot backend {spec!r}: no robot {robot_id} is registered")
    if robot.role != Role.DRIVER:
        raise LookupError(f"robot backend {spec!r}: robot {robot.name!r} is an {robot.role} camera, not a rover")
    return RemoteRobotBackend(
        robot.id,
        robot.name,
        parts.robots,
        trial,
        parts.overhead_calibration,
        parts.clock.now_ns,
    )
