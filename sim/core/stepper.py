"""The two ways the move rules are stepped.

The move rules are said once, in `sim.core.moves.Moves` (a table per node space). Every consumer steps through such a table:

- a pose at a time, `graph.moves.step(pose, action)` (`NavGraph.moves`, compiled once per graph):
  the live simulator seat, the demo's players, `sim play`, the benchmark's start protocol, offline
  self-play and the agents' episodes, the Commanders' router;
- a batch at once, `BatchStepper` on a `World`'s table (`World.moves`, every maze in one node space):

    stepper = BatchStepper(world, batch=B)
    stepper.start(envs, node, heading, goal, goal_dist, goal_next)  # (re)start some episodes
    collided = stepper.step(actions)             # (B,) 0 forward, 1 left, 2 right, 3 stop
    stepper.observations()                       # (B, F) ray features of the poses
    stepper.teacher_actions()                    # the shortest-path actions
    stepper.td, .otd, .path_length, .steps, .done, .stopped   # per episode

  the Gymnasium vector env (`sim.tasks.batch_env.BatchNavEnv`) and `RobotSlang/NDH-v0`
  (`sim.tasks.env`, a batch of one), the NDH baselines (`sim.tasks.evaluation`) and the learned
  Driver's rollouts (`models.rollout`).

`tests/sim/test_dynamics.py` and `tests/sim/test_stepper.py` hold both against the rules written
plainly (`tests/sim/helpers.reference_step`), step for step.

Batch semantics: an episode is done after STOP or after `max_actions` moves (forward, left, right;
the stop is not counted, as in `sim.core.metrics`); actions of finished episodes are ignored. The
teacher is `sim.core.dynamics.shortest_actions`, the same rule as the graph's teacher.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from sim.core.dynamics import Action, shortest_actions
from sim.core.geometry import HEADINGS
from sim.core.moves import ACTIONS, ENTRY_LOW, MAX_LENGTHS, SLOT_SHIFT

if TYPE_CHECKING:
    from sim.core.world import World

_FORWARD, _STOP = int(Action.FORWARD), int(Action.STOP)  # plain ints: a member look-up costs a microsecond a step
_MOVE_ACTIONS = np.arange(_STOP, dtype=np.int64)  # forward, left, right

MAX_EPISODE_ACTIONS = 120  # the benchmark's cap on a Driver episode's moves


class BatchStepper:
    """A batch of Driver episodes on a `World`, stepped at once through its `Moves` table."""

    def __init__(self, world: World, batch: int, max_actions: int = MAX_EPISODE_ACTIONS, record: bool = False):
        if batch < 1:
            raise ValueError(f"batch={batch}: must be at least 1")
        if max_actions < 1:
            raise ValueError(f"max_actions={max_actions}: must be at least 1")
        self.world, self.size, self.max_actions, self.record = world, batch, max_actions, record
        moves = world.moves
        self._moves = moves.table
        width = int(world.size.max())
        self._width = width
        # Goal rows, one per episode: distance and global next hop toward its goal from each node.
        self._dist = np.full((batch, width), np.inf)
        self._next = np.full((batch, width), -1, dtype=np.int64)
        self._dist_flat, self._next_flat = self._dist.reshape(-1), self._next.reshape(-1)  # views
        self._base = np.zeros(batch, dtype=np.int64)  # flat index of (episode, global node 0)
        self.slot = np.zeros(batch, dtype=np.int64)
        self.goal = np.zeros(batch, dtype=np.int64)  # global node
        self.steps = np.zeros(batch, dtype=np.int64)
        self.done = np.ones(batch, dtype=bool)
        self.collisions = np.zeros(batch, dtype=np.int64)
        self.path_length = np.zeros(batch)
        self.td = np.full(batch, np.inf)
        self.otd = np.full(batch, np.inf)
        self.shortest = np.full(batch, np.inf)
        self._started = False
        self._history: list[np.ndarray] = []
        # ORed into the actions: 3 (the stop) where an episode is done, so it stays put, 0 elsewhere.
        self._halt = np.full(batch, _STOP, dtype=np.int64)
        self._a, self._k = np.empty(batch, np.int64), np.empty(batch, np.int64)
        self._counted = np.empty(batch, bool)
        self._scratch = np.empty(batch)
        self._moved = np.empty(batch, self._moves.dtype)
        # Metres and collision flag by the low 6 bits of a table entry, so that one mask serves
        # both look-ups.
        code = np.arange(ENTRY_LOW + 1)
        self._metres = np.append(moves.lengths, np.zeros(MAX_LENGTHS - moves.lengths.size))[code >> 1]
        self._hit = (code & 1).astype(bool)
        # The forward's collision bit per slot, apart: the action mask reads it every step, and
        # masking it out of the table there cost an env step 1 us (6 %).
        self._blocked = (self._moves[_FORWARD::ACTIONS] & 1).astype(bool)

    # -- episodes -------------------------------------------------------------------
    def start(
        self,
        envs: ArrayLike,
        node: ArrayLike,
        heading: ArrayLike,
        goal: ArrayLike,
        goal_dist: ArrayLike,
        goal_next: ArrayLike,
    ) -> None:
        """Start episodes in batch positions `envs` (an index array or a boolean mask) at global
        `node`, `heading`, toward global `goal`, with its maze's goal rows (K, >= maze size):
        metres to the goal and next local node toward it (-1 where none) from each local node."""
        envs = np.flatnonzero(envs) if np.asarray(envs).dtype == bool else np.asarray(envs, dtype=np.int64)
        node, heading, goal = (np.asarray(a, dtype=np.int64) for a in (node, heading, goal))
        goal_dist, goal_next = np.asarray(goal_dist), np.asarray(goal_next)
        if not (node.shape == heading.shape == goal.shape == envs.shape):
            raise ValueError("start(): envs, node, heading and goal must have one entry per episode")
        if envs.size and (
            node.min() < 0
            or node.max() >= self.world.nodes
            or goal.min() < 0
            or goal.max() >= self.world.nodes
            or heading.min() < 0
            or heading.max() >= HEADINGS
        ):
            raise ValueError(
                f"start(): a node or goal outside the world ({self.world.nodes} nodes) "
                f"or a heading outside 0..{HEADINGS - 1}"
            )
        maze = np.searchsorted(self.world.offset, node, side="right") - 1
        offset = self.world.offset[maze]
        if np.any(np.searchsorted(self.world.offset, goal, side="right") - 1 != maze):
            raise ValueError("start(): an episode's goal is in another maze than its start")
        width = min(goal_dist.shape[1], self._width)
        self._dist[envs] = np.inf
        self._dist[envs, :width] = goal_dist[:, :width]
        self._next[envs] = -1
        self._next[envs, :width] = np.where(goal_next[:, :width] >= 0, goal_next[:, :width] + offset[:, None], -1)
        self._base[envs] = envs * self._width - offset
        self.slot[envs] = node * HEADINGS + heading
        self.goal[envs] = goal
        self.steps[envs] = 0
        self.done[envs] = False
        self._halt[envs] = 0
        self.collisions[envs] = 0
        self.path_length[envs] = 0.0
        self.td[envs] = self.otd[envs] = self.shortest[envs] = self._dist_flat[self._base[envs] + node]
        self._started = True
        if self.record:
            self._history = [self.node.copy()]

    def step(self, actions: ArrayLike) -> np.ndarray:
        """Apply (B,) actions; returns which of them were forward moves into a wall."""
        if not self._started:
            raise RuntimeError("step() before start(): start the batch's episodes first")
        actions = np.asarray(actions)
        if actions.shape != (self.size,) or actions.dtype.kind not in "iu":
            raise ValueError(
                f"actions of shape {actions.shape} and dtype {actions.dtype}: expected ({self.size},) integers"
            )
        # Into the stepper's own buffers: a step at batch 1000 is some twenty numpy calls on
        # 8 kB arrays, so each call and each temporary array costs as much as the arithmetic.
        a, k, moved, counted = self._a, self._k, self._moved, self._counted
        if actions.dtype != np.int64:
            actions = actions.astype(np.int64)  # an out-of-range unsigned one wraps to negative
        np.bitwise_or(actions, self._halt, out=a)  # a finished episode stops
        if a.view(np.uint64).max() > _STOP:  # an invalid action stays invalid; a negative wraps
            raise ValueError("actions must be 0 forward, 1 left, 2 right or 3 stop")
        np.multiply(self.slot, ACTIONS, out=k)
        k += a
        self._moves.take(k, out=moved, mode="clip")  # slot << 6 | length index << 1 | collided
        np.right_shift(moved, SLOT_SHIFT, out=self.slot)
        moved &= ENTRY_LOW
        self.path_length += self._metres.take(moved, out=self._scratch, mode="clip")
        collided = self._hit.take(moved, mode="clip")
        self.collisions += collided
        np.less(a, _STOP, out=counted)  # the stop is not a move
        self.steps += counted
        np.greater_equal(self.steps, self.max_actions, out=self.done)
        np.less_equal(counted, self.done, out=self.done)  # or stopped (or was done: its action is the stop)
        np.multiply(self.done, _STOP, out=self._halt)
        np.right_shift(self.slot, 3, out=k)
        k += self._base
        self.td = self._dist_flat.take(k, mode="clip")  # a new array: callers keep the one before the step
        np.minimum(self.otd, self.td, out=self.otd)
        if self.record:
            self._history.append(self.node)
        return collided

    # -- what the agent and its teacher see -------------------------------------------
    def observations(self, out: np.ndarray | None = None) -> np.ndarray:
        """(B, F) ray features of the current poses (in the world's dtype)."""
        if self.world.obs is None:
            raise ValueError("the world was compiled without observations")
        # The slots are in range: "raise" mode would gather into a copy of `out`, then copy it.
        return np.take(self.world.obs, self.slot, axis=0, out=out, mode="clip")

    def next_slots(self) -> np.ndarray:
        """(B, 3) the pose that forward, left and right would lead to (a collision: the same)."""
        slots: np.ndarray = self._moves[self.slot[:, None] * ACTIONS + _MOVE_ACTIONS] >> SLOT_SHIFT
        return slots

    def forward_blocked(self) -> np.ndarray:
        blocked: np.ndarray = self._blocked[self.slot]
        return blocked

    def teacher_actions(self) -> np.ndarray:
        """Shortest-path actions for the current poses (`sim.core.dynamics.shortest_actions`), the
        next hops read from the episodes' goal rows."""
        node = self.node
        return shortest_actions(self.world.ij, node, self.heading, self.goal, self._next_flat[self._base + node])

    def distance(self, node: ArrayLike) -> np.ndarray:
        """Metres from (B,) global nodes to each episode's goal."""
        return self._dist_flat[self._base + np.asarray(node, dtype=np.int64)]

    # -- bookkeeping ---------------------------------------------------------------
    @property
    def stopped(self) -> np.ndarray:
        """Which started episodes ended by the stop (the others done ran out of moves)."""
        return self.done & (self.steps < self.max_actions)

    @property
    def node(self) -> np.ndarray:
        return self.slot >> 3

    @property
    def heading(self) -> np.ndarray:
        return self.slot & (HEADINGS - 1)

    def visited(self) -> np.ndarray:
        """(T + 1, B) global node of each episode before each step since the last start(), then
        after the last; episode k's trajectory is its first `steps[k] + 1` rows. Needs record=True."""
        if not self.record:
            raise RuntimeError("trajectories are not recorded: make the stepper with record=True")
        return np.stack(self._history)

    def trajectories(self) -> list[list[int]]:
        """Global nodes visited by each episode: the start, then one per move (a collision
        repeats the node), as `sim.core.metrics.score_trajectory` takes them once made local."""
        history = self.visited()
        return [history[: self.steps[k] + 1, k].tolist() for k in range(self.size)]
