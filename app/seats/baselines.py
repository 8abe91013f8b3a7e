"""Baseline Drivers: `agent:random` (uniform moves, claims now and then; it sees nothing it
does not use) and `oracle:shortest`, which cheats: it follows the navigation graph's shortest
path to the current target from the true pose, so it never ranks with the agents."""

from __future__ import annotations

import random

from app.mazes import Mazes
from app.seats.base import Oracle, Seating
from app.seats.registry import AgentParts
from sim.agents.stepwise import StepwiseDriver
from sim.core.dynamics import Action, snap_pose, teacher_action
from sim.trial.vocabulary import Move

RANDOM_CLAIM_P = 0.02


class RandomDriver(StepwiseDriver):
    def __init__(self, seed: int) -> None:
        self.rng = random.Random(seed)  # seeded per trial, so a trial's moves repeat

    def decide(self) -> Move | None:
        if self.rng.random() < RANDOM_CLAIM_P:
            return None
        return self.rng.choice(list(Move))


class ShortestPathOracle(StepwiseDriver):
    """Needs the true pose (simulator); without one it claims at once."""

    def __init__(self, mazes: Mazes, oracle: Oracle) -> None:
        self.oracle = oracle
        self.maze, self.graph = mazes.load(oracle.maze), mazes.graph(oracle.maze)

    @property
    def target(self) -> str | None:
        index = self.target_index
        return self.oracle.targets[index] if index is not None and index < len(self.oracle.targets) else None

    def claim_words(self) -> str:
        return f"I think I found the {self.target}"

    def decide(self) -> Move | None:
        pose, target = self.oracle.true_pose(), self.target
        if pose is None or target is None:
            return None
        goal = self.graph.nearest_node(*self.maze.objects[target])
        action = teacher_action(self.graph, snap_pose(self.graph, *pose), goal)
        return None if action == Action.STOP else Move(action.word)


def random_driver(parts: AgentParts, seating: Seating) -> RandomDriver:
    return RandomDriver(seating.seed)


def shortest_driver(parts: AgentParts, seating: Seating) -> ShortestPathOracle:
    if seating.oracle is None:
        raise ValueError("oracle:shortest needs the oracle's view of the trial")
    return ShortestPathOracle(parts.mazes, seating.oracle)
