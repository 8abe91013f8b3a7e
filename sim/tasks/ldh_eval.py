"""LDH metrics and the non-learned localizers.

A localizer gives a belief over the maze's navigable nodes; a point prediction is a one-hot
belief, and `random` is the uniform one, so its scores are exact expectations, not samples.
TD is the shortest-path distance on the benchmark graph (mode "benchmark", as the NDH metrics)
from the predicted node to the node nearest the true position; Euclidean error is measured
from the predicted node's position; accuracy within r counts TD <= r. Predictions range over
the maze's main component (the largest set of mutually reachable nodes), which the map alone
determines, so no prediction has an infinite TD to a robot standing in it.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, fields
from functools import cached_property
from pathlib import Path
from typing import Any, NotRequired, Protocol, TypedDict

import numpy as np

from sim.core.metrics import group_by, mean_std
from sim.core.navgraph import NavGraph
from sim.tasks.benchmark import Benchmark
from sim.tasks.ldh import LDHInstance
from sim.tasks.ldh_features import maze_views, mentions

ACC_RADII_M = (0.25, 0.5, 1.0)


@dataclass(frozen=True, eq=False)
class MazeContext:
    """A maze as localizers see it: graph, per-pose views, and the main component."""

    run: str
    graph: NavGraph
    views: np.ndarray | None = None  # (N, 8, sectors, labels, 2), see pose_views; the language localizers' only

    @property
    def required_views(self) -> np.ndarray:
        """`views`, for the localizers that read them: an error where the context has none."""
        if self.views is None:
            raise ValueError(f"maze {self.run!r}: this context was built without views")
        return self.views

    @cached_property
    def main(self) -> np.ndarray:
        """Boolean (N,): nodes of the largest set of mutually reachable nodes."""
        reach = np.isfinite(self.graph.dist)
        main: np.ndarray = reach[int(reach.sum(axis=1).argmax())]
        return main

    @cached_property
    def center(self) -> int:
        """The main-component node with the smallest mean TD to all main-component nodes."""
        main = np.flatnonzero(self.main)
        return int(main[self.graph.dist[np.ix_(main, main)].mean(axis=1).argmin()])

    def node_at(self, x: float, y: float) -> int:
        """The main-component node nearest a point (a person's click on the map)."""
        main = np.flatnonzero(self.main)
        return int(main[np.hypot(*(self.graph.nodes[main] - (x, y)).T).argmin()])

    def uniform(self) -> np.ndarray:
        return np.asarray(self.main / self.main.sum())

    def one_hot(self, node: int) -> np.ndarray:
        out = np.zeros(self.graph.n)
        out[node] = 1.0
        return out

    def decide(self, pose_logits: np.ndarray) -> int:
        """The main-component node minimising expected TD under softmax(pose_logits (N, 8))."""
        logits = np.where(self.main[:, None], pose_logits, -np.inf)
        p = np.exp(logits - logits.max())
        node_p = p.sum(axis=1) / p.sum()
        main = np.flatnonzero(self.main)
        expected = self.graph.dist[np.ix_(main, main)] @ node_p[main]
        return int(main[expected.argmin()])


class MazeContexts:
    """Contexts per run of a benchmark, built once (graphs and ray tables are cached on disk)."""

    def __init__(self, bench: Benchmark):
        self.bench = bench
        self._contexts: dict[str, MazeContext] = {}

    def __getitem__(self, run: str) -> MazeContext:
        if run not in self._contexts:
            graph = self.bench.graph(run, "benchmark")
            self._contexts[run] = MazeContext(run, graph, maze_views(self.bench.maze(run), graph, self.bench.cache_dir))
        return self._contexts[run]


class Localizer(Protocol):
    def __call__(self, inst: LDHInstance, ctx: MazeContext) -> np.ndarray:
        """A belief (N,) over the maze's nodes, summing to 1."""


def random_localizer(inst: LDHInstance, ctx: MazeContext) -> np.ndarray:
    return ctx.uniform()


def center_localizer(inst: LDHInstance, ctx: MazeContext) -> np.ndarray:
    return ctx.one_hot(ctx.center)


VISIBLE_FLOOR = 0.02  # likelihood of a named label that the sector does not see


def colour_features(views: np.ndarray, far_weight: float = 0.5) -> np.ndarray:
    """(N, 8, MENTION_FEATURES) float32: per pose, the log-likelihood of one mention of each
    (sector, label): the log share of that sector's rays that hit the label (far hits count
    `far_weight`), for a label named without a direction the best sector's."""
    seen = views[..., 0] + far_weight * views[..., 1]  # (N, 8, sectors, labels)
    log_seen = np.log(VISIBLE_FLOOR + seen)
    return (
        np.concatenate([log_seen, log_seen.max(axis=2, keepdims=True)], axis=2)
        .reshape(*views.shape[:2], -1)
        .astype(np.float32)
    )


def colour_logits(counts: np.ndarray, views: np.ndarray) -> np.ndarray:
    """(N, 8) log-likelihood of the Driver's mentions (sectors x labels, see
    `sim.tasks.ldh_features.mentions`) at each pose, mentions taken as independent."""
    logits: np.ndarray = colour_features(views) @ counts.ravel()
    return logits


def colours_localizer(inst: LDHInstance, ctx: MazeContext) -> np.ndarray:
    """The language baseline: match the colours and objects the Driver names, with the side
    named, against what each pose sees, and take the expected-TD-minimising node."""
    return ctx.one_hot(ctx.decide(colour_logits(mentions(inst.dialog), ctx.required_views)))


BASELINES: dict[str, Localizer] = {"random": random_localizer, "center": center_localizer, "colours": colours_localizer}


@dataclass(frozen=True)
class LDHResult:
    split: str
    variant: str
    inst_idx: int
    agent: str
    seed: int
    run: str
    true_x: float
    true_y: float
    td: float  # expected over the belief
    euclid: float
    acc: tuple[float, ...]  # per ACC_RADII_M


# `write_csv`'s header: a column per field, the accuracy one per radius.
CSV_COLUMNS = (*(f.name for f in fields(LDHResult) if f.name != "acc"), *(f"acc_{r}" for r in ACC_RADII_M))


def score(ctx: MazeContext, belief: np.ndarray, inst: LDHInstance) -> tuple[float, float, tuple[float, ...]]:
    """Expected (TD, Euclidean error, accuracy per radius) of a belief over nodes."""
    true = ctx.graph.nearest_node(inst.x, inst.y)
    td = ctx.graph.dist[:, true]
    euclid = np.linalg.norm(ctx.graph.nodes - np.asarray((inst.x, inst.y)), axis=1)
    support = belief > 0
    b, td, euclid = belief[support], td[support], euclid[support]
    return float(b @ td), float(b @ euclid), tuple(float(b @ (td <= r)) for r in ACC_RADII_M)


def evaluate(
    bench: Benchmark,
    split: str,
    instances: list[LDHInstance],
    agents: dict[str, Localizer],
    seed: int = 0,
    contexts: MazeContexts | None = None,
    progress: Callable[[Iterable[Any]], Iterable[Any]] = lambda it: it,
) -> list[LDHResult]:
    contexts = contexts or MazeContexts(bench)
    out = []
    for inst in progress(instances):
        ctx = contexts[inst.run]
        for name, localizer in agents.items():
            td, euclid, acc = score(ctx, localizer(inst, ctx), inst)
            out.append(
                LDHResult(
                    split, inst.variant.value, inst.inst_idx, name, seed, inst.run, inst.x, inst.y, td, euclid, acc
                )
            )
    return out


class LDHSummary(TypedDict):
    """The JSON of `robotslang eval ldh`."""

    split: str
    variant: str
    n: int
    agents: dict[str, dict[str, float]]  # td_mean, td_std, td_median, euclid_mean, acc_<radius>
    tests: NotRequired[list[dict[str, object]]]  # `eval ldh --versus`: paired tests (models.stats.Comparison)


def summarize_agent(results: list[LDHResult]) -> dict[str, float]:
    """Means over instances (seeds averaged per instance first); td_std is the sample std."""
    by_inst = group_by(results, lambda r: r.inst_idx)
    td = [float(np.mean([r.td for r in rs])) for rs in by_inst.values()]
    euclid = [float(np.mean([r.euclid for r in rs])) for rs in by_inst.values()]
    td_mean, td_std = mean_std(td)
    out = {
        "td_mean": td_mean,
        "td_std": td_std,
        "td_median": float(np.median(td)) if td else math.nan,
        "euclid_mean": mean_std(euclid)[0],
    }
    for k, radius in enumerate(ACC_RADII_M):
        out[f"acc_{radius}"] = mean_std([float(np.mean([r.acc[k] for r in rs])) for rs in by_inst.values()])[0]
    return out


def summarize(split: str, variant: str, n: int, results: list[LDHResult]) -> LDHSummary:
    """The JSON of `robotslang eval ldh`: {split, variant, n, agents: {NAME: {...}}}."""
    agents = group_by(results, lambda r: r.agent)
    return {
        "split": split,
        "variant": variant,
        "n": n,
        "agents": {name: summarize_agent(rs) for name, rs in agents.items()},
    }


def write_csv(path: str | Path, results: Iterable[LDHResult]) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(CSV_COLUMNS)
        for r in results:
            row = asdict(r)
            acc = row.pop("acc")
            writer.writerow([*row.values(), *acc])
