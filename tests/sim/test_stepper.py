"""The simulator core, BatchStepper, held step for step against the reference rules."""

from __future__ import annotations

import numpy as np
import pytest

from sim.core.dynamics import Action, Pose, teacher_actions
from sim.core.metrics import score_trajectory
from sim.core.navgraph import NavGraph
from sim.core.stepper import MAX_EPISODE_ACTIONS, BatchStepper
from sim.core.world import World, goal_rows
from sim.tasks.benchmark import Benchmark, episode_start, goal_node
from sim.tasks.library import MazeLibrary
from tests.sim.helpers import reference_step

RUNS = ("Run_318", "Run_114", "Run_135", "Run_345")


def compile_world(bench, runs, observations=True):
    return World.compile([(r, bench.maze(r), bench.graph(r)) for r in runs], observations=observations)


@pytest.fixture(scope="module")
def bench(benchmark_path):
    return Benchmark(benchmark_path)


@pytest.fixture(scope="module")
def world(bench):
    return compile_world(bench, RUNS)


def random_episodes(world, graphs, count, seed):
    """(maze index, Pose, goal node) triples, local to their maze."""
    rng = np.random.default_rng(seed)
    out = []
    for m in rng.integers(len(graphs), size=count):
        n = graphs[m].n
        out.append((int(m), Pose(int(rng.integers(n)), int(rng.integers(8))), int(rng.integers(n))))
    return out


def start(stepper, graphs, episodes):
    world = stepper.world
    for k, (m, pose, goal) in enumerate(episodes):
        dist, hop = goal_rows(graphs[m], [goal])
        off = world.offset[m]
        stepper.start([k], [off + pose.node], [pose.heading], [off + goal], dist, hop)


def check_agreement(world, graphs, count=200, steps=60, observations=True):
    stepper = BatchStepper(world, count, max_actions=1000)
    episodes = random_episodes(world, graphs, count, seed=0)
    start(stepper, graphs, episodes)
    poses = [pose for _, pose, _ in episodes]
    rng = np.random.default_rng(1)
    collisions = 0
    for _ in range(steps):
        actions = rng.choice(3, size=count, p=[0.6, 0.2, 0.2])  # mostly forward: walls are met
        collided = stepper.step(actions)
        obs = stepper.observations() if observations else None
        blocked = stepper.forward_blocked()
        for k, (m, _, goal) in enumerate(episodes):
            poses[k], hit = reference_step(graphs[m], poses[k], Action(int(actions[k])))
            assert collided[k] == hit
            assert blocked[k] == reference_step(graphs[m], poses[k], Action.FORWARD)[1]
            assert stepper.node[k] - world.offset[m] == poses[k].node and stepper.heading[k] == poses[k].heading
            assert stepper.td[k] == graphs[m].dist[poses[k].node, goal]
            if observations:
                assert np.array_equal(obs[k], world.obs[(world.offset[m] + poses[k].node) * 8 + poses[k].heading])
        collisions += int(collided.sum())
        assert not stepper.done.any()
    assert collisions > 0
    assert np.array_equal(stepper.steps, np.full(count, steps))


def test_agrees_step_by_step_with_the_reference_and_the_ray_tables(bench, world):
    from sim.core.observations import RayTable

    check_agreement(world, [bench.graph(r) for r in RUNS])
    for m, run in enumerate(RUNS):  # the world's rows are the ray tables' features
        rows = world.obs[world.offset[m] * 8 : (world.offset[m] + world.size[m]) * 8]
        assert np.array_equal(rows, RayTable.build(bench.maze(run), bench.graph(run)).features().reshape(len(rows), -1))


@pytest.mark.slow
def test_agrees_step_by_step_on_every_benchmark_map(bench):
    runs = bench.runs()
    world = compile_world(bench, runs, observations=False)
    check_agreement(world, [bench.graph(r) for r in runs], count=600, steps=40, observations=False)


def test_agrees_step_by_step_on_the_bundled_mazes():
    library = MazeLibrary()
    items = [(n, library.load(n), NavGraph.build(library.load(n))) for n in library.names()[:3]]
    check_agreement(World.compile(items), [g for _, _, g in items])


def test_a_worlds_moves_are_its_mazes_moves(bench, world):
    """One compile of the rules: the world's table over the global node space is each graph's,
    its slots shifted by the maze's offset, the same collisions and metres."""
    for m, run in enumerate(RUNS):
        mine = bench.graph(run).moves
        rows = slice(world.offset[m] * 8 * 4, (world.offset[m] + world.size[m]) * 8 * 4)
        theirs = world.moves.table[rows]
        assert np.array_equal(theirs >> 6, (mine.table >> 6) + world.offset[m] * 8)
        assert np.array_equal(theirs & 1, mine.table & 1)
        assert np.array_equal(world.moves.lengths[theirs >> 1 & 31], mine.lengths[mine.table >> 1 & 31])


