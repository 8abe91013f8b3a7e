"""Whole trials with agents in both seats, offline: localize, the three targets in order, each
claim judged by the Commander. The harness is the referee: it alone holds the true pose, steps it
on the robot's graph (`NavGraph.for_robot`: the landmarks block, as on the platform) by the trial's
rules (`graph.moves.step`, `sim.core.stepper.Moves`), hands the Driver the RayTable row of
each pose as its `Saw` and the Commander the claim frame's rays in `Claimed`, and measures.

Agents are named: `dialog` in either seat (percepts only); `oracle` in either seat cheats (the
Commander is handed the true pose, the Driver answers from its true view without turning)."""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from sim.agents.dialog_commander import DialogCommander
from sim.agents.dialog_driver import DialogDriver
from sim.agents.oracle_commander import OracleCommander
from sim.agents.oracle_driver import OracleDriver
from sim.agents.route import Router
from sim.agents.sight import pose_rays
from sim.agents.turns import (
    Agent,
    Claimed,
    DoClaim,
    DoJudge,
    DoLocalize,
    DoMove,
    DoSay,
    Heard,
    Judged,
    Moved,
    Outcome,
    Percept,
    Phase,
    PhaseChanged,
    Saw,
    SeatInfo,
    Speaker,
)
from sim.core.dynamics import Action, Pose
from sim.core.geometry import HEADINGS, SUCCESS_RADIUS_M
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.language.phrases import Phrases, Phrasing

J = TypeVar("J")  # a job of `iter_results`
R = TypeVar("R")  # and its result
TARGET_ORDER = ("jar", "mug", "paddle")  # every benchmark trial's order
MAX_MOVES = 600  # per trial: the trial is aborted there, as a seat's cap would
MAX_MESSAGES = 150
MAX_REJECTIONS = 3  # per target
BUNDLED_START_MIN_M = 1.0  # a bundled maze's start: at least this far (path) from the first target


class CommanderName(StrEnum):
    DIALOG = "dialog"
    ORACLE = "oracle"  # cheats: the true pose


class DriverName(StrEnum):
    DIALOG = "dialog"
    ORACLE = "oracle"  # cheats: answers from its true view


@dataclass(frozen=True)
class TrialSpec:
    maze: str  # a benchmark run or a library maze's name
    start: Pose
    targets: tuple[tuple[str, tuple[float, float]], ...]
    seed: int


@dataclass
class TrialResult:
    maze: str
    targets_total: int
    targets_confirmed: int = 0
    moves: int = 0
    shortest: int = 0  # the fewest moves of each leg begun, from where it began
    messages: int = 0
    first_estimate_td_m: float | None = None  # TD of the Commander's first mark from the true pose then
    false_confirmations: int = 0  # confirmed with the robot further than 2 robot lengths from the target
    rejections: int = 0
    ended: str = "finished"  # or the cap that ended it
    seconds: float = 0.0
    update_s: list[float] = field(default_factory=list)  # the Commander's time per Driver message
    dialog: list[tuple[str, str]] = field(default_factory=list)

    @property
    def completed(self) -> bool:
        return self.targets_confirmed == self.targets_total


