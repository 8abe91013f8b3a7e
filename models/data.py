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
from sim.core.stepper import BatchStepper
from sim.core.world import EpisodeGeometry, World
from sim.tasks.benchmark import Benchmark, NDHInstance


@dataclass
class EpisodeSet:
    split: str
    instances: list[NDHInstance]
    tokens: np.ndarray  # (M, T) int64 ids, 0-padded
    lengths: np.ndarray  # (M,)
    # The instances' EpisodeGeometry on the world:
    maze: np.ndarray  # (M,) index into World.names
    start_node: np.ndarray  # (M,) global
    start_heading: np.ndarray  # (M,)
    goal_node: np.ndarray  # (M,) global
    goal_dist: np.ndarray  # (M, Nmax) shortest-path metres to the goal from each local node
    goal_next: np.ndarray  # (M, Nmax) next local node toward the goal; -1 where no path
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
        return cls(
            split, instances, tokens, np.array([len(r) for r in ids]), target_label=target_label, **geometry.__dict__
        )

    def start(self, stepper: BatchStepper, idx: np.ndarray) -> None:
        """Start episodes `idx` of this set in every position of `stepper` (one per index)."""
        stepper.start(
            np.arange(len(idx)),
            self.start_node[idx],
            self.start_heading[idx],
            self.goal_node[idx],
            self.goal_dist[idx],
            self.goal_next[idx],
        )


def goal_distance(world: World, episodes: EpisodeSet, idx: np.ndarray, node: np.ndarray) -> np.ndarray:
    """Topological distance (metres) from global nodes to each episode's goal node."""
    return episodes.goal_dist[idx, node - world.offset[episodes.maze[idx]]]


def splits_runs(bench: Benchmark, splits: list[str]) -> list[str]:
    """The runs that the given splits use, sorted."""
    return sorted({inst.run for s in splits for inst in bench.split(s)}, key=lambda r: (len(r), r))
