"""The dialog Driver against the oracle Commander, offline, per NDH leg of val_seen and test.

    python -m bench.dialog_driver --benchmark PATH --json [--splits val_seen,test] [--limit N] [--processes 2]
    python -m bench.dialog_driver --benchmark PATH --ndh --json [--splits ...]
    python -m bench.dialog_driver --benchmark PATH --phrasing personas --json [--splits ...]

Each NDH instance is one leg: the Driver starts at the recorded start (`sim.tasks.benchmark.recorded_start`)
and is told its target; the oracle Commander (handed the true pose: it cheats) guides it in the scripted
phrasing and, separately, in the frozen held-out phrasing. success: share of legs whose claim the
Commander confirmed (within 2 robot lengths, the judge's rule); moves_ratio: all moves over all
shortest-path moves (the fewest moves, turns counted, to the node nearest the target; the
teacher's next-hop path takes 24 % more on val_seen); messages_per_leg: both seats' messages; claims_rejected: rejected over all claims.
localization (val_seen's first targets): after the localization exchange (at most 6 Driver messages)
the `colours` LDH localizer reading the Driver's words puts the robot within 0.5 m (TD) in what share of
episodes; the reference is the benchmark's human Drivers' words (LDH prefix-v1) through the same
localizer. reply_p95_s / act_p95_s: the Driver's compute time for a perceive call that answers a
Commander message / decides a move. Develop on val_seen; run test only for final figures.

`--phrasing personas` speaks in the five frozen Commander personas instead (terse, chatty, typos,
landmarks, metric: `sim/language/personas/`, written by someone who had not read the parser) and
prints each one's figures under `personas`.

`--ndh` runs the NDH episodes instead: from the benchmark's episode start, the leg's own recorded
human Commander messages reach the Driver one at a time (each once it has finished the last), up to
the benchmark's 120 moves, ending at its claim or after the last message; it prints TD, SR and SPL
(`sim.core.metrics`) for comparison with the seq2seq Driver (docs/model_card_ndh.md).
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
from multiprocessing import Pool
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from sim.agents.dialog_driver import DialogDriver
from sim.agents.episode import LegResult, replay, run
from sim.agents.oracle_commander import OracleCommander
from sim.core.metrics import TrajectoryScore, score_trajectory
from sim.core.observations import RayTable
from sim.core.stepper import MAX_EPISODE_ACTIONS
from sim.language.phrases import Persona, Phrasing, style
from sim.tasks.benchmark import Benchmark, NDHInstance, episode_start, goal_node, recorded_start
from sim.tasks.ldh import FIRST_TARGET, LDHInstance, Variant, derive, load_split
from sim.tasks.ldh_eval import MazeContexts, colours_localizer, score
from sim.trial.vocabulary import Phase

MAX_LEG_MOVES = 400
LOCALIZATION_MESSAGES = 6


@functools.cache
def _benchmark(root: str) -> Benchmark:
    """The benchmark, loaded once per worker process."""
    return Benchmark(root)


def _play(job: tuple[str, str, int, str]) -> tuple[str, str, LegResult]:
    root, split, k, mode = job
    bench = _benchmark(root)
    inst = bench.split(split)[k]
    graph = bench.graph(inst.run)
    rays = RayTable.build(bench.maze(inst.run), graph, cache_dir=bench.cache_dir)
    phrasing = Phrasing.SCRIPTED if mode == "localize" else style(mode)
    commander = OracleCommander(graph, rays, [(inst.target, inst.target_pose)], phrasing, seed=inst.inst_idx)
    start = recorded_start(graph, inst)
    if mode == "localize":
        result = run(
            DialogDriver(inst.inst_idx), commander, start, Phase.LOCALIZING, MAX_LEG_MOVES, LOCALIZATION_MESSAGES
        )
    else:
        result = run(DialogDriver(inst.inst_idx), commander, start, Phase.NAVIGATING, MAX_LEG_MOVES)
    return split, mode, result


def _leg_dialog(instances: list[NDHInstance], k: int) -> tuple[tuple[str, str], ...]:
    """The leg's own messages: a mug or paddle instance's history starts with the previous leg's."""
    inst = instances[k]
    if k > 0 and inst.previous_object is not None and instances[k - 1].run == inst.run:
        before = instances[k - 1].dialog
        if inst.dialog[: len(before)] == before:
            return inst.dialog[len(before) :]
    return inst.dialog


def _ndh(job: tuple[str, str, int]) -> TrajectoryScore:
    root, split, k = job
    bench = _benchmark(root)
    instances = bench.split(split)
    inst = instances[k]
    graph = bench.graph(inst.run)
    rays = RayTable.build(bench.maze(inst.run), graph, cache_dir=bench.cache_dir)
    start = episode_start(graph, inst)
    target = (inst.target, inst.target_pose)
    nodes = replay(
        DialogDriver(inst.inst_idx), graph, rays, start, target, _leg_dialog(instances, k), MAX_EPISODE_ACTIONS
    )
    return score_trajectory(graph, nodes, goal_node(graph, inst))


