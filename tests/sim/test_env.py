"""The Gymnasium environment RobotSlang/NDH-v0: the API contract, episodes and their end."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sim.tasks.env  # noqa: F401  (registers RobotSlang/NDH-v0)
from sim.core.dynamics import Action, Pose, teacher_action
from sim.core.geometry import SUCCESS_RADIUS_M
from sim.core.labels import Label
from sim.core.maze import Maze
from sim.core.observations import OBS_FEATURES, RayTable
from sim.tasks.benchmark import Benchmark, episode_start, goal_node, recorded_start
from sim.tasks.env import ENV_ID, NDHEnv
from tests.sim.helpers import open_table, wall_at_x


@pytest.fixture(scope="module")
def bench(benchmark_path):
    return Benchmark(benchmark_path)


@pytest.fixture(scope="module")
def val_env(bench):
    env = NDHEnv(benchmark=bench, split="val_seen", privileged_info=True)
    yield env
    env.close()


@pytest.fixture(scope="module")
def walled_maze():
    """A table split by a wall with a gap at the top: routes from left to right must detour."""
    labels = wall_at_x(open_table(objects=((0.4, 0.5), (2.0, 0.5), (2.0, 1.6))), 1.2, Label.BLUE, y_range=(0.0, 1.5))
    return Maze.from_labels(labels, "walled")


def _quiet_check_env(env):
    # check_env reports problems as warnings: any warning is a failure here.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped if hasattr(env, "unwrapped") else env)


def test_check_env_passes_on_benchmark_episodes(benchmark_path):
    env = gym.make(ENV_ID, benchmark=benchmark_path, split="val_seen", render_mode="rgb_array")
    _quiet_check_env(env)
    assert env.action_space == gym.spaces.Discrete(4)
    assert env.observation_space["rays"].shape == (OBS_FEATURES,)


def test_check_env_passes_on_mazes_without_the_benchmark(walled_maze):
    env = gym.make(ENV_ID, mazes=[walled_maze], render_mode="rgb_array", render_view="top_down")
    _quiet_check_env(env)


def test_runs_on_the_bundled_mazes_by_default():
    env = gym.make(ENV_ID, render_mode="rgb_array", privileged_info=True)
    _quiet_check_env(env)
    names = env.unwrapped.source.names
    assert names and all(name.startswith("gen-") for name in names)
    _, info = env.reset(options={"maze": names[1], "target": "paddle"})
    assert info["maze"] == names[1] and info["target"] == "paddle"
    assert SUCCESS_RADIUS_M < info["td"] < np.inf


def test_make_with_module_prefix_imports_and_registers(walled_maze):
    env = gym.make("sim.tasks.env:RobotSlang/NDH-v0", mazes=[walled_maze])
    assert isinstance(env.unwrapped, NDHEnv)


def test_reset_starts_the_benchmarks_episode(bench, val_env):
    for inst in bench.split("val_seen")[:12]:
        obs, info = val_env.reset(options={"inst_idx": inst.inst_idx})
        graph = bench.graph(inst.run)
        start, goal = episode_start(graph, inst), goal_node(graph, inst)
        assert info["pose"] == start and info["goal"] == goal
        assert info["maze"] == inst.run and info["target"] == inst.target and info["steps"] == 0
        assert info["td"] == pytest.approx(graph.dist[start.node, goal])
        features = RayTable.build(bench.maze(inst.run), graph).features()
        assert np.array_equal(obs["rays"], features[start.node, start.heading])
        assert obs["target"] == ("jar", "mug", "paddle").index(inst.target)
        assert obs["dialog"].startswith("<COM> " if inst.dialog[0][0] == "oracle" else "<DRI> ")
        assert inst.dialog[-1][1] in obs["dialog"]


def test_recorded_start_option(bench):
    env = NDHEnv(benchmark=bench, split="val_seen", start="recorded", privileged_info=True)
    inst = next(i for i in bench.split("val_seen") if i.target != "jar")
    _, info = env.reset(options={"inst_idx": inst.inst_idx})
    assert info["pose"] == recorded_start(bench.graph(inst.run), inst)


def test_same_seed_same_episode(val_env):
    a = val_env.reset(seed=7)[1]
    b = val_env.reset(seed=7)[1]
    assert (a["inst_idx"], a["pose"]) == (b["inst_idx"], b["pose"])
    assert len({val_env.reset(seed=s)[1]["inst_idx"] for s in range(10)}) > 1


def test_step_moves_turns_collides_and_rewards_progress(bench, val_env):
    inst = bench.split("val_seen")[0]
    _, info = val_env.reset(options={"inst_idx": inst.inst_idx})
    graph = bench.graph(inst.run)
    features = RayTable.build(bench.maze(inst.run), graph).features()
    pose, td, goal = info["pose"], info["td"], info["goal"]
    rng = np.random.default_rng(0)
    seen_collision = seen_move = False
    for t in range(1, 100):
        action = Action.FORWARD if rng.random() < 0.6 else Action(int(rng.integers(1, 3)))
        obs, reward, terminated, truncated, info = val_env.step(action)
        if action == Action.FORWARD:
            nxt = graph.forward[pose.node, pose.heading]
            expected = pose if nxt < 0 else Pose(int(nxt), pose.heading)
            assert info["collided"] == (nxt < 0)
            seen_collision |= bool(nxt < 0)
            seen_move |= bool(nxt >= 0)
        else:
            expected = Pose(pose.node, (pose.heading + (1 if action == Action.LEFT else -1)) % 8)
            assert not info["collided"]
        assert info["pose"] == expected and info["steps"] == t
        assert not terminated and not truncated
        assert info["td"] == pytest.approx(graph.dist[expected.node, goal])
        assert reward == pytest.approx(td - info["td"])
        assert np.array_equal(obs["rays"], features[expected.node, expected.heading])
        assert obs["action_mask"].tolist() == [int(graph.forward[expected.node, expected.heading] >= 0), 1, 1, 1]
        pose, td = expected, info["td"]
    assert seen_collision and seen_move


def test_stop_terminates_and_pays_success_only_near_the_goal(bench, val_env):
    inst = bench.split("val_seen")[3]
    _, info = val_env.reset(options={"inst_idx": inst.inst_idx})
    assert info["td"] > SUCCESS_RADIUS_M
    _, reward, terminated, truncated, info = val_env.step(Action.STOP)
    assert terminated and not truncated and reward == 0.0 and info["steps"] == 0
    with pytest.raises(RuntimeError, match="reset"):
        val_env.step(Action.FORWARD)


def test_teacher_reaches_the_goal_and_is_paid_for_it(bench, val_env):
    reached = 0
    for inst in bench.split("val_seen")[:15]:
        _, info = val_env.reset(options={"inst_idx": inst.inst_idx})
        graph, goal, start_td = val_env.episode_graph, info["goal"], info["td"]
        total, done = 0.0, False
        while not done:
            action = teacher_action(graph, val_env.pose, goal)
            _, reward, terminated, truncated, info = val_env.step(action)
            total += reward
            done = terminated or truncated
        if terminated:  # the shortest route fits in 120 actions
            reached += 1
            assert info["td"] == 0.0 and val_env.pose.node == goal
            assert total == pytest.approx(start_td + sim.tasks.env.SUCCESS_REWARD)
    assert reached >= 12


def test_truncated_after_120_moves(val_env):
    val_env.reset(seed=3)
    for t in range(1, 121):
        _, _, terminated, truncated, info = val_env.step(Action.LEFT)
        assert not terminated and info["steps"] == t
        assert truncated == (t == 120)
    with pytest.raises(RuntimeError):
        val_env.step(Action.LEFT)


def test_episodes_on_mazes_start_where_the_target_is_reachable(walled_maze):
    env = NDHEnv(mazes=[walled_maze], privileged_info=True)
    for seed in range(20):
        _, info = env.reset(seed=seed)
        assert info["maze"] == "walled" and info["target"] in ("jar", "mug", "paddle")
        assert SUCCESS_RADIUS_M < info["td"] < np.inf
    _, info = env.reset(options={"target": "mug"})
    assert info["goal"] == env.episode_graph.nearest_node(*walled_maze.objects["mug"])


def test_render_first_person_and_top_down(walled_maze):
    fp = NDHEnv(mazes=[walled_maze], render_mode="rgb_array")
    fp.reset(seed=0)
    image = fp.render()
    assert image.shape == (240, 320, 3) and image.dtype == np.uint8 and image.std() > 0
    td = NDHEnv(mazes=[walled_maze], render_mode="rgb_array", render_view="top_down")
    td.reset(seed=0)
    top = td.render()
    assert top.ndim == 3 and top.shape[1] > top.shape[0]  # the table is wider than deep
    # RGB order: the blue wall is bright in the last channel, dark in the first.
    blue = (top[..., 2] > 200) & (top[..., 0] < 60) & (top[..., 1] < 60)
    assert blue.any()


def test_bad_arguments_are_named(bench, walled_maze):
    with pytest.raises(ValueError, match="not both"):
        NDHEnv(benchmark=bench, mazes=[walled_maze])
    with pytest.raises(KeyError, match="unknown maze 'Run_0'"):
        NDHEnv(mazes=["Run_0"])
    with pytest.raises(ValueError, match="options\\['maze'\\]='gen-999'"):
        NDHEnv(mazes=[walled_maze]).reset(options={"maze": "gen-999"})
    with pytest.raises(ValueError, match="start='nowhere'"):
        NDHEnv(benchmark=bench, start="nowhere")
    with pytest.raises(ValueError, match="render_view"):
        NDHEnv(mazes=[walled_maze], render_view="sideways")
    env = NDHEnv(benchmark=bench, split="val_seen")
    with pytest.raises(ValueError, match="inst_idx"):
        env.reset(options={"inst_idx": -5})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action 7"):
        env.step(7)


def test_info_holds_nothing_privileged_unless_asked(walled_maze):
    env = NDHEnv(mazes=[walled_maze])
    _, info = env.reset(seed=0)
    _, _, _, _, step_info = env.step(Action.FORWARD)
    assert not {"td", "goal", "pose"} & (set(info) | set(step_info))


@pytest.mark.parametrize("env_id", sorted(i for i in gym.registry if i.startswith("RobotSlang/")))
def test_check_env_passes_on_every_registered_env(env_id):
    # As MiniGrid's tests: every id this package registers, with its default arguments.
    _quiet_check_env(gym.make(env_id))