def test_the_cached_world_steps_as_the_compiled_one(bench, tmp_path):
    runs = list(RUNS[:2])
    built = World.build(bench, runs, cache_dir=tmp_path, observations=False, progress=False)
    loaded = World.build(bench, runs, cache_dir=tmp_path, observations=False, progress=False)
    assert isinstance(loaded.moves.table, np.memmap)  # read from the cache, not compiled again
    compiled = compile_world(bench, runs, observations=False).moves
    for moves in (built.moves, loaded.moves):
        assert np.array_equal(moves.table, compiled.table) and np.array_equal(moves.lengths, compiled.lengths)
    check_agreement(loaded, [bench.graph(r) for r in runs], count=50, steps=20, observations=False)


def test_teacher_matches_the_single_pose_teacher(bench, world):
    graphs = [bench.graph(r) for r in RUNS]
    stepper = BatchStepper(world, 300)
    episodes = random_episodes(world, graphs, 300, seed=2)
    start(stepper, graphs, episodes)
    expected = [int(teacher_actions(graphs[m], [p.node], [p.heading], [g])[0]) for m, p, g in episodes]
    assert stepper.teacher_actions().tolist() == expected


def test_teacher_rollouts_reach_the_goal_on_benchmark_episodes(bench, world):
    graphs = [bench.graph(r) for r in RUNS]
    episodes = [
        (m, episode_start(graphs[m], inst), goal_node(graphs[m], inst))
        for split in ("train", "val_seen", "test")
        for inst in bench.split(split)
        if inst.run in RUNS
        for m in [RUNS.index(inst.run)]
    ]
    assert len(episodes) >= 10
    stepper = BatchStepper(world, len(episodes))
    start(stepper, graphs, episodes)
    while not stepper.done.all():
        stepper.step(stepper.teacher_actions())
    fits = np.array(
        [
            graphs[m].dist[p.node, g] < np.inf and len(graphs[m].path(p.node, g)) <= MAX_EPISODE_ACTIONS // 3
            for m, p, g in episodes
        ]
    )
    assert fits.any()
    assert np.all(stepper.td[fits] == 0) and np.all(stepper.stopped[fits])
    assert np.all(stepper.node[fits] == stepper.goal[fits])


def test_bookkeeping_matches_the_metrics(bench, world):
    graphs = [bench.graph(r) for r in RUNS]
    stepper = BatchStepper(world, 100, max_actions=40, record=True)
    episodes = random_episodes(world, graphs, 100, seed=3)
    start(stepper, graphs, episodes)
    rng = np.random.default_rng(4)
    for _ in range(45):
        stepper.step(rng.choice(4, size=100, p=[0.6, 0.17, 0.17, 0.06]))
    assert stepper.done.all() and stepper.stopped.any() and not stepper.stopped.all()
    assert np.all(stepper.steps[~stepper.stopped] == 40) and np.all(stepper.steps <= 40)
    for k, nodes in enumerate(stepper.trajectories()):
        m, pose, goal = episodes[k]
        local = np.array(nodes) - world.offset[m]
        assert local[0] == pose.node and len(local) == stepper.steps[k] + 1
        score = score_trajectory(graphs[m], local, goal)
        assert stepper.td[k] == score.td and stepper.otd[k] == score.otd
        assert stepper.path_length[k] == pytest.approx(score.path_length, abs=1e-12)
        assert stepper.shortest[k] == score.shortest


def test_finished_episodes_ignore_actions(bench, world):
    graphs = [bench.graph(r) for r in RUNS]
    stepper = BatchStepper(world, 4, max_actions=5)
    start(stepper, graphs, random_episodes(world, graphs, 4, seed=5))
    stepper.step(np.array([Action.STOP, Action.LEFT, Action.LEFT, Action.LEFT]))
    assert stepper.done.tolist() == [True, False, False, False]
    frozen = int(stepper.slot[0])
    for _ in range(10):
        collided = stepper.step(np.zeros(4, dtype=np.int64))
        assert stepper.slot[0] == frozen and not collided[0]
    assert stepper.done.all() and stepper.steps.tolist() == [0, 5, 5, 5]
    assert stepper.stopped.tolist() == [True, False, False, False]  # the others ran out of moves


def test_bad_input_is_named(world):
    stepper = BatchStepper(world, 1)
    with pytest.raises(RuntimeError, match="before start"):
        stepper.step(np.zeros(1, dtype=np.int64))
    with pytest.raises(ValueError, match="outside the world"):
        stepper.start([0], [world.nodes], [0], [0], np.zeros((1, 1)), np.zeros((1, 1), dtype=np.int64))
    with pytest.raises(ValueError, match="another maze"):
        stepper.start([0], [0], [0], [world.offset[1]], np.zeros((1, 1)), np.zeros((1, 1), dtype=np.int64))
    stepper.start([0], [0], [0], [1], np.zeros((1, 2)), np.zeros((1, 2), dtype=np.int64))
    with pytest.raises(ValueError, match="shape"):
        stepper.step(np.zeros(2, dtype=np.int64))
    bad = [np.array([a]) for a in (-1, 4, 5, 7)] + [np.array([2**64 - 1], dtype=np.uint64)]
    for actions in [*bad, np.array([4], dtype=np.uint8), np.array([-1], dtype=np.int32)]:
        with pytest.raises(ValueError, match="0 forward"):
            stepper.step(actions)
    stepper.step(np.array([Action.STOP]))
    for actions in bad:  # a finished episode's action is ignored, but not unchecked
        with pytest.raises(ValueError, match="0 forward"):
            stepper.step(actions)
