"""`BatchNavEnv`: a batch of Driver episodes, possibly in different mazes, stepped in one go.

    env = BatchNavEnv([(graph_a, rays_a), (graph_b, rays_b)])   # the mazes episodes may use
    obs = env.reset([(graph_a, start_pose, goal_node), (graph_b, Pose(12, 3), 40), ...])
    while not env.done.all():
        obs, collided, done = env.step(env.teacher_actions())    # or a policy's (B,) actions
    env.td, env.otd, env.path_length, env.steps                  # per episode, metres / moves
    env.trajectories()                                           # nodes visited, per episode

The per-maze tables (forward moves, ray features, move lengths) are concatenated into one
global node index space (maze k's node i is `offsets[k] + i`), so a step over the whole batch
is a handful of fancy-indexing operations. Distances and next hops toward each episode's goal
are copied out of the maze's all-pairs tables at reset, one row per episode, padded to the
largest maze.

Semantics match `sim.dynamics.step`: a forward into a non-navigable grid point is a collision
and leaves the pose unchanged. An episode is done after STOP or after `max_actions` moves
(forward, left, right; the stop is not counted, as in `sim.metrics`); actions of finished
episodes are ignored and their observation stays the last one.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from sim.benchmark import MAX_EPISODE_ACTIONS
from sim.dynamics import Action, Pose, actions_toward
from sim.geometry import HEADINGS
from sim.navgraph import NavGraph
from sim.observations import OBS_FEATURES, RayTable

# Heading change per action: forward 0, left +1, right -1, stop 0.
_TURN = np.array([0, 1, -1, 0], dtype=np.int64)


class BatchNavEnv:
    """Episodes over a fixed set of mazes, each given as (NavGraph, RayTable)."""

    def __init__(self, worlds: Sequence[tuple[NavGraph, RayTable]] = (),
                 max_actions: int = MAX_EPISODE_ACTIONS, record: bool = True):
        if max_actions < 1:
            raise ValueError(f"max_actions={max_actions}: must be at least 1")
        self.max_actions, self.record = max_actions, record
        self.graphs: list[NavGraph] = []
        self._world_of: dict[int, int] = {}  # id(graph) -> world index
        self.offsets = np.zeros(1, dtype=np.int64)
        self.forward = np.zeros(0, dtype=np.int64)  # (sum N * 8,) global node or -1
        self.move_length = np.zeros(0)  # (sum N * 8,) metres of a forward move; 0 on collision
        self.features = np.zeros((0, OBS_FEATURES), dtype=np.float32)  # (sum N * 8, F)
        self.node_ij = np.zeros((0, 2), dtype=np.int64)  # (sum N, 2) grid indices
        self.positions = np.zeros((0, 2))  # (sum N, 2) metres
        self.size = 0  # episodes in the batch, set by reset()
        for graph, rays in worlds:
            self.add(graph, rays)

    # -- mazes --------------------------------------------------------------------
    def add(self, graph: NavGraph, rays: RayTable) -> int:
        """Make a maze available to episodes; returns its world index (adding twice is a no-op)."""
        if id(graph) in self._world_of:
            return self._world_of[id(graph)]
        if rays.labels.shape[0] != graph.n:
            raise ValueError(f"ray table has {rays.labels.shape[0]} nodes but the graph has {graph.n}: "
                             f"build it with RayTable.build(maze, graph) for this graph")
        offset = int(self.offsets[-1])
        local = graph.forward.reshape(-1).astype(np.int64)
        forward = np.where(local >= 0, local + offset, -1)
        source = np.repeat(np.arange(graph.n), HEADINGS)
        length = np.linalg.norm(graph.nodes[np.maximum(local, 0)] - graph.nodes[source], axis=1)
        self.forward = np.concatenate([self.forward, forward])
        self.move_length = np.concatenate([self.move_length, np.where(local >= 0, length, 0.0)])
        self.features = np.concatenate([self.features, rays.features().reshape(-1, OBS_FEATURES)])
        self.node_ij = np.concatenate([self.node_ij, graph.node_ij.astype(np.int64)])
        self.positions = np.concatenate([self.positions, graph.nodes])
        self.offsets = np.append(self.offsets, offset + graph.n)
        self.graphs.append(graph)
        self._world_of[id(graph)] = len(self.graphs) - 1
        return len(self.graphs) - 1

    def world_index(self, graph: NavGraph | int) -> int:
        if isinstance(graph, (int, np.integer)):
            if not 0 <= graph < len(self.graphs):
                raise ValueError(f"world {graph}: expected 0..{len(self.graphs) - 1}")
            return int(graph)
        if id(graph) not in self._world_of:
            raise ValueError("a graph not added to this BatchNavEnv: call env.add(graph, rays) first")
        return self._world_of[id(graph)]

    # -- episodes -------------------------------------------------------------------
    def reset(self, episodes: Sequence[tuple[NavGraph | int, Pose, int]]) -> np.ndarray:
        """Start one episode per (graph or world index, start Pose, goal node); returns (B, F) obs."""
        b = len(episodes)
        if b == 0:
            raise ValueError("reset() needs at least one episode")
        worlds = np.empty(b, dtype=np.int64)
        nodes = np.empty(b, dtype=np.int64)
        headings = np.empty(b, dtype=np.int64)
        goals = np.empty(b, dtype=np.int64)
        for k, (graph, pose, goal) in enumerate(episodes):
            w = worlds[k] = self.world_index(graph)
            n = self.graphs[w].n
            if not (0 <= pose.node < n and 0 <= pose.heading < HEADINGS and 0 <= goal < n):
                raise ValueError(f"episode {k}: start {pose} or goal {goal} outside the graph "
                                 f"({n} nodes, headings 0..{HEADINGS - 1})")
            nodes[k], headings[k], goals[k] = pose.node, pose.heading, goal

        self.size = b
        self.world = worlds
        self.offset = self.offsets[worlds]
        self.goal = goals  # local node index in its maze
        # Toward-goal rows: distance and (global) next hop from every node of the episode's maze.
        width = int(max(self.graphs[w].n for w in set(worlds.tolist())))
        self._to_goal = np.full((b, width), np.inf)
        self._hop = np.full((b, width), -1, dtype=np.int64)
        for w in set(worlds.tolist()):
            rows = np.flatnonzero(worlds == w)
            graph = self.graphs[w]
            # Columns, not the transposed rows: Dijkstra's sums differ in the last bit.
            self._to_goal[rows, : graph.n] = graph.dist[:, goals[rows]].T
            hop = graph.next_hop[:, goals[rows]].T
            self._hop[rows, : graph.n] = np.where(hop >= 0, hop + self.offsets[w], -1)
        self._rows = np.arange(b)

        self.node = nodes + self.offset  # global node index
        self.heading = headings
        self.steps = np.zeros(b, dtype=np.int64)
        self.done = np.zeros(b, dtype=bool)
        self.stopped = np.zeros(b, dtype=bool)
        self.collisions = np.zeros(b, dtype=np.int64)
        self.path_length = np.zeros(b)
        self.td = self._to_goal[self._rows, nodes]
        self.shortest = self.td.copy()
        self.otd = self.td.copy()
        self._history = [self.node.copy()] if self.record else None
        return self.features[self.node * HEADINGS + self.heading]

    def step(self, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Apply (B,) actions; returns observations (B, F), collided (B,), done (B,)."""
        if self.size == 0:
            raise RuntimeError("step() before reset(): start the batch's episodes first")
        actions = np.asarray(actions)
        if actions.shape != (self.size,):
            raise ValueError(f"actions of shape {actions.shape}: expected ({self.size},)")
        if actions.min() < 0 or actions.max() > Action.STOP:
            raise ValueError("actions must be 0 forward, 1 left, 2 right or 3 stop")
        live = ~self.done
        slot = self.node * HEADINGS + self.heading
        forward = live & (actions == Action.FORWARD)
        target = self.forward[slot]
        moved = forward & (target >= 0)
        collided = forward & (target < 0)
        self.node = np.where(moved, target, self.node)
        self.path_length += np.where(moved, self.move_length[slot], 0.0)
        self.heading = (self.heading + np.where(live, _TURN[actions], 0)) & (HEADINGS - 1)
        stop = live & (actions == Action.STOP)
        self.steps += live & ~stop
        self.collisions += collided
        self.stopped |= stop
        self.done |= stop | (self.steps >= self.max_actions)
        self.td = self._to_goal[self._rows, self.node - self.offset]
        np.minimum(self.otd, self.td, out=self.otd)
        if self.record:
            self._history.append(self.node.copy())
        return self.features[self.node * HEADINGS + self.heading], collided, self.done.copy()

    def teacher_actions(self) -> np.ndarray:
        """Shortest-path actions for the current poses, as `sim.dynamics.teacher_actions`."""
        hop = self._hop[self._rows, self.node - self.offset]
        stop = (self.node - self.offset == self.goal) | (hop < 0)
        hop = np.where(stop, self.node, hop)
        actions = actions_toward(self.node_ij[hop] - self.node_ij[self.node], self.heading)
        return np.where(stop, Action.STOP, actions).astype(np.int64)

    # -- bookkeeping ---------------------------------------------------------------
    @property
    def local_node(self) -> np.ndarray:
        """Each episode's node in its own maze's graph."""
        return self.node - self.offset

    def poses(self) -> list[Pose]:
        return [Pose(int(n), int(h)) for n, h in zip(self.local_node, self.heading)]

    def observations(self) -> np.ndarray:
        return self.features[self.node * HEADINGS + self.heading]

    def trajectories(self) -> list[list[int]]:
        """Local nodes visited by each episode: the start, then one per move (a collision repeats
        the node), as `sim.metrics.score_trajectory` takes them."""
        if not self.record:
            raise RuntimeError("trajectories are not recorded: make the env with record=True")
        history = np.stack(self._history) - self.offset  # (T + 1, B)
        return [history[: self.steps[k] + 1, k].tolist() for k in range(self.size)]
