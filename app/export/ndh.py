"""Recorded trials as NDH and LDH instances in the benchmark's own JSON schema and layout.

An export folder reads exactly like a RobotSlangBenchmark clone (`sim.tasks.benchmark.Benchmark`):

    NDH-data/{train,val_seen,test}.json   one instance per target reached, dialog up to it
    LDH-data/{train,val_seen,test}.json   dialog up to the end of localization, the estimate
    lookup_scans.json                     scan -> the three target positions
    mazedata/<maze>/maze/maze.map-fixed.png, maze.map.png
    splits.json                           maze -> fold (no maze in two folds)

As in the benchmark, the dialog of each NDH instance runs from the start of the trial (it grows
from one target to the next), `agent_pose` is the true start pose (x, y, heading) for the first
target and the previous target's position for the others, and `all_targets` lists the three
targets' positions in the order the trial visits them.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import NotRequired, TypedDict

import numpy as np

from app.export.record import TrialRecord
from sim.core.maze import Maze
from sim.tasks.benchmark import Split
from sim.tasks.ldh import DialogTurn, LDHInstanceJson
from sim.trial import events as ev
from sim.trial.state import LoggedEvent
from sim.trial.vocabulary import Phase, Role

HELD_OUT_FRACTION = 0.15  # of mazes, for each of val_seen and test (the benchmark: 26 + 26 of 170)
ROLES = {Role.COMMANDER: "oracle", Role.DRIVER: "navigator"}


class NDHInstanceJson(TypedDict):
    """One NDH instance as `NDH-data/<split>.json` lists them."""

    scan: str
    target: str
    agent_pose: list[float]
    target_pose: list[float]
    all_targets: list[list[float]]
    dialog_history: list[DialogTurn]
    trial_id: str
    seats: dict[str, str]
    inst_idx: NotRequired[int]  # set when the split is written


def scan_id(maze: str, target: str, agent_pose: Sequence[float], target_pose: Sequence[float]) -> str:
    """The benchmark's scan string: map path, target, start and goal rounded as numpy prints them,
    e.g. `mazedata/Run_114/maze/maze.labelled.npz-jar-[0.59  1.785 3.619]-[2.262 0.179]`."""
    start = np.round(np.asarray(agent_pose, dtype=np.float64), 3)
    goal = np.round(np.asarray(target_pose, dtype=np.float64), 3)
    return f"mazedata/{maze}/maze/maze.labelled.npz-{target}-{start}-{goal}"


def _dialog(events: Iterable[LoggedEvent], before_seq: int) -> list[DialogTurn]:
    return [
        {"role": ROLES[e.payload["role"]], "message": e.payload["text"]}
        for e in events
        if e.is_(ev.Chat) and e.seq < before_seq and e.payload.get("role") in ROLES
    ]


def _pose_at(events: Sequence[LoggedEvent], seq: int) -> list[float] | None:
    """The last true pose logged at or before `seq` (the first one after, when none was before)."""
    poses = [e for e in events if e.is_(ev.PoseSampled)]
    before = [e for e in poses if e.seq <= seq]
    chosen = before[-1] if before else (poses[0] if poses else None)
    if chosen is None:
        return None
    p = chosen.payload
    return [float(p["x"]), float(p["y"]), float(p.get("heading") or 0.0) % (2 * math.pi)]


def _start_seq(events: Sequence[LoggedEvent]) -> int:
    starts = [e.seq for e in events if e.is_(ev.PhaseChanged) and e.payload.get("phase") == Phase.LOCALIZING]
    return starts[0] if starts else (events[0].seq if events else 0)


def _positions(record: TrialRecord, maze: Maze) -> list[list[float]]:
    return [list(map(float, maze.objects[t])) for t in record.targets]


def ndh_instances(record: TrialRecord, maze: Maze) -> list[NDHInstanceJson]:
    """One NDH instance per confirmed target, in the order reached (without `inst_idx`).

    The first target's instance needs the true start pose; a trial without one (a real robot
    with no overhead tracker) yields instances for the later targets only.
    """
    events = sorted(record.events, key=lambda e: e.seq)
    all_targets = _positions(record, maze)
    start = _pose_at(events, _start_seq(events))
    out: list[NDHInstanceJson] = []
    for e in events:
        if not e.is_(ev.TargetConfirmed):
            continue
        k = int(e.payload["target_index"])
        target = record.targets[k]
        agent_pose = start if k == 0 else all_targets[k - 1]
        if agent_pose is None:
            continue
        out.append(
            {
                "scan": scan_id(record.maze, target, agent_pose, all_targets[k]),
                "target": target,
                "agent_pose": agent_pose,
                "target_pose": all_targets[k],
                "all_targets": all_targets,
                "dialog_history": _dialog(events, e.seq),
                "trial_id": str(record.trial_id),
                "seats": seats(record),
            }
        )
    return out


def ldh_instances(record: TrialRecord, maze: Maze) -> list[LDHInstanceJson]:
    """The localization half of a trial: the dialog until localization ended, the Commander's
    estimate, and the true pose then and at the start where known (None where not).

    Localization ends where an annotator marked it (`record.localized_after`: after that many
    messages, the last estimate made before the next message), else at the Commander's first
    estimate; `localization_source` says which.
    """
    events = sorted(record.events, key=lambda e: e.seq)
    estimates = [e for e in events if e.is_(ev.Localized)]
    if not record.targets or not (estimates or record.localized_after):
        return []
    if record.localized_after is not None:
        after, source = record.localized_after
        chats = [e.seq for e in events if e.is_(ev.Chat)]
        cut_seq = chats[after - 1] if 0 < after <= len(chats) else _start_seq(events)
        next_seq = chats[after] if after < len(chats) else events[-1].seq + 1
        made = [e for e in estimates if e.seq < next_seq]
        estimate = made[-1] if made else None
        dialog = _dialog(events, next_seq)
    else:
        estimate, source = estimates[0], "first_estimate"
        cut_seq, dialog = estimate.seq, _dialog(events, estimate.seq)
    start = _pose_at(events, _start_seq(events))
    truth = _pose_at(events, max(cut_seq, estimate.seq) if estimate else cut_seq)
    guess_xy = [float(estimate.payload["x"]), float(estimate.payload["y"])] if estimate else None
    heading = estimate.payload.get("heading") if estimate else None
    guess = None if guess_xy is None else [*guess_xy, None if heading is None else float(heading)]
    error = None if truth is None or guess_xy is None else math.dist(truth[:2], guess_xy)
    target = record.targets[0]
    all_targets = _positions(record, maze)
    instance: LDHInstanceJson = {
        "scan": scan_id(record.maze, target, start or guess_xy or truth or [0.0, 0.0], all_targets[0]),
        "target": target,
        "agent_pose": truth,
        "start_pose": start,
        "commander_estimate": guess,
        "localization_error_m": error,
        "localization_source": source,
        "localized_after_message": len(dialog),
        "all_targets": all_targets,
        "dialog_history": dialog,
        "trial_id": str(record.trial_id),
        "seats": seats(record),
    }
    if record.tags:
        instance["tags"] = record.tags
    return [instance]


def seats(record: TrialRecord) -> dict[str, str]:
    """Who held each seat, by participant id (or the agent that drove), as `source.load_trial` says."""
    return {"commander": str(record.info.get("commander", "")), "driver": str(record.info.get("driver_seat", ""))}


def assign_splits(mazes: Iterable[str]) -> dict[str, str]:
    """Each maze to one fold, by a stable hash of its name: about 15% of mazes each to val_seen
    and test once there are at least three, the rest (always the first) to train."""
    names = sorted(set(mazes), key=lambda m: (hashlib.sha256(m.encode()).hexdigest(), m))
    n = len(names)
    held = max(1, round(HELD_OUT_FRACTION * n)) if n >= 3 else 0
    n_val = held if n >= 3 else (1 if n == 2 else 0)
    folds = {}
    for i, name in enumerate(names):
        if i < n - n_val - held:
            folds[name] = "train"
        elif i < n - held:
            folds[name] = "val_seen"
        else:
            folds[name] = "test"
    return folds


@dataclass
class ExportSummary:
    ndh: dict[str, int] = field(default_factory=dict)  # split -> instances
    ldh: dict[str, int] = field(default_factory=dict)
    splits: dict[str, str] = field(default_factory=dict)  # maze -> split
    trials: int = 0


def write_benchmark(
    trials: Iterable[tuple[TrialRecord, Maze]], out_dir: str | Path, folds: Mapping[str, str] | None = None
) -> ExportSummary:
    """Write the trials' NDH and LDH instances, maps and lookup table in the benchmark's layout.

    `folds`: each maze -> its fold (`app.export.folds`, by layout); without it, `assign_splits` by maze.
    `inst_idx` counts from 0 across train, val_seen and test in that order, as in the benchmark.
    """
    out_dir = Path(out_dir)
    trials = list(trials)
    mazes = {maze.name: maze for _, maze in trials}
    folds = dict(folds) if folds is not None else assign_splits(mazes)
    ndh: dict[str, list[NDHInstanceJson]] = {s: [] for s in Split}
    ldh: dict[str, list[LDHInstanceJson]] = {s: [] for s in Split}
    for record, maze in trials:
        ndh[folds[maze.name]].extend(ndh_instances(record, maze))
        ldh[folds[maze.name]].extend(ldh_instances(record, maze))

    for name, maze in mazes.items():
        maze.save(out_dir / "mazedata" / name)
    for kind, by_split in (("NDH-data", ndh), ("LDH-data", ldh)):
        (out_dir / kind).mkdir(parents=True, exist_ok=True)
        index = 0
        for split in Split:
            for inst in by_split[split]:
                inst["inst_idx"] = index
                index += 1
            (out_dir / kind / f"{split}.json").write_text(json.dumps(by_split[split], indent=1))
    lookup = {inst["scan"]: inst["all_targets"] for split in Split for inst in ndh[split]}
    (out_dir / "lookup_scans.json").write_text(json.dumps(lookup, indent=1))
    (out_dir / "splits.json").write_text(json.dumps(folds, indent=1, sort_keys=True))
    return ExportSummary(
        ndh={s: len(v) for s, v in ndh.items()},
        ldh={s: len(v) for s, v in ldh.items()},
        splits=folds,
        trials=len(trials),
    )
