"""`BatchNavEnv`: `RobotSlang/NDH-v0` as a `gymnasium.vector.VectorEnv` over the simulator core.

    env = gymnasium.make_vec("RobotSlang/NDH-v0", num_envs=1000, vectorization_mode="vector_entry_point",
                             benchmark="../shared/robotslang", split="train")
    obs, info = env.reset(seed=0)           # obs: the Dict of NDH-v0, each entry batched
    obs, reward, terminated, truncated, info = env.step(actions)   # actions (num_envs,) ints

All episodes live in one `sim.core.stepper.BatchStepper` over a `World` of every maze of the
source (a benchmark split or mazes, as `NDHEnv`), so a step of the whole batch is a handful
of array look-ups. Episodes are drawn as `NDHEnv` draws them.

Autoreset mode: `NEXT_STEP`, Gymnasium's default. The step that ends an episode returns its
last observation with terminated or truncated set; the next step ignores that sub-env's
action, starts a new episode there and returns its first observation with reward 0 and
neither flag. `info` holds, per sub-env, `collided` and `steps`, and with
`privileged_info=True` also `td` (metres to the goal), for evaluation code.
"""

from __future__ import annotations

from typing import Any, NotRequired, TypedDict, Unpack, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space
from numpy.typing import ArrayLike

from sim.core.dynamics import Action
from sim.core.geometry import SUCCESS_RADIUS_M
from sim.core.labels import OBJECTS
from sim.core.stepper import MAX_EPISODE_ACTIONS, BatchStepper
from sim.tasks.env import (
    SUCCESS_REWARD,
    EpisodeOptions,
    EpisodeSource,
    SourceOptions,
    observation_space,
    start_episodes,
)


class BatchObservation(TypedDict):
    """`sim.tasks.env.Observation`, each entry batched over the sub-envs."""

    rays: np.ndarray
    target: np.ndarray
    dialog: tuple[str, ...]
    action_mask: np.ndarray


class BatchInfo(TypedDict):
    collided: np.ndarray
    steps: np.ndarray
    td: NotRequired[np.ndarray]  # with privileged_info only


class BatchNavEnv(gym.vector.VectorEnv):
    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        num_envs: int = 1,
        max_actions: int = MAX_EPISODE_ACTIONS,
        privileged_info: bool = False,
        **source: Unpack[SourceOptions],
    ):
        if num_envs < 1:
            raise ValueError(f"num_envs={num_envs}: must be at least 1")
        self.source = EpisodeSource(**source)
        self.num_envs, self.privileged_info = num_envs, privileged_info
        self.stepper = BatchStepper(self.source.world(), num_envs, max_actions)
        self.single_observation_space = observation_space()
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.single_action_space = spaces.Discrete(len(Action))
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._target = np.zeros(num_envs, dtype=np.int64)
        self._dialog = [""] * num_envs
        self._autoreset = np.zeros(num_envs, dtype=bool)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[BatchObservation, dict[str, Any]]:
        super().reset(seed=seed)
        self._start(np.arange(self.num_envs), cast(EpisodeOptions, options or {}))
        self._autoreset[:] = False
        return self._observations(), dict(self._info(np.zeros(self.num_envs, dtype=bool)))  # Gymnasium's plain dict

    def step(self, actions: ArrayLike) -> tuple[BatchObservation, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        actions = np.asarray(actions)
        stepper, restart = self.stepper, self._autoreset.copy()
        before = stepper.td
        collided = stepper.step(np.where(restart, Action.STOP, actions))  # restarting: ignored
        td = stepper.td
        reward = np.where(np.isinf(td), 0.0, before - td)
        terminated = stepper.stopped & ~restart
        truncated = stepper.done & ~stepper.stopped & ~restart
        reward = reward + SUCCESS_REWARD * (terminated & (td <= SUCCESS_RADIUS_M))
        reward[restart] = 0.0
        if restart.any():
            self._start(np.flatnonzero(restart), {})
        self._autoreset = terminated | truncated
        return self._observations(), reward, terminated, truncated, dict(self._info(collided))

    def _start(self, envs: np.ndarray, options: EpisodeOptions) -> None:
        episodes = [self.source.sample(self.np_random, options) for _ in envs]
        start_episodes(self.stepper, self.source, envs, episodes)
        for env, ep in zip(envs, episodes):
            self._target[env] = OBJECTS.index(ep.target)
            self._dialog[env] = ep.dialog

    def _observations(self) -> BatchObservation:
        mask = np.ones((self.num_envs, len(Action)), dtype=np.int8)
        mask[:, Action.FORWARD] = ~self.stepper.forward_blocked()
        return {
            "rays": self.stepper.observations(),
            "target": self._target.copy(),
            "dialog": tuple(self._dialog),
            "action_mask": mask,
        }

    def _info(self, collided: np.ndarray) -> BatchInfo:
        info: BatchInfo = {"collided": collided, "steps": self.stepper.steps.copy()}
        if self.privileged_info:
            info["td"] = self.stepper.td.copy()
        return info
