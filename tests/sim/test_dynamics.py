"""Agent dynamics: snapping, turns, forward moves, collisions (`graph.moves`, the one stepper,
against the readable reference of the rules) and the teacher."""

from __future__ import annotations

import numpy as np
import pytest

from sim.core.dynamics import Action, Pose, snap_pose, teacher_action
from sim.core.geometry import GRID_STEP_M
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.tasks.benchmark import Benchmark
from sim.tasks.library import MazeLibrary
from tests.sim.helpers import open_table, reference_step, wall_at_x
from tests.sim.reference_baselines import ShortestAgent, run_episode


@pytest.fixture(scope="module")
def walled():
    return NavGraph.build(Maze.from_labels(wall_at_x(open_table(), 1.0), "walled"), use_cache=False)


def test_snap_to_nearest_node_and_45_degrees(walled):
    pose = snap_pose(walled, 0.52, 0.68, np.radians(100))
    assert np.allclose(walled.nodes[pose.node], [0.49, 0.7])
    assert pose.heading == 2  # 100 degrees -> 90
    assert snap_pose(walled, 0.52, 0.68, np.radians(-50)).heading == 7  # -45 degrees


def test_turns_are_counter_clockwise_left(walled):
    pose = Pose(walled.nearest_node(0.5, 0.7), 0)
    left, collided = walled.moves.step(pose, Action.LEFT)
    assert left.heading == 1 and left.node == pose.node and not collided
    assert walled.moves.step(pose, Action.RIGHT)[0].heading == 7


def test_forward_moves_one_grid_step_straight_or_diagonal(walled):
    start = Pose(walled.nearest_node(0.49, 0.7), 0)
    ahead, collided = walled.moves.step(start, Action.FORWARD)
    assert not collided
    assert np.linalg.norm(walled.nodes[ahead.node] - walled.nodes[start.node]) == pytest.approx(GRID_STEP_M)
    diag, _ = walled.moves.step(Pose(start.node, 1), Action.FORWARD)
    assert np.linalg.norm(walled.nodes[diag.node] - walled.nodes[start.node]) == pytest.approx(0.099, abs=1e-3)


def test_forward_into_a_wall_is_a_collision_and_leaves_the_pose(walled):
    # The last column of nodes before the wall at x = 1.0 m, facing it.
    xs = walled.nodes[:, 0]
    edge = walled.nearest_node(xs[xs < 1.0].max(), 1.0)
    pose = Pose(edge, 0)
    after, collided = walled.moves.step(pose, Action.FORWARD)
    assert collided and after == pose and walled.moves.blocked(pose)
    assert not walled.moves.blocked(Pose(edge, 4))


def test_stop_changes_nothing(walled):
    pose = Pose(3, 5)
    assert walled.moves.step(pose, Action.STOP) == (pose, False)


def test_every_move_of_every_pose_is_the_reference_rules(walled, benchmark_path):
    library, bench = MazeLibrary(), Benchmark(benchmark_path)
    graphs = [walled, NavGraph.for_robot(library.load(library.names()[0]))]
    graphs += [bench.graph(run, mode) for run in ("Run_318", "Run_135") for mode in ("benchmark", "exact")]
    for graph in graphs:
        assert graph.moves is graph.moves  # compiled once per graph
        after = graph.moves.after()  # (N * 8, 3): where forward, left and right lead
        collisions = 0
        for node in range(graph.n):
            for heading in range(8):
                for action in Action:
                    pose = Pose(node, heading)
                    expected = reference_step(graph, pose, action)
                    assert graph.moves.step(pose, action) == expected
                    collisions += expected[1]
                    if action != Action.STOP:
                        assert after[node * 8 + heading, action] == expected[0].node * 8 + expected[0].heading
                assert graph.moves.blocked(pose) == reference_step(graph, pose, Action.FORWARD)[1]
        assert collisions > 0


def test_teacher_turns_by_the_smaller_turn_and_stops_at_goal(walled):
    here = walled.nearest_node(0.49, 0.7)
    east = walled.nearest_node(0.49 + 5 * 0.07, 0.7)
    assert teacher_action(walled, Pose(here, 0), east) == Action.FORWARD
    assert teacher_action(walled, Pose(here, 1), east) == Action.RIGHT
    assert teacher_action(walled, Pose(here, 7), east) == Action.LEFT
    assert teacher_action(walled, Pose(here, 3), east) == Action.RIGHT  # 135 degrees left -> turn right
    assert teacher_action(walled, Pose(east, 4), east) == Action.STOP
    across = walled.nearest_node(1.5, 1.0)  # behind the wall: no path
    assert teacher_action(walled, Pose(here, 0), across) == Action.STOP


def test_teacher_reaches_every_goal_within_the_action_limit_when_a_path_allows(benchmark_path):
    bench = Benchmark(benchmark_path)
    rng = np.random.default_rng(1)
    for run in ("Run_318", "Run_135"):
        g = bench.graph(run)
        for start, goal in rng.integers(0, g.n, size=(60, 2)):
            pose = Pose(int(start), int(rng.integers(8)))
            nodes, moves = run_episode(g, pose, int(goal), ShortestAgent(), rng, max_actions=10_000)
            if np.isfinite(g.dist[start, goal]):
                assert nodes[-1] == goal
                if moves <= 120:
                    assert run_episode(g, pose, int(goal), ShortestAgent(), rng)[0][-1] == goal
            else:
                assert moves == 0