def _summary(results: list[LegResult]) -> dict[str, float]:
    claims = sum(r.claims for r in results)
    return {
        "success": float(np.mean([r.success for r in results])),
        "moves_ratio": sum(r.moves for r in results) / max(1, sum(r.shortest for r in results)),
        "messages_per_leg": float(np.mean([r.messages for r in results])),
        "claims_rejected": sum(r.rejected for r in results) / claims if claims else 0.0,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benchmark", required=True, type=Path)
    parser.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    parser.add_argument("--splits", default="val_seen,test")
    parser.add_argument("--limit", type=int, default=None, help="the first N instances of each split")
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--ndh", action="store_true", help="replay the recorded Commanders' messages instead")
    parser.add_argument(
        "--phrasing",
        choices=["standard", "personas"],
        default="standard",
        help="scripted and held-out, or the personas",
    )
    args = parser.parse_args()
    bench = Benchmark(args.benchmark)
    splits = args.splits.split(",")
    if args.ndh:
        ndh_jobs = [
            (str(bench.root), split, k) for split in splits for k in range(len(bench.split(split)[: args.limit]))
        ]
        with Pool(args.processes) as pool:
            scores = list(tqdm(pool.imap(_ndh, ndh_jobs), total=len(ndh_jobs), desc="ndh", file=sys.stderr))
        ndh = {
            "td": float(np.mean([t.td for t in scores])),
            "sr": float(np.mean([t.success for t in scores])),
            "spl": float(np.mean([t.spl for t in scores])),
        }
        print(json.dumps({"ndh": ndh, "splits": splits, "episodes": len(scores)}, indent=None if args.json else 2))
        return
    modes = ["scripted", "held_out"] if args.phrasing == "standard" else [f"persona:{p.value}" for p in Persona]
    jobs: list[tuple[str, str, int, str]] = []
    firsts: dict[int, Any] = {}
    for split in splits:
        instances = bench.split(split)[: args.limit]
        jobs += [(str(bench.root), split, k, mode) for k in range(len(instances)) for mode in modes]
        if split == "val_seen" and args.phrasing == "standard":
            for k, inst in enumerate(instances):
                if inst.target == FIRST_TARGET:
                    jobs.append((str(bench.root), split, k, "localize"))
                    firsts[k] = inst
    results: list[tuple[str, str, LegResult]] = []
    with Pool(args.processes) as pool:
        for item in tqdm(pool.imap(_play, jobs), total=len(jobs), desc="dialog driver", file=sys.stderr):
            results.append(item)
    by_mode = {mode: [r for _, m, r in results if m == mode] for mode in (*modes, "localize")}
    localization: dict[str, float | None] = {"within_0_5m": None, "reference_within_0_5m": None}
    if firsts:
        contexts = MazeContexts(bench)
        ours = []
        jobs_localize = [j for j in jobs if j[3] == "localize"]
        for job, result in zip(jobs_localize, by_mode["localize"]):
            inst = firsts[job[2]]
            ldh = derive(inst, Variant.FULL)
            ldh = LDHInstance(ldh.inst_idx, ldh.run, ldh.x, ldh.y, ldh.heading, tuple(result.dialog), Variant.PREFIX)
            ctx = contexts[inst.run]
            ours.append(score(ctx, colours_localizer(ldh, ctx), ldh)[2][1])
        idx = {inst.inst_idx for inst in firsts.values()}
        reference = [i for i in load_split(bench, "val_seen") if i.inst_idx in idx]
        ref = [score(contexts[i.run], colours_localizer(i, contexts[i.run]), i)[2][1] for i in reference]
        localization = {"within_0_5m": float(np.mean(ours)), "reference_within_0_5m": float(np.mean(ref))}
    legs = [r for results_of_mode in by_mode.values() for r in results_of_mode]
    spoken: dict[str, Any] = (
        {mode: _summary(by_mode[mode]) for mode in modes}
        if args.phrasing == "standard"
        else {"personas": {mode.removeprefix("persona:"): _summary(by_mode[mode]) for mode in modes}}
    )
    figures = {
        **spoken,
        "localization": localization,
        "reply_p95_s": float(np.percentile([t for r in legs for t in r.reply_s], 95)),
        "act_p95_s": float(np.percentile([t for r in legs for t in r.act_s], 95)),
        "splits": splits,
        "episodes": len(by_mode[modes[0]]),
    }
    print(json.dumps(figures, indent=None if args.json else 2))


if __name__ == "__main__":
    main()
