"""Simulator speed on the benchmark's maps: `python -m bench.sim [--benchmark PATH] [--maps N] [--json]`.

Each `bench_*` function below measures one figure; `main` prints them all in one table against
the targets (2-core machine): all maps' graphs + all-pairs + ray tables in under 15 s, batched
steps of the core with observations over 10,000,000 per second at batch 1000, first-person
renders over 1,000 frames per second at 320x240, and one student-forcing iteration of the NDH
learner at batch 100 (`rollout_iter_s`). `--json` prints one object with the keys
`all_maps_s`, `png_decode_s`, `env_step_us`, `batch_steps_per_s_1000`, `render_fps_320x240`
and `rollout_iter_s` (wall clock), so a script can hold them against targets; the machine's
load average goes to stderr beside them. The table also times the grid-march camera the render
replaced (`bench.render_reference`) on the same poses, and the speed-up.

Everything is built uncached (`use_cache=False`), so the figures are build costs, not disk reads.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
from rich.console import Console, JustifyMethod
from rich.table import Table
from tqdm import tqdm

from bench.render_reference import first_person as reference_first_person
from sim.core.geometry import heading_angle
from sim.core.maze import FIXED_MAP, WALLS_MAP, Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.core.stepper import MAX_EPISODE_ACTIONS, BatchStepper
from sim.core.world import World, goal_rows
from sim.robot.render import first_person
from sim.tasks.benchmark import Benchmark, BenchmarkError
from sim.tasks.env import ENV_ID, NDHEnv

REPO = Path(__file__).resolve().parent.parent


class Stopwatch:
    """Wall-clock and process CPU seconds, accumulated over `with` blocks. On a shared machine
    the CPU time is what the work costs; the wall time is what it cost this time."""

    def __init__(self):
        self.wall = self.cpu = 0.0

    def __enter__(self) -> Stopwatch:
        self._wall, self._cpu = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc) -> None:
        self.wall += time.perf_counter() - self._wall
        self.cpu += time.process_time() - self._cpu


@dataclass
class Figure:
    name: str
    wall: float
    cpu: float
    unit: str
    target: str = ""
    ok: bool | None = None  # on the wall-clock figure; None where there is no target


def default_benchmark() -> Path:
    env = os.environ.get("ROBOTSLANG_BENCHMARK")
    return Path(env) if env else REPO.parent / "shared" / "robotslang"


def _per_map(name: str, watches: list[Stopwatch]) -> list[Figure]:
    wall, cpu = np.array([w.wall for w in watches]), np.array([w.cpu for w in watches])
    return [
        Figure(f"{name}, mean per map", 1e3 * wall.mean(), 1e3 * cpu.mean(), "ms"),
        Figure(f"{name}, max per map", 1e3 * wall.max(), 1e3 * cpu.max(), "ms"),
        Figure(f"{name}, {len(watches)} maps", float(wall.sum()), float(cpu.sum()), "s"),
    ]


def _total(watches: list[Stopwatch]) -> Stopwatch:
    total = Stopwatch()
    total.wall, total.cpu = sum(w.wall for w in watches), sum(w.cpu for w in watches)
    return total


def bench_decode(benchmark: Benchmark, runs: list[str]) -> tuple[list[Maze], list[Figure]]:
    """PNG decode: both maps of a run to label grids (`Maze.from_dir`)."""
    mazes, watches = [], []
    for run in tqdm(runs, desc="decode PNGs", unit="map"):
        with Stopwatch() as watch:
            folder = benchmark.root / "mazedata" / run / "maze"
            walls = folder / WALLS_MAP
            mazes.append(
                Maze.from_png(folder / FIXED_MAP, walls if walls.exists() else None, name=run, use_cache=False)
            )
        watches.append(watch)
    return mazes, _per_map("PNG decode", watches)


def bench_graphs(mazes: list[Maze], mode: str = "benchmark") -> tuple[list[NavGraph], Stopwatch, list[Figure]]:
    """Navigation graph and exact all-pairs shortest paths, uncached."""
    graphs, watches = [], []
    for maze in tqdm(mazes, desc=f"graphs ({mode})", unit="map"):
        with Stopwatch() as watch:
            graphs.append(NavGraph.build(maze, mode, use_cache=False))
        watches.append(watch)
    return graphs, _total(watches), _per_map("graph + all-pairs", watches)


def bench_rays(mazes: list[Maze], graphs: list[NavGraph]) -> tuple[list[RayTable], Stopwatch, list[Figure]]:
    """Ray table (13 rays per node and heading), uncached."""
    tables, watches = [], []
    for maze, graph in tqdm(list(zip(mazes, graphs)), desc="ray tables", unit="map"):
        with Stopwatch() as watch:
            tables.append(RayTable.build(maze, graph, use_cache=False))
        watches.append(watch)
    return tables, _total(watches), _per_map("ray table", watches)


def bench_single_env(mazes: list[Maze], episodes: int = 400, seed: int = 0) -> list[Figure]:
    """`NDHEnv.step` alone (unwrapped) and through `gymnasium.make`'s wrappers; random
    forward/left/right episodes of 120 moves on the first few maps, resets not timed."""
    rng = np.random.default_rng(seed)
    actions = rng.integers(0, 3, (episodes, MAX_EPISODE_ACTIONS)).tolist()
    wrapped = gym.make(ENV_ID, mazes=mazes[:4])
    figures = []
    for label, env in (("env step, unwrapped", wrapped.unwrapped), ("env step, gymnasium.make", wrapped)):
        env.reset(seed=seed)
        watch = Stopwatch()
        for episode in tqdm(actions, desc=label, unit="ep", leave=False):
            env.reset()  # not timed: the first episode in a maze builds its tables
            step = env.step
            with watch:
                for a in episode:
                    step(a)
        n = episodes * MAX_EPISODE_ACTIONS
        us_wall, us_cpu = 1e6 * watch.wall / n, 1e6 * watch.cpu / n
        unwrapped = isinstance(env, NDHEnv)
        figures.append(
            Figure(
                label, us_wall, us_cpu, "us/step", "< 20 us" if unwrapped else "", us_wall < 20 if unwrapped else None
            )
        )
        figures.append(Figure(label.replace("step", "steps/s", 1), 1e6 / us_wall, 1e6 / us_cpu, "steps/s"))
    return figures


def bench_batch(graphs: list[NavGraph], world: World, batch: int, steps: int = 300, seed: int = 0) -> list[Figure]:
    """`BatchStepper.step` and its observations, episodes spread over all maps, random moves."""
    rng = np.random.default_rng(seed)
    stepper = BatchStepper(world, batch, max_actions=10**9)  # keep every episode live
    for k, m in enumerate(rng.integers(len(graphs), size=batch)):
        node, goal = int(rng.integers(graphs[m].n)), int(rng.integers(graphs[m].n))
        dist, hop = goal_rows(graphs[m], [goal])
        off = int(world.offset[m])
        stepper.start([k], [off + node], [int(rng.integers(8))], [off + goal], dist, hop)
    actions = rng.integers(0, 3, (steps, batch))
    assert world.obs is not None  # compiled with observations above
    obs = np.empty((batch, world.obs_features), dtype=world.obs.dtype)
    for a in actions[:10]:
        stepper.step(a)
        stepper.observations(out=obs)
    with Stopwatch() as watch:
        for a in actions:
            stepper.step(a)
            stepper.observations(out=obs)
    rate, rate_cpu = steps * batch / watch.wall, steps * batch / watch.cpu
    target = batch >= 1000
    return [
        Figure(
            f"batch steps/s with observations, batch {batch}",
            rate,
            rate_cpu,
            "steps/s",
            "> 10,000,000" if target else "",
            rate > 1e7 if target else None,
        )
    ]


def bench_rollout(benchmark: Benchmark, runs: list[str], iterations: int = 3, batch: int = 100) -> list[Figure]:
    """One student-forcing iteration of the NDH learner (rollout, loss, backward, Adam step) at
    batch 100 on the train instances of `runs` (all maps: the whole split), median of a few;
    the world comes from the cache. Torch on one thread: on a shared 2-core machine a second
    thread waits for the other's core (15 s against 0.9 s an iteration at load average 8)."""
    import torch

    from models.data import EpisodeSet
    from models.rollout import run_episodes
    from models.tokenizer import Tokenizer
    from models.train import TrainConfig, make_agent

    train = benchmark.split("train")
    instances = [i for i in train if i.run in set(runs)] or train[:batch]  # a few maps may hold none
    world = World.build(benchmark, sorted({i.run for i in instances}, key=lambda r: (len(r), r)), benchmark.cache_dir)
    batch = min(batch, len(instances))
    tokenizer = Tokenizer.from_dialogs((i.dialog, i.target) for i in instances)
    episodes = EpisodeSet.build(benchmark, world, "train", tokenizer, instances=instances)
    torch.set_num_threads(1)
    agent = make_agent(TrainConfig(feedback="student"), tokenizer, world.obs_features)
    optimizer = torch.optim.Adam(agent.parameters(), lr=1e-3)
    watches = []
    for it in range(iterations):
        idx = np.random.default_rng(it).choice(len(episodes), batch, replace=False)
        with Stopwatch() as watch:
            roll = run_episodes(
                agent, world, episodes, idx, "student", generator=torch.Generator().manual_seed(it), train=True
            )
            optimizer.zero_grad()
            assert roll.loss is not None  # a training rollout has its loss
            roll.loss.backward()
            optimizer.step()
        watches.append(watch)
    wall, cpu = float(np.median([w.wall for w in watches])), float(np.median([w.cpu for w in watches]))
    return [Figure(f"learner iteration, student forcing, batch {batch}", wall, cpu, "s")]


