"""Fixtures for the platform: settings on a private data directory, on SQLite or PostgreSQL; the
virtual rover's maze, start and lab; a small recorded trial; a tiny learned Driver."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator

import pytest

from app.export.record import TrialRecord
from app.perception.cameras import learned
from sim.core.geometry import heading_angle
from sim.core.navgraph import NavGraph
from sim.robot.camera import FrontCamera
from sim.robot.rover import NOISE_MODELS, Rover, RoverPose
from sim.tasks.benchmark import Benchmark
from sim.tasks.library import MazeLibrary
from tests.app.live import platform_settings
from tests.app.rover_lab import MAZE, Lab
from tests.app.trial_log import trial_record


@pytest.fixture(params=["sqlite", "postgres"])
def any_db_settings(request, tmp_path):
    """Settings on a real SQLite file, then again on the machine's PostgreSQL."""
    if request.param == "sqlite":
        return platform_settings(tmp_path)
    return platform_settings(tmp_path, database_url=request.getfixturevalue("postgres_url"))


@pytest.fixture(scope="module")
def maze():
    return MazeLibrary().load(MAZE)


@pytest.fixture(scope="module")
def start(maze) -> RoverPose:
    """A node and heading with 4 to 8 free steps ahead of an exact rover: room to move, a wall in reach."""
    graph = NavGraph.build(maze, use_cache=False)
    for x, y in graph.nodes:
        for k in range(8):
            pose = RoverPose(float(x), float(y), float(heading_angle(k)))
            try:
                rover = Rover(maze, pose, NOISE_MODELS["none"])
            except ValueError:
                break  # the body does not fit here
            free = 0
            while free < 12 and not rover.move("forward").collided:
                free += 1
            if 4 <= free <= 8:
                return pose
    raise AssertionError(f"no start pose with a wall 4 to 8 steps ahead on {MAZE}")


@pytest.fixture
def start_lab(tmp_path, server_process) -> Iterator[Callable[..., Lab]]:
    """`start_lab(**settings)`: the virtual rover's lab, its server on more settings of its own
    (for the server and the services beside it); closed when the test ends."""
    labs = []

    def start(**settings) -> Lab:
        server = server_process(platform_settings(tmp_path, cache_dir=tmp_path / "cache", **settings))
        labs.append(Lab(tmp_path, server))
        return labs[-1]

    yield start
    for lab in labs:
        lab.close()


@pytest.fixture
def lab(start_lab) -> Lab:
    return start_lab()


@pytest.fixture(scope="module")
def camera_calibration(tmp_path_factory):
    """The software rover's front camera as a lab would calibrate it (learned once per module)."""
    return learned(FrontCamera()).save(tmp_path_factory.mktemp("lab") / "camera_calibration.json")


@pytest.fixture(scope="module")
def stopping_checkpoint(benchmark_path, tmp_path_factory):
    """A tiny real checkpoint taught on episodes that start at their goal, so it stops at once:
    its claims are deterministic, and after a rejection its forced move is the model's own choice."""
    # Imported here: torch takes seconds to load, and only the learned Driver's tests need it.
    from models.data import World
    from models.train import TrainConfig, train

    bench = Benchmark(benchmark_path)
    jars = [i for i in bench.split("train") if len(i.agent_pose) > 2][:4]
    # New scan and index: the episode cache is keyed by them and must not mix these with the originals.
    at_goal = [
        dataclasses.replace(i, inst_idx=100_000 + i.inst_idx, scan=f"{i.scan}@goal", agent_pose=(*i.target_pose, 0.0))
        for i in jars
    ]
    world = World.build(bench, sorted({i.run for i in at_goal}))
    out = tmp_path_factory.mktemp("seq2seq")
    cfg = TrainConfig(feedback="teacher", iters=12, batch=4, lr=1e-2, eval_every=12, max_actions=10)
    train(bench, cfg, out, world=world, progress=False, train_instances=at_goal, eval_instances=at_goal[:1])
    return out / "last.pt"


@pytest.fixture
def record(tmp_path) -> TrialRecord:
    return trial_record(tmp_path)
