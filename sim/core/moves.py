"""`Moves`: the move rules, once, tabulated over a node space (one maze's graph or a world).

Per slot (a pose, `8 * node + heading`) and action: the slot reached, the metres moved and whether
it was a collision. `compile` is the only statement of the rules in the project: a forward goes to
the neighbouring grid point along the heading (the graph's `forward` table), and where that point
is not navigable it is a collision that leaves the pose; left and right turn by 45 degrees (left
counter-clockwise); stop stays. `NavGraph.moves` steps a pose at a time through it,
`sim.core.stepper.BatchStepper` a batch (reading its entries as laid out here).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import DTypeLike

from sim.core.dynamics import Action, Pose
from sim.core.geometry import HEADINGS

ACTIONS = len(Action)
_FORWARD, _STOP = int(Action.FORWARD), int(Action.STOP)
# A `Moves.table` entry: the slot reached << SLOT_SHIFT | the index of the metres moved in `lengths` << 1 | collided.
SLOT_SHIFT, ENTRY_LOW, MAX_LENGTHS = 6, 63, 32
# Heading change per action: forward 0, left +1, right -1, stop 0.
_TURN = np.array([0, 1, -1, 0], dtype=np.int64)


@dataclass(frozen=True, eq=False)
class Moves:
    """The rules tabulated over a node space: one maze's graph (`NavGraph.moves`) or a world's."""

    nodes: np.ndarray  # (N, 2) positions, metres
    table: np.ndarray  # (N * 8 * 4,) the entry of action a from slot s at 4 s + a
    lengths: np.ndarray  # (L <= 32,) the distinct metres of a move, ascending

    @classmethod
    def compile(cls, nodes: np.ndarray, forward: np.ndarray, dtype: DTypeLike = np.int64) -> Moves:
        """The rules for every pose: `forward` (N, 8) is the node a forward move reaches per heading,
        -1 where that grid point is not navigable. A world's table is int64 (numpy's index type):
        the batch indexes with its entries, and an int32 table cost a conversion per look-up. A
        graph's (`NavGraph.moves`) is int32: half the memory a live trial holds, and a single
        pose's look-up converts nothing."""
        if len(nodes) * HEADINGS << SLOT_SHIFT > np.iinfo(dtype).max:
            raise ValueError(f"{len(nodes)} nodes: too many for a {np.dtype(dtype)} moves table")
        slot = np.arange(len(nodes) * HEADINGS)
        node, heading = slot // HEADINGS, slot % HEADINGS
        ahead = np.asarray(forward).reshape(-1)
        reached = np.empty((slot.size, ACTIONS), dtype=np.int64)
        reached[:, _FORWARD] = np.where(ahead >= 0, ahead * HEADINGS + heading, slot)  # a collision stays
        for a in (Action.LEFT, Action.RIGHT, Action.STOP):
            reached[:, a] = node * HEADINGS + (heading + _TURN[a]) % HEADINGS
        collided = np.zeros((slot.size, ACTIONS), dtype=np.int64)
        collided[:, _FORWARD] = ahead < 0
        metres = np.zeros((slot.size, ACTIONS))
        span = np.linalg.norm(nodes[np.maximum(ahead, 0)] - nodes[node], axis=1)
        metres[:, _FORWARD] = np.where(ahead >= 0, span, 0.0)
        lengths = np.unique(metres)
        if lengths.size > MAX_LENGTHS:
            raise ValueError(f"{lengths.size} distinct move lengths: the moves table holds {MAX_LENGTHS}")
        index = np.searchsorted(lengths, metres).astype(np.int64)
        table = ((reached << SLOT_SHIFT) | (index << 1) | collided).reshape(-1)
        return cls(nodes, table.astype(dtype, copy=False), lengths)

    def step(self, pose: Pose, action: Action) -> tuple[Pose, bool]:
        """One action from one pose: the pose after it, and whether it was a forward into a wall."""
        entry = int(self.table[(pose.node * HEADINGS + pose.heading) * ACTIONS + action])
        node, heading = divmod(entry >> SLOT_SHIFT, HEADINGS)
        return Pose(node, heading), bool(entry & 1)

    def blocked(self, pose: Pose) -> bool:
        """Whether a forward move from `pose` would collide."""
        return bool(self.table[(pose.node * HEADINGS + pose.heading) * ACTIONS + _FORWARD] & 1)

    def after(self) -> np.ndarray:
        """(N * 8, 3) the slot that forward, left and right lead to from each slot (a collision: the same)."""
        slots: np.ndarray = self.table.reshape(-1, ACTIONS)[:, :_STOP] >> SLOT_SHIFT
        return slots
