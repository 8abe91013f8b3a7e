"""Server memory over a study: simulator trials on every maze of the library, one after another,
`--live` of them running at a time (each opened as a seat would open it, then aborted), in one
process as the server runs them. Prints the RSS of the process and of its render processes
(`RENDER_PROCESSES`) together: at the start, its peak and at the end, and how many mazes and
graphs the process still holds.

    ROBOTSLANG_BENCHMARK=../shared/robotslang python -m bench.memory --live 8
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import os
import tempfile
from pathlib import Path

from rich.console import Console
from rich.progress import Progress

from app.main import create_app
from app.settings import Settings
from bench.live import ServerProcesses, team_trial
from bench.report import load_average

console = Console()


def rss_mb() -> float:
    """This process's RSS and its children's (the render processes), MB."""
    return ServerProcesses(os.getpid()).sample_rss()


async def study(services, live: int, limit: int | None) -> dict:
    names = services.mazes.names()[:limit]
    running: collections.deque = collections.deque()
    start, peak = rss_mb(), 0.0
    with Progress(console=console, transient=True) as progress:
        bar = progress.add_task(f"trials on {len(names)} mazes, {live} at a time", total=len(names))
        for i, maze in enumerate(names):
            with services.db.begin() as db:
                trial = team_trial(db, f"mem-team-{i}", maze, names, services.clock.now_ns())
            runtime = await services.hub.local(trial)
            while runtime.state.last_frame_id is None:  # its first frame, as a seat would see it
                await asyncio.sleep(0.01)
            running.append(runtime)
            if len(running) > live:
                running.popleft().abort()
                await asyncio.sleep(0.05)  # the trial ends and leaves the process
            peak = max(peak, rss_mb())
            progress.update(bar, advance=1, description=f"trials on {len(names)} mazes, RSS {rss_mb():.0f} MB")
    while running:
        running.popleft().abort()
    await asyncio.sleep(0.2)
    return {
        "mazes": len(names),
        "live": live,
        "rss_start_mb": round(start, 1),
        "rss_peak_mb": round(peak, 1),
        "rss_end_mb": round(rss_mb(), 1),
        "mazes_held": len(services.mazes.load),
        "graphs_held": len(services.mazes.graph),
        "live_trials_left": len(services.hub.live()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--live", type=int, default=8, help="trials running at a time")
    parser.add_argument("--mazes", type=int, help="only the first N mazes of the library")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="robotslang-memory-") as tmp:
        settings = Settings(data_dir=Path(tmp) / "var", secret_key="memory")
        if settings.benchmark is None:
            console.print("[yellow]ROBOTSLANG_BENCHMARK is not set: only the bundled mazes[/]")
        services = create_app(settings).state.services
        figures = asyncio.run(study(services, args.live, args.mazes))
    console.print(
        f"[bold]bench.memory[/]: trials on {figures['mazes']} mazes, {figures['live']} live at a time "
        f"(load average {load_average()})"
    )
    console.print(
        f"  RSS start {figures['rss_start_mb']:.0f} MB, peak {figures['rss_peak_mb']:.0f} MB, "
        f"end {figures['rss_end_mb']:.0f} MB; mazes held {figures['mazes_held']}, "
        f"graphs held {figures['graphs_held']}"
    )
    print(figures)


if __name__ == "__main__":
    main()
