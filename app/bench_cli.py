"""`robotslang bench sim`: the simulator's speed figures (`bench/sim.py`) from the command line.

bench/ is not in the installed packages: it is found in the checkout beside app/, so nothing in
sim/ needs to know it exists."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import typer

# bench/ lives in the checkout beside sim/, not in the installed packages.
CHECKOUT = Path(__file__).resolve().parent.parent


def bench_sim(
    benchmark: Path | None = typer.Option(
        None,
        "--benchmark",
        envvar="ROBOTSLANG_BENCHMARK",
        help="A RobotSlangBenchmark clone (default ../shared/robotslang).",
    ),
    maps: int | None = typer.Option(None, "--maps", min=1, help="Only the first N maps (default: all)."),
) -> None:
    """Print the simulator's speed: graph, all-pairs and ray-table builds, env steps, renders."""
    if not (CHECKOUT / "bench" / "sim.py").exists():
        raise typer.BadParameter(f"{CHECKOUT / 'bench'}: no bench/sim.py; run from a source checkout")
    if str(CHECKOUT) not in sys.path:
        sys.path.insert(0, str(CHECKOUT))
    bench = importlib.import_module("bench.sim")
    argv = [] if benchmark is None else ["--benchmark", str(benchmark)]
    bench.main(argv + ([] if maps is None else ["--maps", str(maps)]))


def register(root: typer.Typer) -> None:
    bench_app = typer.Typer(help="Speed benchmarks that print figures.", no_args_is_help=True)
    bench_app.command("sim")(bench_sim)
    root.add_typer(bench_app, name="bench")
