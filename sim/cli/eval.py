"""`robotslang eval baselines`: Immediate Stop, Random and Shortest on an NDH split."""

from __future__ import annotations

import json
from collections.abc import Iterable
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.console import Console
from rich.table import Table

from sim.tasks.baselines import BASELINES
from sim.tasks.benchmark import Benchmark, BenchmarkError, Split

if TYPE_CHECKING:
    from sim.core.metrics import EpisodeResult, Summary

BENCHMARK_OPTION = typer.Option(
    ..., "--benchmark", envvar="ROBOTSLANG_BENCHMARK", help="A RobotSlangBenchmark clone (or an export in its layout)."
)


def open_benchmark(path: Path) -> Benchmark:
    """The benchmark at `path`, or a usage error that names what is missing there."""
    try:
        return Benchmark(path)
    except BenchmarkError as e:
        raise typer.BadParameter(str(e), param_hint="--benchmark") from None


class StartMode(StrEnum):
    episode = "episode"
    recorded = "recorded"


class EdgeMode(StrEnum):
    benchmark = "benchmark"
    exact = "exact"


def parse_list(text: str, kind: str, allowed: Iterable[str] | None = None) -> list[str]:
    items = [part.strip() for part in text.split(",") if part.strip()]
    if not items:
        raise typer.BadParameter(f"no {kind} given")
    if allowed is not None:
        unknown = [i for i in items if i not in allowed]
        if unknown:
            raise typer.BadParameter(f"unknown {kind} {', '.join(unknown)}; expected {', '.join(allowed)}")
    return items


def parse_seeds(text: str) -> list[int]:
    try:
        return [int(s) for s in parse_list(text, "seed")]
    except ValueError:
        raise typer.BadParameter(f"seeds must be integers, got {text!r}", param_hint="--seeds") from None


def print_results(split: str, results: list[EpisodeResult], as_json: bool, per_instance: Path | None) -> None:
    """The split's summary, as JSON or a table, and a CSV row per result where asked."""
    from sim.core.metrics import summarize, write_csv

    summary = summarize(split, results)
    if per_instance is not None:
        write_csv(per_instance, results)
    if as_json:
        typer.echo(json.dumps(summary, indent=2))
    else:
        print_table(summary, Console())


def print_table(summary: Summary, console: Console) -> None:
    table = Table(title=f"{summary['split']} (n={summary['n']})")
    for col in ("agent", "TD", "OTD", "SR", "SPL", "steps"):
        table.add_column(col, justify="right" if col != "agent" else "left")
    for name, s in summary["agents"].items():
        table.add_row(
            name,
            f"{s['td_mean']:.2f} ± {s['td_std']:.2f}",
            f"{s['otd_mean']:.2f} ± {s['otd_std']:.2f}",
            f"{s['sr']:.3f}",
            f"{s['spl']:.3f}",
            f"{s['steps_mean']:.1f}",
        )
    console.print(table)
    for name, s in summary["agents"].items():
        if s.get("unreachable"):
            console.print(
                f"[yellow]{name}: {s['unreachable']} instances stopped where the goal is unreachable "
                f"(infinite TD, left out of the means)"
            )


def eval_baselines(
    benchmark: Path = BENCHMARK_OPTION,
    split: Split = typer.Option(Split.VAL_SEEN, help="NDH split."),
    agent: str = typer.Option("stop,random,shortest", help="Agents, comma-separated: stop, random, shortest."),
    start: StartMode = typer.Option(
        StartMode.episode,
        help="episode: the benchmark simulator's start; recorded: the instance's recorded pose (the paper's Stop row).",
    ),
    edges: EdgeMode = typer.Option(EdgeMode.benchmark, help="Graph edges: benchmark (as published) or exact."),
    seeds: str = typer.Option("0,1,2", help="Seeds for random agents, comma-separated."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table."),
    per_instance: Path | None = typer.Option(None, help="Write a CSV row per instance, agent and seed."),
) -> None:
    """Score the baseline Drivers on an NDH split (TD, OTD, SR, SPL)."""
    from sim.tasks.evaluation import evaluate_baselines

    agents = parse_list(agent, "agent", BASELINES)
    seed_list = parse_seeds(seeds)
    try:
        bench = open_benchmark(benchmark)
        results = evaluate_baselines(
            bench, split.value, agents, start=start.value, edges=edges.value, seeds=seed_list, progress=not as_json
        )
    except BenchmarkError as e:
        raise typer.BadParameter(str(e), param_hint="--benchmark") from None
    print_results(split.value, results, as_json, per_instance)
