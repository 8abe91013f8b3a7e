"""Baseline Drivers: `random` (uniform moves, claims now and then) and `shortest` (an oracle that
follows the navigation graph's shortest path to the current target using the true pose)."""

from __future__ import annotations

import random
from typing import Any

from app.mazes import Mazes
from app.trial.vocabulary import MoveAction
from sim.core.dynamics import snap_pose, teacher_action
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph

RANDOM_CLAIM_P = 0.02


class RandomDriver:
    def __init__(self) -> None:
        self.rng = random.Random()  # seeded per trial in reset, so a trial's moves repeat

    def reset(self, info: dict[str, Any]) -> None:
        self.rng.seed(info.get("trial_id", 0))

    def act(self, dialog, observation) -> str:
        if self.rng.random() < RANDOM_CLAIM_P:
            return "stop"
        return str(self.rng.choice(list(MoveAction)))


class ShortestPathDriver:
    """Needs the true pose (simulator); without one it claims at once."""

    def __init__(self, mazes: Mazes) -> None:
        self.mazes = mazes
        self.maze: Maze | None = None
        self.graph: NavGraph | None = None

    def reset(self, info: dict[str, Any]) -> None:
        self.maze, self.graph = self.mazes.load(info["maze"]), self.mazes.graph(info["maze"])

    def act(self, dialog, observation) -> str:
        pose = observation.get("pose")
        if pose is None:
            return "stop"
        maze, graph = self.maze, self.graph
        if maze is None or graph is None:
            raise RuntimeError("ShortestPathDriver.act before reset(info)")
        goal = graph.nearest_node(*maze.objects[observation["target"]])
        return teacher_action(graph, snap_pose(graph, *pose), goal).word


def random_driver(info, services) -> RandomDriver:
    return RandomDriver()


def shortest_driver(info, services) -> ShortestPathDriver:
    return ShortestPathDriver(services.mazes)
