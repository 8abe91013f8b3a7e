"""`robotslang demo --trials N [--server URL]`."""

from __future__ import annotations

import typer
from rich.console import Console
from rich.progress import Progress

console = Console(stderr=True)


def register(root: typer.Typer) -> None:
    root.command("demo")(demo)


def demo(
    trials: int = typer.Option(1, "--trials", min=1, help="How many trials to play."),
    server: str | None = typer.Option(
        None,
        "--server",
        help="A running server on the same data "
        "directory (e.g. http://127.0.0.1:8000); by default the demo "
        "serves the app itself on a free loopback port.",
    ),
    parallel: int = typer.Option(1, "--parallel", min=1, help="Trials played at the same time."),
    pace: float | None = typer.Option(
        None,
        "--pace",
        min=0.0,
        help="Seconds between the Driver's "
        "moves and the Commander's lines (default: just above the "
        "server's minimum move interval).",
    ),
    seed: int = typer.Option(0, "--seed", help="Seed of targets, mistakes and questions."),
) -> None:
    """Play complete simulator trials with a scripted Commander and Driver over the trial sockets,
    so that every page, the leaderboard, replays and exports have content."""
    import asyncio  # here, so that every other command starts without it

    from app.demo.players import DemoError
    from app.demo.runner import Demo
    from app.settings import Settings

    settings = Settings()
    runner = Demo(settings, seed=seed, pace_s=pace)
    try:
        with Progress(console=console) as progress:
            bar = progress.add_task("demo trials", total=trials)
            results = asyncio.run(runner.run(trials, server, parallel, on_done=lambda r: progress.advance(bar)))
    except DemoError as err:
        console.print(f"[red]error:[/red] {err}", soft_wrap=True)
        raise typer.Exit(1) from None
    failed = 0
    for r in results:
        line = f"trial {r.trial_id}: maze {r.maze}, targets {', '.join(r.targets)}: {r.phase}, {r.moves} moves"
        if r.error:
            failed += 1
            line += f" [red]({r.error})[/red]"
        console.print(line, soft_wrap=True)
    console.print(
        f"data in {settings.data_dir.resolve()}; see /leaderboard, and `robotslang export all --format mcap --out DIR`"
    )
    if failed:
        raise typer.Exit(1)
