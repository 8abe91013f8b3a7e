"""The live simulator seat: landmarks are physical objects, so a claim shows its target."""

from __future__ import annotations

import asyncio
import math

import numpy as np
import pytest

from app.backends.base import Frame
from app.backends.sim import SimulatorBackend
from app.clock import ServerClock
from app.mazes import Mazes
from app.settings import Settings
from sim.core.dynamics import Action, Pose, teacher_action
from sim.core.geometry import heading_angle, heading_index
from sim.core.labels import OBJECTS, Label
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable, cast_rays, too_close
from tests.app.trial_play import object_pixels

MAZE = "gen-000"


def drive(maze, graph, start: Pose, actions) -> tuple[list[str], list[Frame], list[Pose]]:
    """Play `actions` on the seat's backend; the outcomes, every camera frame and every pose."""

    async def play():
        backend = SimulatorBackend(maze, graph, RayTable.build(maze, graph, use_cache=False), start, ServerClock())
        await backend.connect()
        poses, outcomes = [backend.grid_pose], []
        for a in actions:
            outcomes.append((await backend.execute(a.word)).outcome)
            poses.append(backend.grid_pose)
        await backend.close()
        return outcomes, [f async for f in backend.frames()], poses

    return asyncio.run(play())


def approach(maze, graph: NavGraph, target: str) -> tuple[Pose, list[Action]]:
    """From the seat's start pose, the teacher's moves to the target's node, then a turn to
    face the object and a forward move into it: what a Driver does before claiming."""
    goal = graph.nearest_node(*maze.objects[target])
    far = np.flatnonzero(np.isfinite(graph.dist[:, goal]) & (graph.dist[:, goal] > 0.6))
    start = pose = Pose(int(far[0]), 0)
    actions = []
    while (a := teacher_action(graph, pose, goal)) != Action.STOP:
        actions.append(a)
        pose, _ = graph.moves.step(pose, a)
    (x, y), (ox, oy) = graph.nodes[goal], maze.objects[target]
    facing = heading_index(math.atan2(oy - y, ox - x))
    turn = (facing - pose.heading) % 8
    actions += [Action.LEFT] * turn if turn <= 4 else [Action.RIGHT] * (8 - turn)
    return start, actions + [Action.FORWARD]


@pytest.fixture(scope="module")
def mazes(tmp_path_factory):
    return Mazes(Settings(data_dir=tmp_path_factory.mktemp("data"), cache_dir=tmp_path_factory.mktemp("cache")))


@pytest.mark.parametrize("target", OBJECTS)
def test_a_move_into_a_landmark_is_a_collision_and_the_claim_frame_shows_it(mazes, target):
    maze, graph = mazes.load(MAZE), mazes.graph(MAZE)
    start, actions = approach(maze, graph, target)
    outcomes, frames, _ = drive(maze, graph, start, actions)
    assert outcomes[-1] == "collision"
    assert set(outcomes[:-1]) == {"ok"}
    assert object_pixels(frames[-1].jpeg, Label[target.upper()]) > 300


def test_each_frame_carries_the_rays_cast_at_its_pose(mazes):
    # The observation is looked up in the maze's ray table: it must be what the caster sees there.
    maze, graph = mazes.load(MAZE), mazes.graph(MAZE)
    start, actions = approach(maze, graph, "jar")
    _, frames, poses = drive(maze, graph, start, actions)
    assert len(frames) == len(poses) > 5
    for frame, pose in zip(frames, poses, strict=True):
        x, y = graph.nodes[pose.node]
        labels, depth = cast_rays(maze, float(x), float(y), float(heading_angle(pose.heading)))
        obs = frame.observation
        np.testing.assert_array_equal(obs.labels, labels)
        np.testing.assert_allclose(obs.depth, depth, atol=1e-6)
        np.testing.assert_array_equal(obs.too_close, too_close(depth, pose.heading))
        assert obs.forward_blocked == (graph.forward[pose.node, pose.heading] < 0)


def test_on_the_benchmarks_walls_only_graph_the_robot_drives_into_the_landmark(mazes):
    # The same approach on the graph the metrics use: the object is walkable, the move is not a
    # collision, and the robot ends inside the object, facing the wall behind it.
    maze = mazes.load(MAZE)
    graph = NavGraph.build(maze, cache_dir=mazes.settings.cache_dir)
    start, actions = approach(maze, graph, "mug")
    outcomes, frames, _ = drive(maze, graph, start, actions)
    assert outcomes[-1] == "ok"
    assert object_pixels(frames[-1].jpeg, Label.MUG) < 50
