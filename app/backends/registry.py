"""Which backend fills a trial's robot seat, by the trial's `backend` spec.

`sim` registers here; the rover (`robot:<id>`) is found in `PLUGINS` and imported on first use.
A factory gets the spec, the trial (as a `RobotTrial`: its state, its seats, its cameras) and
`BackendParts` (what backends use of the server), and returns a `RobotBackend` that is not yet connected.
"""

from __future__ import annotations

import asyncio
import importlib
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from sqlalchemy.orm import Session, sessionmaker

from app.backends.base import RobotBackend
from app.backends.render import FrameRenderer
from app.clock import ServerClock
from app.mazes import Mazes
from app.trial.port import RobotTrial
from sim.trial.specs import BackendSpec

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


BackendFactory = Callable[[str, RobotTrial, BackendParts], Awaitable[RobotBackend]]

_FACTORIES: dict[str, BackendFactory] = {}
# Backend kinds whose factory ("module:function") is imported on the first trial of that kind.
PLUGINS = {"robot": "app.rover.backend:remote_backend"}


def register_backend(kind: str, factory: BackendFactory) -> None:
    _FACTORIES[kind] = factory


def backend_kinds() -> list[str]:
    return sorted(set(_FACTORIES) | set(PLUGINS))


async def create_backend(spec: str, trial: RobotTrial, parts: BackendParts) -> RobotBackend:
    kind = BackendSpec.parse(spec).kind
    if kind not in _FACTORIES and kind in PLUGINS:
        module, name = PLUGINS[kind].split(":")
        _FACTORIES[kind] = getattr(importlib.import_module(module), name)
    if kind not in _FACTORIES:
        raise LookupError(f"unknown robot backend {spec!r}; known kinds: {', '.join(backend_kinds())}")
    return await _FACTORIES[kind](spec, trial, parts)


async def simulator_backend(spec: str, trial: RobotTrial, parts: BackendParts) -> RobotBackend:
    from app.backends.sim import SimulatorBackend
    from sim.core.dynamics import snap_pose

    mazes, state = parts.mazes, trial.state
    # Reading a maze and its graph take a while: off the loop, other trials keep moving. The maze
    # is held from the start, so that the graph, the rays and the backend read it once.
    maze = await asyncio.to_thread(mazes.load, state.maze)
    await mazes.preparation.ready(state.maze)  # built, if it is not yet, without holding a thread
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


register_backend("sim", simulator_backend)
