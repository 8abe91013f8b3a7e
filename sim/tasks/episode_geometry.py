"""`EpisodeGeometry`: NDH instances compiled onto a `World`: start pose, goal node and the goal
rows (distance and next hop toward the goal from every node of its maze), cached on disk beside
the world."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.core.cache import ARRAYS_SUFFIX, load_arrays, save_arrays
from sim.core.cache import cache_dir as default_cache_dir
from sim.core.stepper import BatchStepper
from sim.core.world import World, goal_rows
from sim.tasks.benchmark import START_MODES, Benchmark, NDHInstance, goal_node


@dataclass(frozen=True, eq=False)
class EpisodeGeometry:
    """NDH instances on a world: start pose, goal, and goal rows padded to the largest maze."""

    maze: np.ndarray  # (M,) index into World.names
    start_node: np.ndarray  # (M,) global
    start_heading: np.ndarray  # (M,)
    goal_node: np.ndarray  # (M,) global
    goal_dist: np.ndarray  # (M, Nmax) shortest-path metres to the goal from each local node
    goal_next: np.ndarray  # (M, Nmax) next local node toward the goal; -1 where no path

    @classmethod
    def build(
        cls,
        bench: Benchmark,
        world: World,
        instances: Sequence[NDHInstance],
        start: str = "episode",
        mode: str = "benchmark",
    ) -> EpisodeGeometry:
        """Cached on disk beside the world (the start protocol walks the teacher, and the
        goal rows come from the all-pairs tables)."""
        key = hashlib.sha256(f"{world.key}:{mode}:{start}:{[(i.run, i.scan, i.inst_idx) for i in instances]}".encode())
        path = default_cache_dir(bench.cache_dir) / "world" / f"episodes-{key.hexdigest()[:16]}{ARRAYS_SUFFIX}"
        fields = ("maze", "start_node", "start_heading", "goal_node", "goal_dist", "goal_next")
        if world.key and path.exists():
            try:
                data = load_arrays(path)
                return cls(**{f: data[f] for f in fields})
            except (OSError, ValueError, KeyError):
                pass  # torn or stale: recomputed below
        m, nmax = len(instances), int(world.size.max())
        out = {f: np.zeros(m, dtype=np.int64) for f in fields[:4]}
        out["goal_dist"] = np.full((m, nmax), np.inf, dtype=np.float64)
        out["goal_next"] = np.full((m, nmax), -1, dtype=np.int64)
        for k, inst in enumerate(instances):
            graph = bench.graph(inst.run, mode)
            r = world.index(inst.run)
            off = world.offset[r]
            pose = START_MODES[start](graph, inst)
            g = goal_node(graph, inst)
            out["maze"][k], out["start_node"][k], out["start_heading"][k] = r, off + pose.node, pose.heading
            out["goal_node"][k] = off + g
            dist, hop = goal_rows(graph, [g])
            out["goal_dist"][k, : graph.n], out["goal_next"][k, : graph.n] = dist[0], hop[0]
        if world.key:
            save_arrays(path, compressed=False, **out)
        return cls(**out)

    def __len__(self) -> int:
        return len(self.maze)

    def start(self, stepper: BatchStepper, episodes: np.ndarray) -> None:
        """Start `episodes` (indices into these) in `stepper`'s positions 0, 1, ..., one each."""
        stepper.start(
            np.arange(len(episodes)),
            self.start_node[episodes],
            self.start_heading[episodes],
            self.goal_node[episodes],
            self.goal_dist[episodes],
            self.goal_next[episodes],
        )
