"""The NDH baselines one pose at a time: the reference the batched `sim.tasks.evaluation` is held
against, episode for episode."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from sim.core.dynamics import Action, Pose, teacher_action
from sim.core.navgraph import NavGraph
from sim.core.stepper import MAX_EPISODE_ACTIONS


class Policy(Protocol):
    name: str

    def reset(self, graph: NavGraph, start: Pose, goal: int, rng: np.random.Generator) -> None: ...

    def act(self, pose: Pose) -> Action: ...


class StopAgent:
    name = "stop"

    def reset(self, graph: NavGraph, start: Pose, goal: int, rng: np.random.Generator) -> None:
        pass

    def act(self, pose: Pose) -> Action:
        return Action.STOP


class RandomAgent:
    """Uniform over forward/left/right (left/right only when forward would collide); never stops,
    so its episodes run to the action limit."""

    name = "random"

    def reset(self, graph: NavGraph, start: Pose, goal: int, rng: np.random.Generator) -> None:
        self.graph, self.rng = graph, rng

    def act(self, pose: Pose) -> Action:
        if self.graph.moves.blocked(pose):
            return Action(self.rng.choice((Action.LEFT, Action.RIGHT)))
        return Action(self.rng.choice((Action.FORWARD, Action.LEFT, Action.RIGHT)))


class ShortestAgent:
    """The teacher: follows the shortest path and stops at the goal's node."""

    name = "shortest"

    def reset(self, graph: NavGraph, start: Pose, goal: int, rng: np.random.Generator) -> None:
        self.graph, self.goal = graph, goal

    def act(self, pose: Pose) -> Action:
        return teacher_action(self.graph, pose, self.goal)


BASELINES: dict[str, type[Policy]] = {cls.name: cls for cls in (StopAgent, RandomAgent, ShortestAgent)}


def make_baseline(name: str) -> Policy:
    try:
        return BASELINES[name]()
    except KeyError:
        raise ValueError(f"unknown agent {name!r}; expected one of {', '.join(BASELINES)}") from None


def run_episode(
    graph: NavGraph,
    start: Pose,
    goal: int,
    policy: Policy,
    rng: np.random.Generator,
    max_actions: int = MAX_EPISODE_ACTIONS,
) -> tuple[list[int], int]:
    """Roll a policy out; returns the nodes visited (start first) and the moves made."""
    policy.reset(graph, start, goal, rng)
    pose, nodes, moves = start, [start.node], 0
    while moves < max_actions:
        action = policy.act(pose)
        if action == Action.STOP:
            break
        pose, _ = graph.moves.step(pose, action)
        nodes.append(pose.node)
        moves += 1
    return nodes, moves
