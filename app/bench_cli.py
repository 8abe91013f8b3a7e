"""`robotslang bench sim`: the simulator's speed figures (`bench.sim`, an installed package of
the project like app/ and sim/) from the command line."""

from __future__ import annotations

from pathlib import Path

import typer


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
    from bench import sim  # its dependencies load only for this command

    argv = [] if benchmark is None else ["--benchmark", str(benchmark)]
    sim.main(argv + ([] if maps is None else ["--maps", str(maps)]))


def register(root: typer.Typer) -> None:
    bench_app = typer.Typer(help="Speed benchmarks that print figures.", no_args_is_help=True)
    bench_app.command("sim")(bench_sim)
    root.add_typer(bench_app, name="bench")
