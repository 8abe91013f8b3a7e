"""The NDH baselines over a benchmark split, on the simulator core, scored with the NDH metrics.

`evaluate_baselines` runs every (instance, agent, seed) episode of a split as one batch of
`BatchStepper`: Immediate Stop, Shortest (the core's teacher) and Random.

The Random agent draws from its own stream per (seed, instance), `episode_seed`, as a policy
played one pose at a time would with `Generator.choice` (the tests' reference): a choice of 2 or
3 actions is Lemire's bounded draw on one 32-bit word of the stream, so the batch reads the same
words and gets the same actions (and redraws where Lemire's method rejects, as numpy does).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from sim.core.dynamics import Action
from sim.core.geometry import heading_angle
from sim.core.metrics import EpisodeResult, TrajectoryScore
from sim.core.stepper import MAX_EPISODE_ACTIONS, BatchStepper
from sim.core.world import World
from sim.tasks.baselines import BASELINES
from sim.tasks.benchmark import START_MODES, Benchmark, NDHInstance
from sim.tasks.episode_geometry import EpisodeGeometry

_STREAM_WORDS = 2 * MAX_EPISODE_ACTIONS  # 32-bit words drawn per Random episode up front


def episode_seed(seed: int, inst_idx: int) -> np.random.Generator:
    """One independent stream per (seed, instance): results do not depend on instance order."""
    return np.random.default_rng([seed, inst_idx])


class _RandomDraws:
    """Per episode, `Generator.choice` among 2 or 3 actions, vectorised over the batch."""

    def __init__(self, generators: list[np.random.Generator]):
        self.generators = generators
        self.words = np.stack([self._draw(g) for g in generators])  # (B, W) uint64
        self.used = np.zeros(len(generators), dtype=np.int64)

    @staticmethod
    def _draw(generator: np.random.Generator) -> np.ndarray:
        return generator.integers(0, 2**32 - 1, size=_STREAM_WORDS, dtype=np.uint32, endpoint=True).astype(np.uint64)

    def choice(self, n: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """An index in [0, n) for each episode in `rows`, from its next word(s)."""
        n = n.astype(np.uint64)
        threshold = (np.uint64(2**32) - n) % n
        out = np.empty(rows.size, dtype=np.int64)
        todo = np.arange(rows.size)
        while todo.size:
            r = rows[todo]
            if (self.used[r] >= self.words.shape[1]).any():  # a long run of rejections
                self.words = np.concatenate([self.words, np.stack([self._draw(g) for g in self.generators])], axis=1)
            m = self.words[r, self.used[r]] * n[todo]
            self.used[r] += 1
            accepted = (m & np.uint64(0xFFFFFFFF)) >= threshold[todo]
            out[todo[accepted]] = (m[accepted] >> np.uint64(32)).astype(np.int64)
            todo = todo[~accepted]
        return out


def evaluate_baselines(
    benchmark: Benchmark,
    split: str,
    agents: Iterable[str],
    start: str = "episode",
    edges: str = "benchmark",
    seeds: Iterable[int] = (0,),
    instances: list[NDHInstance] | None = None,
    progress: bool = True,
) -> list[EpisodeResult]:
    """Every (instance, agent, seed) episode of a split, scored on the `edges` graph; rows in
    instance, agent, seed order."""
    agents, seeds = list(agents), list(seeds)
    for name in agents:
        if name not in BASELINES:
            raise ValueError(f"unknown agent {name!r}; expected one of {', '.join(BASELINES)}")
    if start not in START_MODES:
        raise ValueError(f"unknown start {start!r}; expected one of {', '.join(START_MODES)}")
    instances = benchmark.split(split) if instances is None else instances
    runs = sorted({inst.run for inst in instances}, key=lambda r: (len(r), r))
    world = World.build(benchmark, runs, benchmark.cache_dir, mode=edges, observations=False, progress=progress)
    geometry = EpisodeGeometry.build(benchmark, world, instances, start=start, mode=edges)

    # One episode per (instance, agent, seed), in the order the rows are reported.
    order = [(k, name, seed) for k in range(len(instances)) for name in agents for seed in seeds]
    inst = np.array([k for k, _, _ in order], dtype=np.int64)
    agent = np.array([name for _, name, _ in order])
    stepper = BatchStepper(world, len(order), record=True)
    geometry.start(stepper, inst)
    stop, shortest, random = (np.flatnonzero(agent == name) for name in ("stop", "shortest", "random"))
    draws = (
        _RandomDraws([episode_seed(seed, instances[k].inst_idx) for k, name, seed in order if name == "random"])
        if random.size
        else None
    )
    actions = np.full(len(order), Action.STOP, dtype=np.int64)
    while not stepper.done.all():
        actions[shortest] = stepper.teacher_actions()[shortest]
        if draws is not None:  # the random agent plays
            # Left or right where forward would collide, else forward, left or right.
            blocked = stepper.forward_blocked()[random]
            pick = draws.choice(np.where(blocked, 2, 3), np.arange(random.size))
            actions[random] = np.where(blocked, Action.LEFT + pick, pick)
        actions[stop] = Action.STOP
        stepper.step(actions)

    # Path lengths as `sim.core.metrics.score_trajectory` sums them (each episode's step lengths,
    # one contiguous row summed alone), so SPL matches to the bit.
    xy = np.asarray(world.xy)[stepper.visited()]  # (T + 1, B, 2)
    moves = np.ascontiguousarray(np.sqrt(np.square(np.diff(xy, axis=0)).sum(axis=2)).T)  # (B, T)
    path_length = [float(moves[e, :n].sum()) for e, n in enumerate(stepper.steps)]
    start_xy = xy[0]
    results = []
    for e, (k, name, seed) in enumerate(order):
        score = TrajectoryScore.of(
            float(stepper.td[e]), float(stepper.otd[e]), path_length[e], float(stepper.shortest[e])
        )
        pose = (float(start_xy[e, 0]), float(start_xy[e, 1]), float(heading_angle(int(geometry.start_heading[k]))))
        instance = instances[k]
        results.append(
            EpisodeResult.scored(
                split, instance.inst_idx, name, seed, pose, instance.target_pose, int(stepper.steps[e]), score
            )
        )
    return results
