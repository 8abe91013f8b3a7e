"""Significance of differences between Driver configurations, as the paper tests them.

Pairs are NDH instances: each configuration's metric is first averaged over its seeds per
instance (the per-trajectory micro-average), then two configurations are compared with a
paired t-test, and the p-values of the whole family of comparisons are corrected with
Benjamini-Yekutieli (which holds under any dependence between the tests).

That tests a claim across instances for these particular training runs. For a claim across
training runs, `seed_tests` takes each seed's mean over instances as one observation and
compares two configurations with a paired t-test over seeds (seed k of A against seed k of B):
n is the number of seeds, so it needs a difference that holds on every seed to be significant.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Protocol

import numpy as np
from scipy import stats

ALPHA = 0.05


class Result(Protocol):
    """One row of results as the tests read it (`sim.core.metrics.EpisodeResult`, `sim.tasks.ldh_eval.LDHResult`):
    its configuration, seed and instance, and the metric by name."""

    @property
    def agent(self) -> str: ...

    @property
    def seed(self) -> int: ...

    @property
    def inst_idx(self) -> int: ...


@dataclass(frozen=True)
class Comparison:
    a: str
    b: str
    metric: str
    n: int
    mean_a: float
    mean_b: float
    t: float
    p: float
    p_adjusted: float
    significant: bool
    unit: str = "instance"  # what the pairs are: NDH instances, or training seeds

    def to_dict(self) -> dict:
        return asdict(self)


def per_instance(results: Sequence[Result], metric: str) -> dict[str, dict[int, float]]:
    """{agent: {inst_idx: metric averaged over seeds}}."""
    values: dict[str, dict[int, list[float]]] = defaultdict(lambda: defaultdict(list))
    for r in results:
        values[r.agent][r.inst_idx].append(float(getattr(r, metric)))
    return {agent: {k: float(np.mean(v)) for k, v in by_inst.items()} for agent, by_inst in values.items()}


def per_seed(results: Sequence[Result], metric: str) -> dict[str, dict[int, float]]:
    """{agent: {seed: metric averaged over that seed's instances}}; an infinite TD (goal
    unreachable from where the agent stopped) is left out, as in `sim.core.metrics`."""
    values: dict[str, dict[int, list[float]]] = defaultdict(lambda: defaultdict(list))
    for r in results:
        v = float(getattr(r, metric))
        if np.isfinite(v):
            values[r.agent][r.seed].append(v)
    return {agent: {s: float(np.mean(v)) for s, v in by_seed.items()} for agent, by_seed in values.items()}


def paired_tests(
    results: Sequence[Result], pairs: list[tuple[str, str]], metrics: tuple[str, ...] = ("td",), alpha: float = ALPHA
) -> list[Comparison]:
    """Paired t-tests over instances of each (a, b) pair on each metric, BY-corrected over all."""
    return _tests(per_instance, "instance", results, pairs, metrics, alpha)


def seed_tests(
    results: Sequence[Result], pairs: list[tuple[str, str]], metrics: tuple[str, ...] = ("td",), alpha: float = ALPHA
) -> list[Comparison]:
    """Paired t-tests over per-seed means of each (a, b) pair on each metric, BY-corrected."""
    return _tests(per_seed, "seed", results, pairs, metrics, alpha)


def _tests(
    table_of,
    unit: str,
    results: Sequence[Result],
    pairs: list[tuple[str, str]],
    metrics: tuple[str, ...],
    alpha: float,
) -> list[Comparison]:
    raw = []
    for metric in metrics:
        table = table_of(results, metric)
        for a, b in pairs:
            for name in (a, b):
                if name not in table:
                    raise ValueError(f"no results for configuration {name!r}; have {', '.join(sorted(table))}")
            common = sorted(set(table[a]) & set(table[b]))
            x = np.array([table[a][k] for k in common])
            y = np.array([table[b][k] for k in common])
            finite = np.isfinite(x) & np.isfinite(y)
            x, y = x[finite], y[finite]
            if len(x) < 2:
                raise ValueError(f"{a} vs {b}: fewer than two {unit}s in common")
            t, p = stats.ttest_rel(x, y)
            if np.isnan(p):  # identical columns: no evidence of any difference
                t, p = 0.0, 1.0
            raw.append((a, b, metric, len(x), float(x.mean()), float(y.mean()), float(t), float(p)))
    adjusted = stats.false_discovery_control([r[-1] for r in raw], method="by") if raw else []
    return [Comparison(*r, p_adjusted=float(q), significant=bool(q < alpha), unit=unit) for r, q in zip(raw, adjusted)]
