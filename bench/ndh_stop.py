"""How learned Drivers stop, on val_seen: TD, OTD, SR, SPL, steps, the share of episodes ended by
their own stop (against the 120-action cap) and the share that ever came within the success
radius (OTD: where any stop rule could have succeeded), per checkpoint, with per-instance CSVs.

    python -m bench.ndh_stop --benchmark PATH RUN/best.pt [RUN/best.pt ...] [--csv-dir DIR] \
        [--thresholds 0.5,0.3]

`--thresholds` scores each checkpoint with each stop threshold in place of the Driver's own
(`models.agent.STOP_THRESHOLD`), as it was chosen.

Development figures: val_seen only (docs/learned_driver.md, test-split hygiene).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from models import agent
from models.data import World
from models.evaluate import evaluate_checkpoint
from sim.core.geometry import SUCCESS_RADIUS_M
from sim.core.metrics import summarize_agent, write_csv
from sim.core.stepper import MAX_EPISODE_ACTIONS
from sim.tasks.benchmark import Benchmark

SPLIT = "val_seen"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benchmark", required=True, type=Path)
    parser.add_argument("--csv-dir", type=Path, default=None)
    parser.add_argument("--thresholds", default=str(agent.STOP_THRESHOLD))
    parser.add_argument("checkpoints", nargs="+", type=Path)
    args = parser.parse_args()
    bench = Benchmark(args.benchmark)
    instances = bench.split(SPLIT)
    world = World.build(bench, sorted({i.run for i in instances}))
    print(
        "| checkpoint | iteration | stop threshold | TD | OTD | SR | SPL | steps | ended by stop | came within "
        "the radius |\n|---|---|---|---|---|---|---|---|---|---|"
    )
    own = agent.STOP_THRESHOLD
    for path in args.checkpoints:
        iteration = torch.load(path, map_location="cpu", weights_only=False)["iteration"]
        for threshold in (float(t) for t in args.thresholds.split(",")):
            agent.STOP_THRESHOLD = threshold  # read by greedy_actions at each decision
            results = evaluate_checkpoint(bench, world, path, SPLIT)
            s = summarize_agent(results)
            stopped = np.mean([r.steps < MAX_EPISODE_ACTIONS for r in results])
            near = np.mean([r.otd <= SUCCESS_RADIUS_M for r in results])
            print(
                f"| {path} | {iteration} | {threshold} | {s['td_mean']:.2f} ± {s['td_std']:.2f} | {s['otd_mean']:.2f} | "
                f"{s['sr']:.3f} | {s['spl']:.3f} | {s['steps_mean']:.1f} | {stopped:.2f} | {near:.2f} |",
                flush=True,
            )
            if args.csv_dir is not None and threshold == own:
                write_csv(args.csv_dir / f"{path.parent.name}-{SPLIT}.csv", results)
        agent.STOP_THRESHOLD = own


if __name__ == "__main__":
    main()
