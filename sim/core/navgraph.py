"""`NavGraph`: the benchmark's navigation graph over a maze, with exact all-pairs shortest paths.

Reproduces the RobotSlang benchmark's planner so that distances compare with the paper:
candidate nodes on a 0.07 m grid, removed where they sit on or within 40 pixels (0.07 m) of a
wall of the walls-only map, joined when their float64 Euclidean distance (as scipy's `cdist`
computes it) is above 0 and at most sqrt(2) * 0.07. Rounding in that test drops about half of
the diagonal edges; the published numbers depend on it, so that is the `benchmark` mode.
The `exact` mode joins every pair of 8-neighbours.

The benchmark's graph is built on the walls-only map, so the objects are walkable. The robot's
graph (`NavGraph.for_robot`) is built on the map with the objects: a move into a landmark is a
collision, as on the real table, and the robot stops in front of the target it claims. It is the
one notion of what blocks the robot on the platform: the live simulator seat drives on it, and
every planner of a trial (the Commanders' routes, the dialog Commander's belief, self-play's
shortest paths) plans on it. Scoring against the benchmark (NDH, LDH, the baselines) always uses
the walls-only graph, as the paper does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import ArrayLike

from sim.core.cache import ARRAYS_SUFFIX, load_arrays, save_arrays
from sim.core.cache import cache_dir as default_cache_dir
from sim.core.geometry import (
    GRID_STEP_M,
    HEADING_DI,
    HEADING_DJ,
    HEADINGS,
    MAP_WIDTH_PX,
    TABLE_HEIGHT_M,
    TABLE_WIDTH_M,
    world_to_pixel,
)
from sim.core.maze import Maze
from sim.core.moves import Moves

MODES = ("benchmark", "exact")
WALL_CLEARANCE_PX = int(round(MAP_WIDTH_PX / TABLE_WIDTH_M * GRID_STEP_M))  # 40
CACHE_VERSION = 1


def candidate_grid() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All candidate nodes as the benchmark lays them out (meshgrid order, y-major).

    Returns positions (M, 2) in metres, grid indices (M, 2) as (i, j), and pixels (M, 2) as
    (row, col), truncated to integers as the benchmark's `pose2pixel` does.
    """
    xs = np.arange(0, TABLE_WIDTH_M, GRID_STEP_M)
    ys = np.arange(0, TABLE_HEIGHT_M, GRID_STEP_M)
    xx, yy = np.meshgrid(xs, ys)
    ii, jj = np.meshgrid(np.arange(xs.size), np.arange(ys.size))
    positions = np.stack([xx.ravel(), yy.ravel()], axis=1)
    ij = np.stack([ii.ravel(), jj.ravel()], axis=1)
    cols, rows = world_to_pixel(positions[:, 0], positions[:, 1])
    return positions, ij, np.stack([np.int32(rows), np.int32(cols)], axis=1)


