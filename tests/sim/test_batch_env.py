"""BatchNavEnv: a batch of episodes over several real mazes behaves as the single-step dynamics."""

from __future__ import annotations

import numpy as np
import pytest

from sim.batch_env import BatchNavEnv
from sim.benchmark import MAX_EPISODE_ACTIONS, Benchmark, episode_start, goal_node
from sim.dynamics import Action, Pose, step, teacher_actions
from sim.library import MazeLibrary
from sim.metrics import score_trajectory
from sim.navgraph import NavGraph
from sim.observations import RayTable

RUNS = ("Run_318", "Run_114", "Run_135", "Run_345")


@pytest.fixture(scope="module")
def worlds(benchmark_path):
    bench = Benchmark(benchmark_path)
    out = []
    for run in RUNS:
        graph = bench.graph(run)
        out.append((graph, RayTable.build(bench.maze(run), graph)))
    return out


def random_episodes(worlds, count, seed):
    rng = np.random.default_rng(seed)
    episodes = []
    for w in rng.integers(len(worlds), size=count):
        graph = worlds[w][0]
        episodes.append((graph, Pose(int(rng.integers(graph.n)), int(rng.integers(8))),
                         int(rng.integers(graph.n))))
    return episodes


@pytest.fixture(scope="module")
def bundled_worlds():
    library = MazeLibrary()
    out = []
    for name in library.names()[:3]:
        maze = library.load(name)
        graph = NavGraph.build(maze)
        out.append((graph, RayTable.build(maze, graph)))
    return out


def test_agrees_step_by_step_with_the_dynamics(worlds):
    check_agreement(worlds)


def test_agrees_step_by_step_on_the_bundled_mazes(bundled_worlds):
    check_agreement(bundled_worlds)


def check_agreement(worlds):
    env = BatchNavEnv(worlds, max_actions=1000)
    episodes = random_episodes(worlds, 200, seed=0)
    obs = env.reset(episodes)
    poses = [pose for _, pose, _ in episodes]
    features = [rays.features() for _, rays in worlds]
    world_of = {id(g): k for k, (g, _) in enumerate(worlds)}
    rng = np.random.default_rng(1)
    collisions = 0
    for t in range(60):
        # Mostly forward, so that walls are met and collisions happen.
        actions = rng.choice(3, size=len(episodes), p=[0.6, 0.2, 0.2])
        obs, collided, done = env.step(actions)
        for k, (graph, _, goal) in enumerate(episodes):
            poses[k], hit = step(graph, poses[k], Action(int(actions[k])))
            assert collided[k] == hit
            assert np.array_equal(obs[k], features[world_of[id(graph)]][poses[k].node, poses[k].heading])
            assert env.td[k] == graph.dist[poses[k].node, goal]
        collisions += int(collided.sum())
        assert env.poses() == poses and not done.any()
    assert collisions > 0
    assert np.array_equal(env.steps, np.full(len(episodes), 60))


def test_teacher_matches_the_single_pose_teacher(worlds):
    env = BatchNavEnv(worlds)
    episodes = random_episodes(worlds, 300, seed=2)
    env.reset(episodes)
    expected = [int(teacher_actions(g, [p.node], [p.heading], [goal])[0]) for g, p, goal in episodes]
    assert env.teacher_actions().tolist() == expected


def test_teacher_rollouts_reach_the_goal_on_benchmark_episodes(benchmark_path, worlds):
    bench = Benchmark(benchmark_path)
    by_run = {run: worlds[k][0] for k, run in enumerate(RUNS)}
    episodes = []
    for split in ("train", "val_seen", "test"):
        for inst in bench.split(split):
            if inst.run in by_run:
                graph = by_run[inst.run]
                episodes.append((graph, episode_start(graph, inst), goal_node(graph, inst)))
    assert len(episodes) >= 10
    env = BatchNavEnv(worlds)
    env.reset(episodes)
    while not env.done.all():
        env.step(env.teacher_actions())
    shortest_fits = np.array([len(teacher_path_actions(g, p, goal)) <= MAX_EPISODE_ACTIONS
                              for g, p, goal in episodes])
    assert shortest_fits.any()
    assert np.all(env.td[shortest_fits] == 0) and np.all(env.stopped[shortest_fits])
    assert np.all(env.local_node[shortest_fits] == env.goal[shortest_fits])


def teacher_path_actions(graph, pose, goal):
    """The single-pose teacher's actions from `pose` until it stops (bounded)."""
    actions = []
    for _ in range(4 * MAX_EPISODE_ACTIONS):
        a = Action(int(teacher_actions(graph, [pose.node], [pose.heading], [goal])[0]))
        if a == Action.STOP:
            break
        actions.append(a)
        pose, _ = step(graph, pose, a)
    return actions


def test_bookkeeping_matches_the_metrics(worlds):
    env = BatchNavEnv(worlds, max_actions=40)
    episodes = random_episodes(worlds, 100, seed=3)
    env.reset(episodes)
    rng = np.random.default_rng(4)
    for _ in range(45):
        actions = rng.choice(4, size=len(episodes), p=[0.6, 0.17, 0.17, 0.06])
        env.step(actions)
    assert env.done.all() and env.stopped.any() and not env.stopped.all()
    assert np.all(env.steps[~env.stopped] == 40) and np.all(env.steps <= 40)
    for k, nodes in enumerate(env.trajectories()):
        graph, pose, goal = episodes[k]
        assert nodes[0] == pose.node and len(nodes) == env.steps[k] + 1
        score = score_trajectory(graph, nodes, goal)
        assert env.td[k] == score.td
        assert env.otd[k] == score.otd
        assert env.path_length[k] == pytest.approx(score.path_length, abs=1e-12)
        assert env.shortest[k] == score.shortest


def test_finished_episodes_ignore_actions(worlds):
    env = BatchNavEnv(worlds, max_actions=5)
    episodes = random_episodes(worlds, 4, seed=5)
    env.reset(episodes)
    obs, _, done = env.step(np.array([Action.STOP, Action.LEFT, Action.LEFT, Action.LEFT]))
    assert done.tolist() == [True, False, False, False]
    frozen = (env.node[0], env.heading[0], obs[0].copy())
    for _ in range(10):
        obs, collided, done = env.step(np.zeros(4, dtype=np.int64))
        assert (env.node[0], env.heading[0]) == frozen[:2] and np.array_equal(obs[0], frozen[2])
        assert not collided[0]
    assert done.all() and env.steps.tolist() == [0, 5, 5, 5]


def test_bad_input_is_named(worlds, benchmark_path):
    env = BatchNavEnv(worlds[:1])
    graph = worlds[0][0]
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros(1, dtype=np.int64))
    with pytest.raises(ValueError, match="not added"):
        env.reset([(worlds[1][0], Pose(0, 0), 0)])
    with pytest.raises(ValueError, match="episode 0"):
        env.reset([(graph, Pose(graph.n, 0), 0)])
    env.reset([(graph, Pose(0, 0), 1)])
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(2, dtype=np.int64))
    with pytest.raises(ValueError, match="0 forward"):
        env.step(np.array([5]))
    with pytest.raises(ValueError, match="nodes but the graph"):
        env.add(worlds[1][0], worlds[0][1])
