"""`robotslang eval selfplay`: whole trials with agents in both seats, offline (`sim.agents.selfplay`)
or through the platform's trial core (`--record`, `app.seats.selfplay`); it lives in app/ because
it uses both layers (nothing in sim/ imports app/)."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from functools import partial
from pathlib import Path

import typer

from app.seats.selfplay import Start, record_trials
from sim.agents.selfplay import (
    CommanderName,
    DriverName,
    Job,
    TrialResult,
    benchmark_trials,
    iter_results,
    library_trials,
    robot_graph,
    row,
    run_job,
    summarize,
)
from sim.cli.eval import open_benchmark
from sim.core.dynamics import continuous_pose
from sim.core.navgraph import NavGraph
from sim.tasks.benchmark import Split


def eval_selfplay(
    benchmark: Path | None = typer.Option(
        None,
        "--benchmark",
        help="A RobotSlangBenchmark clone: one trial per maze of --split from its recorded start. "
        "Without it: the library's bundled mazes, from starts drawn from --seed.",
    ),
    split: Split = typer.Option(Split.VAL_SEEN, help="The benchmark's split (develop on val_seen)."),
    commander: CommanderName = typer.Option(
        CommanderName.DIALOG, help="The Commander's seat: dialog, or oracle (cheats: the true pose)."
    ),
    driver: DriverName = typer.Option(
        DriverName.DIALOG,
        help="The Driver's seat: dialog, oracle (cheats: answers from its true view), or persona:NAME "
        "(the dialog Driver in a frozen Driver persona's words: terse, chatty, typos, landmarks, unsure).",
    ),
    limit: int | None = typer.Option(None, min=1, help="Only the first N trials."),
    processes: int = typer.Option(2, min=1, help="Trials in parallel processes."),
    seed: int = typer.Option(0, help="Bundled mazes: the seed of the starts."),
    per_trial: Path | None = typer.Option(None, help="Write one JSON line per trial (its figures and dialog)."),
    record: Path | None = typer.Option(
        None,
        "--record",
        help="A data directory: play each trial through the platform's trial core (its runtime, event "
        "log and simulator backend, in --processes worker processes on the one database) with the "
        "seats' platform agents (dialog: agent:dialog), recorded there as an ordinary trial (replay, "
        "export) from the same start as without --record (logged with the trial); the pace is the "
        "platform's (ROBOTSLANG_ settings).",
    ),
    timeout_s: float = typer.Option(900.0, min=1.0, help="--record: abort a trial not over after this long."),
    as_json: bool = typer.Option(False, "--json", help="Print the figures as one JSON object."),
) -> None:
    """Play whole trials (localize, three targets in order, claims judged) with agents in both seats
    and print trials, completed, targets_confirmed_mean, moves_ratio, messages_mean,
    first_estimate_td_m, false_confirmations, first_mark_within_0_5m, bumps_per_instruction and
    seconds_per_trial.

    Without --record the trials run on the offline runner (the trial core's rules on the
    simulator's graph, no server or event log) and are not recorded; with it they are ordinary
    recorded trials of the platform."""

    graph_of: Callable[[str], NavGraph]  # a spec's maze -> the robot's graph, its start a pose of
    if benchmark is not None:
        bench = open_benchmark(benchmark)
        root = str(bench.root)
        specs = benchmark_trials(bench, split.value)[:limit]
        graph_of = partial(robot_graph, bench)
    else:
        from sim.tasks.library import BUNDLED_DIR, MazeLibrary

        root = None
        library = MazeLibrary(bundled=BUNDLED_DIR)
        mazes = [(name, library.load(name)) for name in library.names()[:limit]]
        graphs = [NavGraph.for_robot(m) for _, m in mazes]
        specs = library_trials(mazes, graphs, seed)
        graph_of = dict(zip([name for name, _ in mazes], graphs, strict=True)).__getitem__
    if record is not None:
        starts = [Start(spec.maze, continuous_pose(graph_of(spec.maze), spec.start), spec.seed) for spec in specs]
        results = recorded(record, benchmark, starts, commander, driver, processes, timeout_s)
    else:
        jobs = [Job(spec, commander, driver, root) for spec in specs]
        results = offline(jobs, processes, f"self-play {commander}/{driver}")
    if per_trial is not None:
        per_trial.parent.mkdir(parents=True, exist_ok=True)
        per_trial.write_text("".join(json.dumps(row(r)) + "\n" for r in results))
    typer.echo(json.dumps(summarize(results), indent=None if as_json else 2))


def offline(jobs: list[Job], processes: int, desc: str) -> list[TrialResult]:
    from tqdm import tqdm

    return list(tqdm(iter_results(jobs, run_job, processes), total=len(jobs), desc=desc, file=sys.stderr))


# The offline runner's agents as the platform seats them; a name missing here has no platform twin
# (the oracles read the simulator's truth directly; the platform's `oracle:shortest` Driver does not talk).
PLATFORM_COMMANDERS = {CommanderName.DIALOG: "agent:dialog"}
PLATFORM_DRIVERS = {DriverName.DIALOG: "agent:dialog"}


def recorded(
    data_dir: Path,
    benchmark: Path | None,
    starts: list[Start],
    commander: CommanderName,
    driver: DriverName,
    processes: int,
    timeout_s: float,
) -> list[TrialResult]:
    """The trials through the platform, recorded in `data_dir`."""
    if commander not in PLATFORM_COMMANDERS:
        raise typer.BadParameter(
            f"--record: the platform has no Commander '{commander}' (it seats: {', '.join(PLATFORM_COMMANDERS)})",
            param_hint="--commander",
        )
    if driver not in PLATFORM_DRIVERS:
        raise typer.BadParameter(
            f"--record: the platform has no Driver '{driver}' (it seats: {', '.join(PLATFORM_DRIVERS)})",
            param_hint="--driver",
        )
    return record_trials(
        data_dir, benchmark, starts, PLATFORM_COMMANDERS[commander], PLATFORM_DRIVERS[driver], processes, timeout_s
    )
