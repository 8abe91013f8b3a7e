"""The dialog Commander in whole self-play trials against Drivers that speak as the frozen Driver
personas (terse, chatty, typos, landmarks, unsure: `sim/language/personas/driver_*.json`, written
before the Commander's parser was read), or against the scripted dialog Driver.

    python -m bench.dialog_commander --benchmark PATH --phrasing personas --json [--split val_seen] [--limit N] [--processes 2]

Each trial is `robotslang eval selfplay`'s (`sim.agents.selfplay`): one per maze of the split, from
its recorded start, localize and the three targets in order. Per Driver it prints completed (all
three targets confirmed), targets_confirmed_mean, bumps_per_instruction (moves into a wall, or
the Driver refused for one, per Commander message), first_mark_within_0_5m (share of trials whose Commander's first mark was
within 0.5 m TD of the robot), messages_mean, and the rest of `eval selfplay`'s figures, with the
machine's load. The issue's goals per persona: completed >= 0.80, bumps per instruction <= 0.1,
first mark within 0.5 m >= 0.8. Develop on val_seen.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from tqdm import tqdm

from bench.report import load_average
from sim.agents.selfplay import CommanderName, DriverName, Job, benchmark_trials, iter_results, run_job, summarize
from sim.tasks.benchmark import Benchmark


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benchmark", required=True, type=Path)
    parser.add_argument("--split", default="val_seen")
    parser.add_argument(
        "--phrasing",
        choices=["scripted", "personas"],
        default="personas",
        help="the five Driver personas, or the scripted dialog Driver",
    )
    parser.add_argument("--limit", type=int, default=None, help="only the first N trials")
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    args = parser.parse_args()
    bench = Benchmark(args.benchmark)
    specs = benchmark_trials(bench, args.split)[: args.limit]
    drivers = [DriverName.DIALOG] if args.phrasing == "scripted" else [d for d in DriverName if d.persona is not None]
    figures: dict[str, Any] = {}
    load_before = load_average()
    for driver in drivers:
        jobs = [Job(spec, CommanderName.DIALOG, driver, str(bench.root)) for spec in specs]
        results = list(
            tqdm(iter_results(jobs, run_job, args.processes), total=len(jobs), desc=str(driver), file=sys.stderr)
        )
        figures[driver.persona or driver] = summarize(results)
    out = {
        "personas" if args.phrasing == "personas" else "scripted": figures,
        "split": args.split,
        "trials": len(specs),
        "load_before": load_before,
        "load_after": load_average(),
    }
    print(json.dumps(out, indent=None if args.json else 2))


if __name__ == "__main__":
    main()
