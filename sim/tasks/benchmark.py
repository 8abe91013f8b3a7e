"""The public RobotSlang benchmark on disk: NDH instances, target positions and maze maps.

`Benchmark(root)` reads a clone of the RobotSlangBenchmark repository (or an export in the
same layout). The start-pose protocol of NDH episodes lives here too.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np

from sim.core.dynamics import Action, Pose, snap_pose, teacher_action
from sim.core.geometry import GRID_STEP_M
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph


class Split(StrEnum):
    """The benchmark's folds (split by maze)."""

    TRAIN = "train"
    VAL_SEEN = "val_seen"
    TEST = "test"


EVAL_SPLITS = (Split.VAL_SEEN, Split.TEST)  # what results are reported on
EPISODE_START_AWAY_ACTIONS = 20  # teacher actions toward the target before turning back
EPISODE_START_RADIUS_M = 3 * GRID_STEP_M  # 0.21 m from the previous object

_SCAN = re.compile(
    r"^(?P<dir>.*?)/(?P<run>[^/]+)/maze/[^-]*-(?P<target>[a-z]+)-\[(?P<start>[^\]]*)\]-\[(?P<goal>[^\]]*)\]$"
)


class BenchmarkError(ValueError):
    """Benchmark files missing or not in the expected form."""


def text_hash(text: str) -> str:
    """A dialog turn's text as hand labels name it without holding it: 16 hex digits of its SHA-256."""
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def scan_run(scan: str) -> str:
    """The maze's run folder named in a scan string, e.g. "Run_318"."""
    match = _SCAN.match(scan)
    if not match:
        raise BenchmarkError(f"unrecognised scan {scan!r}")
    return match["run"]


@dataclass(frozen=True)
class NDHInstance:
    inst_idx: int
    scan: str
    run: str  # the maze's run folder name, e.g. "Run_318"
    target: str
    agent_pose: tuple[float, ...]  # (x, y, heading) for jar; (x, y) of the previous object otherwise
    target_pose: tuple[float, float]
    all_targets: tuple[tuple[float, float], ...]
    dialog: tuple[tuple[str, str], ...]  # (role: oracle|navigator, message)

    @classmethod
    def from_json(cls, item: dict[str, Any]) -> NDHInstance:
        return cls(
            inst_idx=int(item["inst_idx"]),
            scan=item["scan"],
            run=scan_run(item["scan"]),
            target=item["target"],
            agent_pose=tuple(float(v) for v in item["agent_pose"]),
            target_pose=(float(item["target_pose"][0]), float(item["target_pose"][1])),
            all_targets=tuple((float(t[0]), float(t[1])) for t in item["all_targets"]),
            dialog=tuple((turn["role"], turn["message"]) for turn in item["dialog_history"]),
        )

    @property
    def start_heading(self) -> float:
        return self.agent_pose[2] if len(self.agent_pose) > 2 else 0.0

    @property
    def previous_object(self) -> tuple[float, float] | None:
        """The object the agent starts beside (the previous target: mug after jar, paddle after mug
        in the benchmark); None for a trial's first target. The benchmark gives it as the two-element
        `agent_pose`, which also holds for exports of trials with other target orders."""
        return None if len(self.agent_pose) > 2 else (self.agent_pose[0], self.agent_pose[1])


class Benchmark:
    """A benchmark clone at `root`; mazes and graphs are loaded once per run and mode."""

    def __init__(self, root: str | Path, cache_dir: str | Path | None = None):
        self.root = Path(root)
        self.cache_dir = cache_dir
        if not (self.root / "NDH-data").is_dir():
            raise BenchmarkError(
                f"{self.root}: no NDH-data folder; point --benchmark or "
                f"ROBOTSLANG_BENCHMARK at a RobotSlangBenchmark clone"
            )
        self._mazes: dict[str, Maze] = {}
        self._graphs: dict[tuple[str, str], NavGraph] = {}

    def split(self, name: str) -> list[NDHInstance]:
        path = self.root / "NDH-data" / f"{name}.json"
        if not path.exists():
            raise BenchmarkError(f"{path}: no such split; expected one of {', '.join(Split)}")
        return [NDHInstance.from_json(item) for item in json.loads(path.read_text())]

    def dialogs(self, name: str) -> dict[str, tuple[tuple[str, str], ...]]:
        """Each run's whole recorded dialog in a split: its instances' histories are prefixes of
        one another, so the longest is the run's dialog."""
        out: dict[str, tuple[tuple[str, str], ...]] = {}
        for inst in self.split(name):
            if len(inst.dialog) > len(out.get(inst.run, ())):
                out[inst.run] = inst.dialog
        return out

    def runs(self) -> list[str]:
        """Run folders that have a full map, in natural order."""
        runs = [p.parent.parent.name for p in (self.root / "mazedata").glob("*/maze/maze.map-fixed.png")]
        return sorted(runs, key=lambda r: (len(r), r))

    def maze(self, run: str) -> Maze:
        if run not in self._mazes:
            self._mazes[run] = Maze.from_dir(self.root / "mazedata" / run, cache_dir=self.cache_dir)
        return self._mazes[run]

    def graph(self, run: str, mode: str = "benchmark") -> NavGraph:
        if (run, mode) not in self._graphs:
            self._graphs[run, mode] = NavGraph.build(self.maze(run), mode, cache_dir=self.cache_dir)
        return self._graphs[run, mode]


def recorded_start(graph: NavGraph, inst: NDHInstance) -> Pose:
    """The node nearest the recorded `agent_pose` (heading 0 where none is given)."""
    return snap_pose(graph, inst.agent_pose[0], inst.agent_pose[1], inst.start_heading)


def goal_node(graph: NavGraph, inst: NDHInstance) -> int:
    return graph.nearest_node(*inst.target_pose)


def episode_start(graph: NavGraph, inst: NDHInstance) -> Pose:
    """The benchmark simulator's start: for mug and paddle, leave the previous object with 20
    teacher actions toward the target, then come back until within 0.21 m of it, facing it."""
    pose = recorded_start(graph, inst)
    previous = inst.previous_object
    if previous is None:
        return pose
    goal = goal_node(graph, inst)
    for _ in range(EPISODE_START_AWAY_ACTIONS):
        action = teacher_action(graph, pose, goal)
        if action == Action.STOP:
            break
        pose, _ = graph.moves.step(pose, action)
    back = graph.nearest_node(*previous)
    target = np.asarray(previous)
    # Bounded: a path visits each (node, heading) at most once on the way back.
    for _ in range(graph.n * 8):
        if np.linalg.norm(graph.nodes[pose.node] - target) < EPISODE_START_RADIUS_M:
            break
        action = teacher_action(graph, pose, back)
        if action == Action.STOP:
            break
        pose, _ = graph.moves.step(pose, action)
    return pose


START_MODES = {"episode": episode_start, "recorded": recorded_start}
