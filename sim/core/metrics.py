"""NDH metrics: topological distance (TD), oracle TD (OTD), success rate (SR) and SPL.

TD is the shortest-path distance on the benchmark graph from where the agent stopped to the
goal; OTD the smallest TD along its path; success is TD <= 0.508 m (two robot lengths); SPL
weights success by shortest / max(path length, shortest).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import TypedDict, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from sim.core.geometry import SUCCESS_RADIUS_M
from sim.core.navgraph import NavGraph

T = TypeVar("T")
K = TypeVar("K")


@dataclass(frozen=True)
class EpisodeResult:
    split: str
    inst_idx: int
    agent: str
    seed: int
    start_x: float
    start_y: float
    start_heading: float  # radians
    goal_x: float
    goal_y: float
    td: float
    otd: float
    steps: int  # moves made (forward, left, right), not counting the final stop
    success: bool
    spl: float

    @classmethod
    def from_row(cls, row: Mapping[str, str]) -> EpisodeResult:
        """A row of `write_csv`'s file."""
        return cls(
            row["split"],
            int(row["inst_idx"]),
            row["agent"],
            int(row["seed"]),
            float(row["start_x"]),
            float(row["start_y"]),
            float(row["start_heading"]),
            float(row["goal_x"]),
            float(row["goal_y"]),
            float(row["td"]),
            float(row["otd"]),
            int(row["steps"]),
            bool(int(row["success"])),
            float(row["spl"]),
        )

    @classmethod
    def scored(
        cls,
        split: str,
        inst_idx: int,
        agent: str,
        seed: int,
        start: tuple[float, float, float],
        goal: tuple[float, float],
        steps: int,
        score: TrajectoryScore,
    ) -> EpisodeResult:
        """An episode from its `start` (x, y, heading in radians), `goal` (x, y) and score."""
        return cls(split, inst_idx, agent, seed, *start, *goal, score.td, score.otd, steps, score.success, score.spl)


CSV_COLUMNS = tuple(f.name for f in fields(EpisodeResult))  # `write_csv`'s header


@dataclass(frozen=True)
class TrajectoryScore:
    td: float
    otd: float
    path_length: float
    shortest: float
    success: bool
    spl: float

    @classmethod
    def of(cls, td: float, otd: float, path_length: float, shortest: float) -> TrajectoryScore:
        """Success within the radius; SPL as the benchmark weighs it."""
        success = td <= SUCCESS_RADIUS_M
        spl = shortest / max(path_length, shortest) if success and shortest > 0 else float(success)
        return cls(td, otd, path_length, shortest, success, spl)


def score_trajectory(graph: NavGraph, nodes: Iterable[int], goal: int) -> TrajectoryScore:
    """Score the nodes an agent visited (first = start, last = where it stopped)."""
    nodes = np.asarray(list(nodes), dtype=np.int64)
    to_goal = graph.dist[nodes, goal]
    path_length = float(np.linalg.norm(np.diff(graph.nodes[nodes], axis=0), axis=1).sum())
    return TrajectoryScore.of(float(to_goal[-1]), float(to_goal.min()), path_length, float(to_goal[0]))


class AgentSummary(TypedDict):
    td_mean: float
    td_std: float
    otd_mean: float
    otd_std: float
    sr: float
    spl: float
    steps_mean: float
    unreachable: int  # instances left out of the means: the goal cannot be reached from the stop


class Summary(TypedDict):
    """The JSON of `robotslang eval baselines` / `eval ndh`."""

    split: str
    n: int
    agents: dict[str, AgentSummary]


def group_by(items: Iterable[T], key: Callable[[T], K]) -> dict[K, list[T]]:
    """`items` listed by `key`, keys in the order they first come."""
    groups: dict[K, list[T]] = {}
    for item in items:
        groups.setdefault(key(item), []).append(item)
    return groups


def mean_std(values: ArrayLike) -> tuple[float, float]:
    """Mean and sample std (ddof=1; 0 for one value), nan for none."""
    a = np.asarray(values)
    if a.size == 0:
        return math.nan, math.nan
    return float(a.mean()), float(a.std(ddof=1)) if a.size > 1 else 0.0


def summarize_agent(results: list[EpisodeResult]) -> AgentSummary:
    """Mean and sample std (ddof=1) over instances; seeds are averaged per instance first.

    Instances whose goal cannot be reached from where the agent stopped have an infinite TD:
    they are counted in `unreachable` and left out of the means, never silently averaged.
    """
    by_inst = group_by(results, lambda r: r.inst_idx)
    per = {
        k: {f: float(np.mean([getattr(r, f) for r in rs])) for f in ("td", "otd", "steps", "success", "spl")}
        for k, rs in by_inst.items()
    }
    td = np.array([p["td"] for p in per.values()])
    otd = np.array([p["otd"] for p in per.values()])
    finite = np.isfinite(td)
    td_mean, td_std = mean_std(td[finite])
    otd_mean, otd_std = mean_std(otd[np.isfinite(otd)])
    return {
        "td_mean": td_mean,
        "td_std": td_std,
        "otd_mean": otd_mean,
        "otd_std": otd_std,
        "sr": float(np.mean([p["success"] for p in per.values()])) if per else math.nan,
        "spl": float(np.mean([p["spl"] for p in per.values()])) if per else math.nan,
        "steps_mean": float(np.mean([p["steps"] for p in per.values()])) if per else math.nan,
        "unreachable": int((~finite).sum()),
    }


def summarize(split: str, results: list[EpisodeResult]) -> Summary:
    """The JSON of `robotslang eval baselines` / `eval ndh`: {split, n, agents: {NAME: {...}}}."""
    agents = group_by(results, lambda r: r.agent)
    n = len({r.inst_idx for r in results})
    return {"split": split, "n": n, "agents": {name: summarize_agent(rs) for name, rs in agents.items()}}


def write_csv(path: str | Path, results: Iterable[EpisodeResult]) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        for r in results:
            row = asdict(r)
            row["success"] = int(r.success)
            writer.writerow(row)


def read_csv(path: str | Path) -> list[EpisodeResult]:
    with Path(path).open() as f:
        return [EpisodeResult.from_row(row) for row in csv.DictReader(f)]
