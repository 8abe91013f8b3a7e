"""One split's NDH instances for the learner, on the simulator's compiled `sim.core.world.World`.

An `EpisodeSet` holds the instances' token ids, target labels and their `EpisodeGeometry`
(start pose, goal node, and the distance and next hop toward the goal from every node of its
maze), which is what `sim.core.stepper.BatchStepper`, the core every agent runs on, starts from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.tokenizer import Tokenizer
from sim.core.labels import object_label
from sim.core.world import World
from sim.tasks.benchmark import Benchmark, NDHInstance
from sim.tasks.episode_geometry import EpisodeGeometry


@dataclass
class EpisodeSet:
    split: str
    instances: list[NDHInstance]
    tokens: np.ndarray  # (M, T) int64 ids, 0-padded
    lengths: np.ndarray  # (M,)
    geometry: EpisodeGeometry  # the instances on the world: starts, goals and goal rows
    target_label: np.ndarray  # (M,) sim.core.labels.Label of the target object

    def __len__(self) -> int:
        return len(self.instances)

    @classmethod
    def build(
        cls,
        bench: Benchmark,
        world: World,
        split: str,
        tokenizer: Tokenizer,
        mode: str = "benchmark",
        instances: list[NDHInstance] | None = None,
    ) -> EpisodeSet:
        instances = bench.split(split) if instances is None else instances
        m = len(instances)
        ids = [tokenizer.encode(inst.dialog, inst.target) for inst in instances]
        tokens = np.zeros((m, max(map(len, ids))), dtype=np.int64)
        for k, row in enumerate(ids):
            tokens[k, : len(row)] = row
        geometry = EpisodeGeometry.build(bench, world, instances, mode=mode)
        target_label = np.array([int(object_label(inst.target)) for inst in instances], dtype=np.int64)
        return cls(split, instances, tokens, np.array([len(r) for r in ids]), geometry, target_label)


def goal_distance(world: World, episodes: EpisodeSet, idx: np.ndarray, node: np.ndarray) -> np.ndarray:
    """Topological distance (metres) from global nodes to each episode's goal node."""
    g = episodes.geometry
    return g.goal_dist[idx, node - world.offset[g.maze[idx]]]
