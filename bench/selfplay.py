"""Self-play speed: the whole split's wall time and the dialog Commander's belief update per message.

Runs the offline self-play trials of `robotslang eval selfplay` (`sim.agents.selfplay`) on a
benchmark split in parallel processes and prints the wall time of the whole split and the
Commander's time to take in one Driver message (its belief update and its answer): p50, p95 and
the largest, over every message of every trial. The issue's goals: the whole test split within 10
minutes on the 2-core machine, the update p95 at most 0.5 s. Develop on val_seen.

    python -m bench.selfplay --benchmark PATH --split val_seen --json [--driver oracle] [--processes 2]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from sim.agents.selfplay import CommanderName, DriverName, Job, benchmark_trials, iter_results, run_job
from sim.tasks.benchmark import Benchmark


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benchmark", required=True, type=Path)
    parser.add_argument("--split", default="val_seen")
    parser.add_argument("--driver", default=DriverName.DIALOG.value, choices=[d.value for d in DriverName])
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    args = parser.parse_args()
    bench = Benchmark(args.benchmark)
    jobs = [
        Job(spec, CommanderName.DIALOG, DriverName(args.driver), str(bench.root))
        for spec in benchmark_trials(bench, args.split)
    ]
    t0 = time.perf_counter()
    results = list(iter_results(jobs, run_job, args.processes))
    wall = time.perf_counter() - t0
    updates = np.array([s for r in results for s in r.update_s])
    figures = {
        "split": args.split,
        "trials": len(results),
        "processes": args.processes,
        "wall_s": wall,
        "update_p50_s": float(np.percentile(updates, 50)),
        "update_p95_s": float(np.percentile(updates, 95)),
        "update_max_s": float(updates.max()),
        "messages_heard": int(updates.size),
    }
    print(json.dumps(figures, indent=None if args.json else 2))


if __name__ == "__main__":
    main()