def play(commander: Agent, driver: Agent, graph: NavGraph, rays: RayTable, spec: TrialSpec) -> TrialResult:
    """One trial from `spec.start`; an agent with a `pose` (the oracles) is handed the true pose."""
    t0 = time.perf_counter()
    out = TrialResult(spec.maze, len(spec.targets))
    router = Router(graph, rays, Phrases(Phrasing.SCRIPTED))
    pose, frame, index = spec.start, 0, -1
    phase = Phase.LOCALIZING
    rejected = 0
    claim_open = False
    total = len(spec.targets)
    seats = {Speaker.COMMANDER: commander, Speaker.DRIVER: driver}
    commander.reset(SeatInfo(Speaker.COMMANDER, total))
    driver.reset(SeatInfo(Speaker.DRIVER, total))
    queue: deque[tuple[Speaker, Percept]] = deque()

    def begin(k: int) -> None:
        nonlocal index
        index = k
        name, xy = spec.targets[k]
        out.shortest += int(router.moves_to_go(graph.nearest_node(*xy))[pose.node, pose.heading])
        queue.append((Speaker.DRIVER, PhaseChanged(Phase.NAVIGATING, k, total)))
        queue.append((Speaker.COMMANDER, PhaseChanged(Phase.NAVIGATING, k, total, target=name)))

    queue += [
        (Speaker.DRIVER, PhaseChanged(Phase.LOCALIZING, None, total)),
        (Speaker.DRIVER, Saw(0, pose_rays(rays, pose))),
        (Speaker.COMMANDER, PhaseChanged(Phase.LOCALIZING, None, total)),
    ]
    while queue and phase in (Phase.LOCALIZING, Phase.NAVIGATING):
        who, percept = queue.popleft()
        agent = seats[who]
        if isinstance(agent, OracleCommander | OracleDriver):
            agent.pose = pose
        started = time.perf_counter()
        turns = agent.perceive(percept)
        if who == Speaker.COMMANDER and isinstance(percept, Heard) and percept.speaker == Speaker.DRIVER:
            out.update_s.append(time.perf_counter() - started)
        for turn in turns:
            if isinstance(turn, DoSay):
                out.messages += 1
                out.dialog.append((who.value, turn.text))
                queue += [(Speaker.DRIVER, Heard(who, turn.text)), (Speaker.COMMANDER, Heard(who, turn.text))]
            elif isinstance(turn, DoMove) and who == Speaker.DRIVER:
                out.moves += 1
                pose, collided = graph.moves.step(pose, Action.of(turn.move))
                frame += 1
                result = Outcome.COLLISION if collided else Outcome.OK
                queue += [
                    (Speaker.DRIVER, Moved(turn.move, result)),
                    (Speaker.DRIVER, Saw(frame, pose_rays(rays, pose))),
                ]
            elif isinstance(turn, DoClaim) and who == Speaker.DRIVER and phase == Phase.NAVIGATING:
                claim_open = True
                queue.append((Speaker.COMMANDER, Claimed(index, pose_rays(rays, pose))))
            elif isinstance(turn, DoJudge) and who == Speaker.COMMANDER and claim_open:
                claim_open = False
                queue += [(s, Judged(turn.confirmed, index)) for s in Speaker]
                if not turn.confirmed:
                    out.rejections += 1
                    rejected += 1
                    continue
                out.targets_confirmed += 1
                rejected = 0
                if math.dist(graph.nodes[pose.node], spec.targets[index][1]) > SUCCESS_RADIUS_M:
                    out.false_confirmations += 1
                if index + 1 == total:
                    phase = Phase.FINISHED
                    break
                begin(index + 1)
            elif isinstance(turn, DoLocalize) and who == Speaker.COMMANDER:
                if out.first_estimate_td_m is None:
                    out.first_estimate_td_m = graph.topological_distance((turn.x, turn.y), graph.nodes[pose.node])
                if phase == Phase.LOCALIZING:
                    phase = Phase.NAVIGATING
                    begin(0)
        if out.moves >= MAX_MOVES or out.messages >= MAX_MESSAGES or rejected >= MAX_REJECTIONS:
            phase = Phase.ABORTED
            out.ended = (
                "moves" if out.moves >= MAX_MOVES else "messages" if out.messages >= MAX_MESSAGES else "rejections"
            )
    if phase in (Phase.LOCALIZING, Phase.NAVIGATING):
        out.ended = "silence"  # both seats waiting on the other
    out.seconds = time.perf_counter() - t0
    return out


def seat_agents(
    commander: CommanderName,
    driver: DriverName,
    maze: Maze,
    graph: NavGraph,
    rays: RayTable,
    spec: TrialSpec,
    cache_dir: str | Path | None = None,
) -> tuple[Agent, Agent]:
    c: Agent = (
        DialogCommander(maze, spec.seed, cache_dir)
        if commander == CommanderName.DIALOG
        else OracleCommander(graph, rays, list(spec.targets), seed=spec.seed)
    )
    d: Agent = DialogDriver(spec.seed) if driver == DriverName.DIALOG else OracleDriver(rays, spec.seed)
    return c, d


def benchmark_trials(bench: Any, split: str) -> list[TrialSpec]:
    """One trial per maze of the split: from the recorded start of its first target's instance
    (the jar's where the split has it, snapped to the robot's graph), to the maze's three objects
    in the benchmark's order."""
    from sim.tasks.benchmark import recorded_start

    specs = []
    by_run: dict[str, list[Any]] = {}
    for inst in bench.split(split):
        by_run.setdefault(inst.run, []).append(inst)
    for run, instances in by_run.items():
        first = next((i for i in instances if i.target == TARGET_ORDER[0]), instances[0])
        maze = bench.maze(run)
        start = recorded_start(robot_graph(bench, run), first)
        targets = tuple((name, maze.objects[name]) for name in TARGET_ORDER)
        specs.append(TrialSpec(run, start, targets, first.inst_idx))
    return specs


