"""`robotslang eval baselines`, `robotslang mazes ...`, `robotslang sim play`: the simulator's commands."""

from __future__ import annotations

import typer


def register(root: typer.Typer, eval_app: typer.Typer) -> None:
    """Mount the simulator's commands on the root CLI."""
    from sim.cli import eval, mazes, play

    eval_app.command("baselines")(eval.eval_baselines)
    sim_app = typer.Typer(help="The replay simulator by hand.", no_args_is_help=True)
    sim_app.command("play")(play.play)
    root.add_typer(sim_app, name="sim")
    root.add_typer(mazes.app, name="mazes")
