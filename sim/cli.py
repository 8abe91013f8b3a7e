"""`robotslang eval baselines`, `robotslang mazes ...`, `robotslang sim ...`."""

from __future__ import annotations

import typer


def register(root: typer.Typer, eval_app: typer.Typer) -> None:
    """Mount the simulator's commands on the root CLI."""
    from sim import eval_cli

    eval_app.command("baselines")(eval_cli.eval_baselines)
    from sim import bench_cli

    bench_cli.register(root)
    from sim import play

    play.register(root)
    from sim import mazes_cli

    mazes_cli.register(root)