def bench_first_person(maze: Maze, graph: NavGraph, frames: int = 300, size=(320, 240), seed: int = 0) -> list[Figure]:
    """`sim.robot.render.first_person` at 320x240 from random nodes and headings of one maze."""
    rng = np.random.default_rng(seed)
    nodes = rng.integers(graph.n, size=frames)
    headings = rng.integers(8, size=frames)
    poses = [
        (float(graph.nodes[n][0]), float(graph.nodes[n][1]), float(heading_angle(k))) for n, k in zip(nodes, headings)
    ]
    watches = {}
    for render in (first_person, reference_first_person):
        render(maze, *poses[0], size=size)  # the maze's scene is built once
        with Stopwatch() as watches[render]:
            for pose in poses:
                render(maze, *pose, size=size)
    fps = frames / watches[first_person].wall
    old = frames / watches[reference_first_person].wall
    return [
        Figure(
            f"first-person render, {size[0]}x{size[1]}",
            fps,
            frames / watches[first_person].cpu,
            "fps",
            "> 1,000",
            fps > 1000,
        ),
        Figure("  the grid-march camera it replaced", old, frames / watches[reference_first_person].cpu, "fps"),
        Figure(
            "  speed-up, same process", fps / old, watches[reference_first_person].cpu / watches[first_person].cpu, "x"
        ),
    ]