def robot_graph(bench: Any, run: str) -> NavGraph:
    """The robot's graph of a benchmark run (`bench` a `sim.tasks.benchmark.Benchmark`)."""
    return NavGraph.for_robot(bench.maze(run), cache_dir=bench.cache_dir)


def library_trials(mazes: Sequence[tuple[str, Maze]], graphs: Sequence[NavGraph], seed: int = 0) -> list[TrialSpec]:
    """One trial per maze with no recorded start (the bundled mazes): a start drawn from `seed` on
    the main component, at least BUNDLED_START_MIN_M of path from the first target."""
    rng = np.random.default_rng(seed)
    specs = []
    for k, ((name, maze), graph) in enumerate(zip(mazes, graphs, strict=True)):
        targets = tuple((t, maze.objects[t]) for t in TARGET_ORDER if t in maze.objects)
        dist = graph.dist[:, graph.nearest_node(*targets[0][1])]
        candidates = np.flatnonzero(np.isfinite(dist) & (dist >= BUNDLED_START_MIN_M))
        node = int(rng.choice(candidates))
        specs.append(TrialSpec(name, Pose(node, int(rng.integers(HEADINGS))), targets, seed + k))
    return specs


def summarize(results: Sequence[TrialResult]) -> dict[str, Any]:
    """The figures `eval selfplay` prints; moves_ratio is all moves over all shortest moves of the
    legs begun; first_estimate_td_m the mean over trials whose Commander marked an estimate."""
    firsts = [r.first_estimate_td_m for r in results if r.first_estimate_td_m is not None]
    return {
        "trials": len(results),
        "completed": float(np.mean([r.completed for r in results])) if results else 0.0,
        "targets_confirmed_mean": float(np.mean([r.targets_confirmed for r in results])) if results else 0.0,
        "moves_ratio": sum(r.moves for r in results) / max(1, sum(r.shortest for r in results)),
        "messages_mean": float(np.mean([r.messages for r in results])) if results else 0.0,
        "first_estimate_td_m": float(np.mean(firsts)) if firsts else None,
        "false_confirmations": sum(r.false_confirmations for r in results),
        "seconds_per_trial": float(np.mean([r.seconds for r in results])) if results else 0.0,
    }


def row(result: TrialResult) -> dict[str, Any]:
    """A trial's figures for a per-trial file (the dialog included)."""
    out = asdict(result)
    out["completed"] = result.completed
    out["update_p95_s"] = float(np.percentile(result.update_s, 95)) if result.update_s else None
    del out["update_s"]
    return out


def iter_results(jobs: Sequence[J], worker: Callable[[J], R], processes: int) -> Iterator[R]:
    """The jobs' results from parallel processes (in order); one process plays them here."""
    if processes <= 1:
        yield from map(worker, jobs)
        return
    from multiprocessing import get_context

    with get_context("spawn").Pool(processes) as pool:
        yield from pool.imap(worker, jobs)


@dataclass(frozen=True)
class Job:
    spec: TrialSpec
    commander: CommanderName
    driver: DriverName
    benchmark: str | None = None  # a benchmark clone's root; None: the library's bundled mazes


_worlds: dict[tuple[str | None, str], tuple[Maze, NavGraph, RayTable]] = {}


def world(benchmark: str | None, name: str) -> tuple[Maze, NavGraph, RayTable]:
    """A maze with the robot's graph and its views, loaded once per process (graphs and views
    cached on disk)."""
    if (benchmark, name) not in _worlds:
        if benchmark is not None:
            from sim.tasks.benchmark import Benchmark

            bench = Benchmark(benchmark)
            maze, cache = bench.maze(name), bench.cache_dir
        else:
            from sim.tasks.library import MazeLibrary

            maze, cache = MazeLibrary().load(name), None
        graph = NavGraph.for_robot(maze, cache_dir=cache)
        _worlds[benchmark, name] = (maze, graph, RayTable.build(maze, graph, cache_dir=cache))
    return _worlds[benchmark, name]


def run_job(job: Job) -> TrialResult:
    maze, graph, rays = world(job.benchmark, job.spec.maze)
    commander, driver = seat_agents(job.commander, job.driver, maze, graph, rays, job.spec)
    return play(commander, driver, graph, rays, job.spec)
