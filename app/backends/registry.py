"""Which backend fills a trial's robot seat, by the trial's `backend` spec.

`sim` registers here; the rover registers `robot` (spec `robot:<id>`) with `register_backend`.
A factory gets the spec and the trial's runtime (state, services, settings) and returns a
`RobotBackend` that is not yet connected.
"""

from __future__ import annotations

import asyncio
import importlib
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING

from app.backends.base import RobotBackend

if TYPE_CHECKING:
    from app.trial.runtime import TrialRuntime

BackendFactory = Callable[[str, "TrialRuntime"], Awaitable[RobotBackend]]

_FACTORIES: dict[str, BackendFactory] = {}
# Modules that register a backend kind when imported, loaded on the first trial of that kind.
PLUGINS = {"robot": "app.backends.remote"}


def register_backend(kind: str, factory: BackendFactory) -> None:
    _FACTORIES[kind] = factory


def backend_kinds() -> list[str]:
    return sorted(set(_FACTORIES) | set(PLUGINS))


async def create_backend(spec: str, runtime: "TrialRuntime") -> RobotBackend:
    kind = spec.split(":", 1)[0]
    if kind not in _FACTORIES and kind in PLUGINS:
        importlib.import_module(PLUGINS[kind])
    if kind not in _FACTORIES:
        raise LookupError(f"unknown robot backend {spec!r}; known kinds: {', '.join(backend_kinds())}")
    return await _FACTORIES[kind](spec, runtime)


async def simulator_backend(spec: str, runtime: "TrialRuntime") -> RobotBackend:
    from app.backends.sim import SimulatorBackend
    from sim.dynamics import snap_pose

    mazes, state = runtime.services.mazes, runtime.state
    # Reading a maze and building its graph take a while: off the loop, other trials keep moving.
    graph = await asyncio.to_thread(mazes.graph, state.maze)
    if state.pose is not None:  # resuming: the robot is where the log last saw it
        start = snap_pose(graph, *state.pose)
    else:
        start = await asyncio.to_thread(mazes.start_pose, state.maze, state.targets[0], runtime.trial_id)
    return SimulatorBackend(mazes.load(state.maze), graph, start, runtime.services.clock)


register_backend("sim", simulator_backend)