def _number(v: float) -> str:
    return f"{v:,.0f}" if v >= 1000 else f"{v:.3g}" if v < 10 else f"{v:.1f}"


def print_table(console: Console, figures: list[Figure], title: str) -> None:
    table = Table(title=title)
    justified: tuple[tuple[str, JustifyMethod], ...] = (
        ("figure", "left"),
        ("wall clock", "right"),
        ("CPU time", "right"),
        ("unit", "left"),
        ("target", "left"),
        ("", "left"),
    )
    for col, justify in justified:
        table.add_column(col, justify=justify)
    for f in figures:
        mark = "" if f.ok is None else "[green]ok[/]" if f.ok else "[red]missed[/]"
        table.add_row(f.name, _number(f.wall), _number(f.cpu), f.unit, f.target, mark)
    console.print(table)


def main(argv: list[str] | None = None) -> list[Figure]:
    parser = argparse.ArgumentParser(prog="python -m bench.sim", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--benchmark",
        type=Path,
        default=default_benchmark(),
        help="RobotSlangBenchmark clone (default: ROBOTSLANG_BENCHMARK or ../shared/robotslang)",
    )
    parser.add_argument("--maps", type=int, default=None, help="only the first N maps (default: all)")
    parser.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    args = parser.parse_args(argv)
    # With --json, stdout holds the JSON alone: the progress and the header go to stderr.
    console = Console(width=max(Console().width, 110), stderr=args.json)
    try:
        benchmark = Benchmark(args.benchmark)
    except BenchmarkError as error:
        parser.error(str(error))
    runs = benchmark.runs()[: args.maps]
    if not runs:
        parser.error(f"--benchmark {args.benchmark}: no maps under mazedata/")
    console.print(
        f"[bold]bench.sim[/] on {len(runs)} maps of {benchmark.root}, {os.cpu_count()} CPUs, "
        f"load average {os.getloadavg()[0]:.2f}"
    )

    figures: list[Figure] = []
    mazes, decode = bench_decode(benchmark, runs)
    figures += decode
    graphs, graph_s, fig = bench_graphs(mazes)
    figures += fig
    tables, ray_s, fig = bench_rays(mazes, graphs)
    figures += fig
    all_maps = Figure(
        f"graphs + all-pairs + rays, {len(runs)} maps",
        graph_s.wall + ray_s.wall,
        graph_s.cpu + ray_s.cpu,
        "s",
        "< 15 s (all maps)",
        graph_s.wall + ray_s.wall < 15 * len(runs) / len(benchmark.runs()),
    )
    figures.append(all_maps)
    single = bench_single_env(mazes)
    figures += single
    world = World.compile([(run, maze, graph) for run, maze, graph in zip(runs, mazes, graphs)], rays=tables)
    del tables
    batched = [f for b in (100, 1000) for f in bench_batch(graphs, world, b)]
    figures += batched
    render = bench_first_person(mazes[0], graphs[0])
    figures += render
    rollout = bench_rollout(benchmark, runs)
    figures += rollout
    load = os.getloadavg()
    if args.json:
        print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}", file=sys.stderr)
        print(
            json.dumps(
                {
                    "all_maps_s": all_maps.wall,
                    "png_decode_s": decode[-1].wall,
                    "env_step_us": single[0].wall,
                    "batch_steps_per_s_1000": batched[-1].wall,
                    "render_fps_320x240": render[0].wall,
                    "rollout_iter_s": rollout[0].wall,
                }
            )
        )
    else:
        print_table(console, figures, f"Simulator speed (load average {load[0]:.2f} after the run)")
    return figures


if __name__ == "__main__":
    main()
