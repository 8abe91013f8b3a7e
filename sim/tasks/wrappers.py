"""Wrappers for libraries that take fixed-size observations only (stable-baselines3 and most).

`DialogCodes` turns NDH-v0's `dialog` (a Text space) into the codes of its last `max_chars`
characters: MultiDiscrete, one category per character of the Text charset plus 0 for padding
(the codes are right-aligned, so the most recent words keep their positions). Everything else
in the Dict passes through.
"""

from __future__ import annotations

from typing import TypedDict

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sim.tasks.env import Observation

DEFAULT_MAX_CHARS = 256


class CodedObservation(TypedDict):
    """`Observation` with the dialog as (max_chars,) int64 codes."""

    rays: np.ndarray
    target: int
    dialog: np.ndarray
    action_mask: np.ndarray


class DialogCodes(gym.ObservationWrapper):
    def __init__(self, env: gym.Env, max_chars: int = DEFAULT_MAX_CHARS):
        super().__init__(env)
        space = env.observation_space
        text = space.spaces.get("dialog") if isinstance(space, spaces.Dict) else None
        if not isinstance(space, spaces.Dict) or not isinstance(text, spaces.Text):
            raise ValueError("DialogCodes wraps an env whose observation has a Text 'dialog'")
        self.max_chars = max_chars
        self._code = {c: k + 1 for k, c in enumerate(text.character_list)}
        self.observation_space = spaces.Dict(
            {
                **{k: v for k, v in space.items() if k != "dialog"},
                "dialog": spaces.MultiDiscrete(np.full(max_chars, len(self._code) + 1)),
            }
        )

    def observation(self, observation: Observation) -> CodedObservation:
        codes = np.zeros(self.max_chars, dtype=np.int64)
        tail = observation["dialog"][-self.max_chars :]
        if tail:
            codes[-len(tail) :] = [self._code[c] for c in tail]
        return {**observation, "dialog": codes}
