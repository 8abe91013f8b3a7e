"""BatchNavEnv: NDH-v0 as a Gymnasium vector env over the core, and what standard libraries see."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import sim.tasks.env  # noqa: F401  (registers RobotSlang/NDH-v0)
from sim.core.dynamics import Action
from sim.tasks.batch_env import BatchNavEnv
from sim.tasks.env import ENV_ID, NDHEnv
from sim.tasks.wrappers import DialogCodes


def test_make_vec_returns_the_batched_core_with_the_single_envs_spaces():
    env = gym.make_vec(ENV_ID, num_envs=6, vectorization_mode="vector_entry_point")
    assert isinstance(env, BatchNavEnv) and env.num_envs == 6
    assert env.single_observation_space == NDHEnv().observation_space
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert obs["rays"].shape == (6, env.single_observation_space["rays"].shape[0])


def test_episodes_end_and_restart_in_the_next_step():
    env = BatchNavEnv(num_envs=3, max_actions=4, privileged_info=True)
    env.reset(seed=1)
    stop, left = Action.STOP, Action.LEFT
    _, reward, terminated, truncated, info = env.step([stop, left, left])
    assert terminated.tolist() == [True, False, False] and not truncated.any()
    before = info["td"][1:].copy()
    for _ in range(3):
        _, reward, terminated, truncated, info = env.step([left, left, left])
    # Env 0 restarted on the first of these steps (its action ignored, reward 0); 1 and 2 ran
    # out of moves on the last, having only turned: no reward.
    assert truncated.tolist() == [False, True, True] and not terminated.any()
    assert reward[1:].tolist() == [0.0, 0.0] and np.array_equal(info["td"][1:], before)
    assert info["steps"].tolist() == [2, 4, 4]
    obs, reward, terminated, truncated, info = env.step([left, left, left])
    assert info["steps"].tolist() == [3, 0, 0] and reward[1:].tolist() == [0.0, 0.0]


def test_rewards_sum_to_the_distance_gained_like_the_single_env():
    env = BatchNavEnv(num_envs=4, privileged_info=True)
    env.reset(seed=2)
    start = env.stepper.td.copy()
    total = np.zeros(4)
    for _ in range(30):
        _, reward, terminated, truncated, info = env.step(env.stepper.teacher_actions())
        total += reward
        if (terminated | truncated).any():
            break
    live = ~(terminated | truncated)
    assert np.allclose(total[live], (start - info["td"])[live])


def test_no_privileged_info_unless_asked():
    env = BatchNavEnv(num_envs=2)
    _, info = env.reset(seed=0)
    assert "td" not in info and "td" not in env.step([0, 0])[4]


def test_stable_baselines3_ppo_learns_on_ndh_v0_through_the_dialog_wrapper(tmp_path):
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = DialogCodes(gym.make(ENV_ID, mazes=["gen-000", "gen-001"]), max_chars=64)
    sb3_check_env(env, warn=True)
    model = PPO("MultiInputPolicy", env, n_steps=128, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=256)
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(int(action))
    model.save(tmp_path / "ppo")
    assert (tmp_path / "ppo.zip").stat().st_size > 0


def test_dialog_codes_keep_the_end_of_the_dialog_within_the_charset(benchmark_path):
    env = DialogCodes(NDHEnv(benchmark=benchmark_path, split="val_seen"), max_chars=32)
    raw = env.unwrapped
    obs, _ = env.reset(seed=0)
    text = raw._episode.dialog
    codes = obs["dialog"]
    assert env.observation_space.contains(obs)
    decoded = "".join(sim.tasks.env.DIALOG_CHARSET[c - 1] for c in codes if c > 0)
    assert decoded == text[-32:]
