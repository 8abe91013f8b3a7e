"""Simulator speed on the benchmark's maps: `python -m bench.sim [--benchmark PATH] [--maps N]`.

Prints one figure per function below, then a table of all of them against the targets of the
design (2-core machine): all maps' graphs + all-pairs + ray tables in under 15 s, a single
environment step under 20 microseconds, batched stepping over 1,000,000 steps per second
with observations, first-person renders over 300 frames per second at 320x240.

Everything is built uncached (`use_cache=False`), so the figures are build costs, not disk reads.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
from rich.console import Console
from rich.table import Table
from tqdm import tqdm

from sim.batch_env import BatchNavEnv
from sim.benchmark import MAX_EPISODE_ACTIONS, Benchmark, BenchmarkError
from sim.dynamics import Pose
from sim.env import ENV_ID, NDHEnv
from sim.geometry import heading_angle
from sim.maze import Maze
from sim.navgraph import NavGraph
from sim.observations import RayTable
from sim.render import first_person

REPO = Path(__file__).resolve().parent.parent


@dataclass
class Figure:
    name: str
    value: float
    unit: str
    target: str = ""
    ok: bool | None = None  # None where there is no target


def default_benchmark() -> Path:
    env = os.environ.get("ROBOTSLANG_BENCHMARK")
    return Path(env) if env else REPO.parent / "shared" / "robotslang"


def _per_map(name: str, seconds: list[float]) -> list[Figure]:
    s = np.asarray(seconds)
    return [Figure(f"{name}, mean per map", 1e3 * s.mean(), "ms"),
            Figure(f"{name}, max per map", 1e3 * s.max(), "ms"),
            Figure(f"{name}, {len(s)} maps", float(s.sum()), "s")]


def bench_decode(benchmark: Benchmark, runs: list[str]) -> tuple[list[Maze], list[Figure]]:
    """PNG decode: both maps of a run to label grids (`Maze.from_dir`)."""
    mazes, seconds = [], []
    for run in tqdm(runs, desc="decode PNGs", unit="map"):
        t = time.perf_counter()
        mazes.append(Maze.from_dir(benchmark.root / "mazedata" / run))
        seconds.append(time.perf_counter() - t)
    return mazes, _per_map("PNG decode", seconds)


def bench_graphs(mazes: list[Maze], mode: str = "benchmark") -> tuple[list[NavGraph], list[float], list[Figure]]:
    """Navigation graph and exact all-pairs shortest paths, uncached."""
    graphs, seconds = [], []
    for maze in tqdm(mazes, desc=f"graphs ({mode})", unit="map"):
        t = time.perf_counter()
        graphs.append(NavGraph.build(maze, mode, use_cache=False))
        seconds.append(time.perf_counter() - t)
    return graphs, seconds, _per_map("graph + all-pairs", seconds)


def bench_rays(mazes: list[Maze], graphs: list[NavGraph]) -> tuple[list[RayTable], list[float], list[Figure]]:
    """Ray table (13 rays per node and heading), uncached."""
    tables, seconds = [], []
    for maze, graph in tqdm(list(zip(mazes, graphs)), desc="ray tables", unit="map"):
        t = time.perf_counter()
        tables.append(RayTable.build(maze, graph, use_cache=False))
        seconds.append(time.perf_counter() - t)
    return tables, seconds, _per_map("ray table", seconds)


def bench_single_env(mazes: list[Maze], episodes: int = 400, seed: int = 0) -> list[Figure]:
    """`NDHEnv.step` alone (unwrapped) and through `gymnasium.make`'s wrappers; random
    forward/left/right episodes of 120 moves on the first few maps, resets not timed."""
    rng = np.random.default_rng(seed)
    actions = rng.integers(0, 3, (episodes, MAX_EPISODE_ACTIONS)).tolist()
    wrapped = gym.make(ENV_ID, mazes=mazes[:4])
    figures = []
    for label, env in (("env step, unwrapped", wrapped.unwrapped), ("env step, gymnasium.make", wrapped)):
        env.reset(seed=seed)
        elapsed, n = 0.0, 0
        for episode in tqdm(actions, desc=label, unit="ep", leave=False):
            env.reset()  # not timed: the first episode in a maze builds its tables
            step = env.step
            t = time.perf_counter()
            for a in episode:
                step(a)
            elapsed += time.perf_counter() - t
            n += len(episode)
        us = 1e6 * elapsed / n
        unwrapped = isinstance(env, NDHEnv)
        figures.append(Figure(label, us, "us/step", "< 20 us" if unwrapped else "", us < 20 if unwrapped else None))
        figures.append(Figure(label.replace("step", "steps/s", 1), 1e6 / us, "steps/s"))
    return figures


def bench_batch(graphs: list[NavGraph], tables: list[RayTable], batch: int, steps: int = 300,
                seed: int = 0) -> list[Figure]:
    """`BatchNavEnv.step` with observations, episodes spread over all maps, random actions."""
    rng = np.random.default_rng(seed)
    env = BatchNavEnv(list(zip(graphs, tables)), max_actions=10 ** 9)  # keep every episode live
    worlds = rng.integers(len(graphs), size=batch)
    episodes = [(int(w), Pose(int(rng.integers(graphs[w].n)), int(rng.integers(8))),
                 int(rng.integers(graphs[w].n))) for w in worlds]
    env.reset(episodes)
    actions = rng.integers(0, 3, (steps, batch))
    for a in actions[:10]:
        env.step(a)
    t = time.perf_counter()
    for a in actions:
        env.step(a)
    rate = steps * batch / (time.perf_counter() - t)
    target = batch >= 1000
    return [Figure(f"batch env steps/s, batch {batch}", rate, "steps/s",
                   "> 1,000,000" if target else "", rate > 1e6 if target else None)]


def bench_first_person(maze: Maze, graph: NavGraph, frames: int = 300, size=(320, 240),
                       seed: int = 0) -> list[Figure]:
    """`sim.render.first_person` at 320x240 from random nodes and headings of one maze."""
    rng = np.random.default_rng(seed)
    nodes = rng.integers(graph.n, size=frames)
    headings = rng.integers(8, size=frames)
    first_person(maze, *graph.nodes[0], 0.0, size=size)  # the maze's scene is built once
    t = time.perf_counter()
    for node, k in zip(nodes, headings):
        x, y = graph.nodes[node]
        first_person(maze, float(x), float(y), float(heading_angle(k)), size=size)
    fps = frames / (time.perf_counter() - t)
    return [Figure(f"first-person render, {size[0]}x{size[1]}", fps, "fps", "> 300", fps > 300)]


def print_table(console: Console, figures: list[Figure], title: str) -> None:
    table = Table(title=title)
    for col, justify in (("figure", "left"), ("measured", "right"), ("unit", "left"), ("target", "left"), ("", "left")):
        table.add_column(col, justify=justify)
    for f in figures:
        value = f"{f.value:,.0f}" if f.value >= 1000 else f"{f.value:.3g}" if f.value < 10 else f"{f.value:.1f}"
        mark = "" if f.ok is None else "[green]ok[/]" if f.ok else "[red]missed[/]"
        table.add_row(f.name, value, f.unit, f.target, mark)
    console.print(table)


def main(argv: list[str] | None = None) -> list[Figure]:
    parser = argparse.ArgumentParser(prog="python -m bench.sim", description=__doc__.splitlines()[0])
    parser.add_argument("--benchmark", type=Path, default=default_benchmark(),
                        help="RobotSlangBenchmark clone (default: ROBOTSLANG_BENCHMARK or ../shared/robotslang)")
    parser.add_argument("--maps", type=int, default=None, help="only the first N maps (default: all)")
    args = parser.parse_args(argv)
    console = Console(width=max(Console().width, 100))
    try:
        benchmark = Benchmark(args.benchmark)
    except BenchmarkError as error:
        parser.error(str(error))
    runs = benchmark.runs()[: args.maps]
    if not runs:
        parser.error(f"--benchmark {args.benchmark}: no maps under mazedata/")
    console.print(f"[bold]bench.sim[/] on {len(runs)} maps of {benchmark.root}, {os.cpu_count()} CPUs")

    figures: list[Figure] = []
    mazes, fig = bench_decode(benchmark, runs)
    figures += fig
    graphs, graph_s, fig = bench_graphs(mazes)
    figures += fig
    tables, ray_s, fig = bench_rays(mazes, graphs)
    figures += fig
    total = sum(graph_s) + sum(ray_s)
    figures.append(Figure(f"graphs + all-pairs + rays, {len(runs)} maps", total, "s",
                          "< 15 s (178 maps)", total < 15 * len(runs) / 178))
    figures += bench_single_env(mazes)
    for batch in (100, 1000):
        figures += bench_batch(graphs, tables, batch)
    figures += bench_first_person(mazes[0], graphs[0])
    print_table(console, figures, "Simulator speed")
    return figures


if __name__ == "__main__":
    main()
