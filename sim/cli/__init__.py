"""`robotslang eval baselines`, `robotslang mazes ...`, `robotslang sim play`: the simulator's commands."""

from __future__ import annotations

import typer


def register(root: typer.Typer, eval_app: typer.Typer) -> None:
    """Mount the simulator's commands on the root CLI."""
    from sim.cli import eval, mazes, play

    eval_app.command("baselines")(eval.eval_baselines)
    play.register(root)
    mazes.register(root)