def navigable_mask(walls: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Candidates whose own pixel is floor and whose 80-pixel square holds no wall pixel."""
    blocked = (walls != 0).astype(np.uint8)
    # Summed-area table (H + 1, W + 1): the count of wall pixels in any clipped square in O(1).
    sat = cv2.integral(blocked, sdepth=cv2.CV_32S)
    r, c = pixels[:, 0], pixels[:, 1]
    r0 = np.maximum(r - WALL_CLEARANCE_PX, 0)
    r1 = np.minimum(r + WALL_CLEARANCE_PX, walls.shape[0])
    c0 = np.maximum(c - WALL_CLEARANCE_PX, 0)
    c1 = np.minimum(c + WALL_CLEARANCE_PX, walls.shape[1])
    in_square = sat[r1, c1] - sat[r0, c1] - sat[r1, c0] + sat[r0, c0]
    navigable: np.ndarray = (blocked[r, c] == 0) & (in_square == 0)
    return navigable


def _edges(nodes: np.ndarray, node_ij: np.ndarray, mode: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs the mode joins, both ways, in row-major order: (i, j, metres), each the float64
    Euclidean distance as scipy's `cdist` computes it (the root of the summed squares). Only
    8-neighbours on the grid can be joined (the next point over is two steps away), so only they
    are measured: all N x N pairs were a tenth of a graph's build."""
    grid = np.full(tuple(node_ij.max(axis=0) + 3), -1, dtype=np.int64)  # a border of -1 all round
    grid[node_ij[:, 0] + 1, node_ij[:, 1] + 1] = np.arange(len(nodes))
    around = [grid[node_ij[:, 0] + 1 + di, node_ij[:, 1] + 1 + dj] for di in (-1, 0, 1) for dj in (-1, 0, 1)]
    j = np.stack(around, axis=1)  # (N, 9), the node itself among them: at distance 0, never joined
    i = np.broadcast_to(np.arange(len(nodes))[:, None], j.shape)
    i, j = i[j >= 0], j[j >= 0]
    order = np.lexsort((j, i))
    i, j = i[order], j[order]
    step = nodes[i] - nodes[j]
    d = np.sqrt((step * step).sum(axis=1))
    joined = (d > 0) & (d <= np.sqrt(2) * GRID_STEP_M) if mode == "benchmark" else i != j
    return i[joined], j[joined], d[joined]


@dataclass(frozen=True, eq=False)
class NavGraph:
    mode: str
    nodes: np.ndarray  # (N, 2) positions, metres
    node_ij: np.ndarray  # (N, 2) grid indices (i along x, j along y)
    node_grid: np.ndarray  # (NX, NY) node index, -1 where not navigable
    dist: np.ndarray  # (N, N) shortest-path metres, inf where no path
    next_hop: np.ndarray  # (N, N) next node from i toward j; -1 where no path
    forward: np.ndarray  # (N, 8) node reached by a forward move per heading; -1 = collision
    objects_block: bool = False  # built on the map with the objects (the live seat), not walls only

    @property
    def n(self) -> int:
        return len(self.nodes)

    @cached_property
    def moves(self) -> Moves:
        """The move rules on this graph, compiled once: what driving on it needs (`Moves.step`), without
        the all-pairs tables (a few MB a maze), which a live simulator seat never reads."""
        return Moves.compile(self.nodes, self.forward, np.int32)

    @classmethod
    def build(
        cls,
        maze: Maze,
        mode: str = "benchmark",
        cache_dir: str | Path | None = None,
        use_cache: bool = True,
        objects_block: bool = False,
    ) -> NavGraph:
        """The graph of `maze` (cached by its contents); `objects_block=True`: `for_robot`."""
        if mode not in MODES:
            raise ValueError(f"unknown edge mode {mode!r}; expected one of {', '.join(MODES)}")
        grid = maze.labels if objects_block else maze.walls
        if not use_cache:  # no key to hash: the maze's hash is 5 ms
            return cls._compute(grid, mode, objects_block)
        kind = f"{mode}-objects" if objects_block else mode
        path = default_cache_dir(cache_dir) / "navgraph" / f"{maze.content_hash}-{kind}-v{CACHE_VERSION}{ARRAYS_SUFFIX}"
        if path.exists():
            try:
                return cls(mode=mode, objects_block=objects_block, **load_arrays(path))
            except (OSError, ValueError, KeyError):
                pass  # a torn or stale cache file is rebuilt below
        graph = cls._compute(grid, mode, objects_block)
        graph._save(path)
        return graph

    @classmethod
    def for_robot(cls, maze: Maze, cache_dir: str | Path | None = None, use_cache: bool = True) -> NavGraph:
        """The graph the robot drives on: the walls and the landmarks block it. A Commander may plan
        on it: the map it is shown has the landmarks."""
        return cls.build(maze, "benchmark", cache_dir=cache_dir, use_cache=use_cache, objects_block=True)

    @classmethod
    def _compute(cls, grid: np.ndarray, mode: str, objects_block: bool = False) -> NavGraph:
        """The graph on the label `grid`, where every non-floor pixel blocks."""
        # scipy is imported here, not at the top: a process whose graphs are cached never needs it.
        from scipy.sparse import csr_matrix
        from scipy.sparse.csgraph import connected_components, shortest_path

        positions, ij, pixels = candidate_grid()
        keep = navigable_mask(grid, pixels)
        i, j, d = _edges(positions[keep], ij[keep], mode)
        if objects_block:
            # An object beside a wall can cut a pocket off the maze: keep the maze's main part,
            # so that a target's nearest node is one the rest of the maze can reach.
            m = int(keep.sum())
            _, component = connected_components(csr_matrix((d, (i, j)), shape=(m, m)), directed=False)
            main = component == np.bincount(component).argmax()
            keep[np.flatnonzero(keep)[~main]] = False
            inside, renumbered = main[i] & main[j], np.cumsum(main) - 1
            i, j, d = renumbered[i[inside]], renumbered[j[inside]], d[inside]
        nodes, node_ij = positions[keep], ij[keep]
        n = len(nodes)
        node_grid = np.full(tuple(ij.max(axis=0) + 1), -1, dtype=np.int32)  # (NX, NY)
        node_grid[node_ij[:, 0], node_ij[:, 1]] = np.arange(n, dtype=np.int32)

        weights = csr_matrix((d, (i, j)), shape=(n, n))
        # The weights are symmetric (the same squares summed either way), so the directed search finds the
        # same distances and predecessors as the undirected one, which relaxes every edge twice.
        dist, pred = shortest_path(weights, method="D", directed=True, return_predecessors=True)
        # Undirected: the predecessor of i on the path from j is i's next hop toward j.
        next_hop = pred.T.astype(np.int32)
        next_hop[next_hop < 0] = -1
        np.fill_diagonal(next_hop, np.arange(n, dtype=np.int32))

        forward = np.full((n, HEADINGS), -1, dtype=np.int32)
        for k in range(HEADINGS):
            ti = node_ij[:, 0] + HEADING_DI[k]
            tj = node_ij[:, 1] + HEADING_DJ[k]
            inside = (ti >= 0) & (ti < node_grid.shape[0]) & (tj >= 0) & (tj < node_grid.shape[1])
            forward[inside, k] = node_grid[ti[inside], tj[inside]]
        return cls(
            mode=mode,
            nodes=nodes,
            node_ij=node_ij,
            node_grid=node_grid,
            dist=dist,
            next_hop=next_hop,
            forward=forward,
            objects_block=objects_block,
        )

    def _save(self, path: Path) -> None:
        save_arrays(
            path,
            nodes=self.nodes,
            node_ij=self.node_ij,
            node_grid=self.node_grid,
            dist=self.dist,
            next_hop=self.next_hop,
            forward=self.forward,
        )

    # -- queries ------------------------------------------------------------------
    def nearest_nodes(self, xy: ArrayLike) -> np.ndarray:
        """Nearest node (Euclidean; first on ties, as the benchmark) for each (x, y) row."""
        points = np.atleast_2d(np.asarray(xy, dtype=np.float64))[:, :2]
        d2 = ((points[:, None, :] - self.nodes[None, :, :]) ** 2).sum(axis=2)
        return np.asarray(d2.argmin(axis=1))

    def nearest_node(self, x: float, y: float) -> int:
        return int(self.nearest_nodes([[x, y]])[0])

    def topological_distance(self, a: Sequence[float], b: Sequence[float]) -> float:
        """Shortest-path metres between the nodes nearest to a and b; inf where no path exists."""
        i, j = self.nearest_nodes([a[:2], b[:2]])
        return float(self.dist[i, j])

    def path(self, i: int, j: int) -> list[int]:
        """Node sequence from i to j inclusive; empty where no path exists."""
        if self.next_hop[i, j] < 0:
            return []
        out = [int(i)]
        while out[-1] != j:
            out.append(int(self.next_hop[out[-1], j]))
        return out

    def reachable_fraction(self) -> float:
        """Share of ordered node pairs joined by a path."""
        return float(np.isfinite(self.dist).mean())
