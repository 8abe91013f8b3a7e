"""Agent dynamics on the navigation grid: actions, poses and the teacher.

A pose is a node and a heading index (k * 45 degrees, counter-clockwise from +x). What a move
does (0.07 m straight or 0.099 m diagonal forward, a 45 degree turn, a forward into a wall a
collision that leaves the pose) is said once, in `sim.core.moves.Moves`, and every consumer
steps through it: `graph.moves.step(pose, action)` a pose at a time, `BatchStepper` a batch.
The teacher is one rule too, `shortest_actions`, whichever table the next hops come from.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from enum import IntEnum
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from robot_client.protocol import Move
from sim.core.geometry import HEADING_DI, HEADING_DJ, HEADINGS, heading_angle, heading_index


class Action(IntEnum):
    """The learners' action indices: the three moves and STOP (the policy's "I am there")."""

    FORWARD = 0
    LEFT = 1  # +45 degrees, counter-clockwise in the table frame
    RIGHT = 2
    STOP = 3

    @property
    def word(self) -> str:
        return self.name.lower()

    @classmethod
    def of(cls, move: Move) -> Action:
        """The index of one of the Driver's moves."""
        return cls[Move(move).name]


@dataclass(frozen=True)
class Pose:
    node: int
    heading: int  # 0..7

    def __iter__(self) -> Iterator[int]:
        """`node, heading = pose`, and a pose indexes the tables kept per (node, heading)."""
        yield self.node
        yield self.heading


class NodeSpace(Protocol):
    """Where the nodes are: a maze's graph (`sim.core.navgraph.NavGraph`) or its moves table
    (`sim.core.moves.Moves`), both built on the actions and poses here."""

    @property
    def nodes(self) -> np.ndarray:
        """(N, 2) positions, metres."""


class Routes(NodeSpace, Protocol):
    """What snapping and the teacher read of a maze's graph (`NavGraph`)."""

    @property
    def node_ij(self) -> np.ndarray:
        """(N, 2) grid indices."""

    @property
    def next_hop(self) -> np.ndarray:
        """(N, N) next node from i toward j; -1 where no path."""

    def nearest_node(self, x: float, y: float) -> int: ...


def snap_pose(graph: Routes, x: float, y: float, theta: float = 0.0) -> Pose:
    """The nearest navigable node and the nearest multiple of 45 degrees."""
    return Pose(graph.nearest_node(x, y), heading_index(theta))


def continuous_pose(graph: NodeSpace, pose: Pose) -> tuple[float, float, float]:
    """A grid pose as (x, y, theta): its node's centre in metres and its heading's angle."""
    x, y = graph.nodes[pose.node]
    return float(x), float(y), float(heading_angle(pose.heading))


# Heading index of each grid step (di, dj) in {-1, 0, 1}^2, indexed [di + 1, dj + 1].
_STEP_HEADING = np.full((3, 3), -1, dtype=np.int64)
_STEP_HEADING[HEADING_DI + 1, HEADING_DJ + 1] = np.arange(HEADINGS)


def teacher_actions(graph: Routes, nodes: ArrayLike, headings: ArrayLike, goals: ArrayLike) -> np.ndarray:
    """Shortest-path actions for arrays of poses and goal nodes on `graph`."""
    at, facing, goal = (np.asarray(a, dtype=np.int64) for a in (nodes, headings, goals))
    return shortest_actions(graph.node_ij, at, facing, goal, graph.next_hop[at, goal])


def teacher_action(graph: Routes, pose: Pose, goal_node: int) -> Action:
    return Action(int(teacher_actions(graph, [pose.node], [pose.heading], [goal_node])[0]))


def shortest_actions(
    ij: np.ndarray, nodes: np.ndarray, headings: np.ndarray, goals: np.ndarray, hops: np.ndarray
) -> np.ndarray:
    """The teacher: from poses (`nodes`, `headings`) whose next node toward `goals` is `hops` (-1
    where there is no path), turn toward the hop by the smaller turn (left on a tie), go forward
    when aligned, stop at the goal's node or where no path to it exists. `ij` holds the nodes'
    grid indices. The graph's teacher (`teacher_actions`) and the batch's
    (`BatchStepper.teacher_actions`) differ only in where they read the hops."""
    stop = (nodes == goals) | (hops < 0)
    delta = ij[np.where(stop, nodes, hops)] - ij[nodes]
    wanted = _STEP_HEADING[delta[..., 0] + 1, delta[..., 1] + 1]
    turn = (wanted - headings) % HEADINGS
    actions = np.where(turn == 0, Action.FORWARD, np.where(turn <= 4, Action.LEFT, Action.RIGHT))
    return np.where(stop, Action.STOP, actions).astype(np.int64)
