"""Whole trials with agents in both seats, offline: localize, the three targets in order, each
claim judged by the Commander. The referee is the trial core's (`sim.trial.offline.OfflineTrial`:
the platform's rules and events, the simulator's moves on the robot's graph, `NavGraph.for_robot`)
and the seats are a `sim.trial.table.Table`, as on the platform; the figures are read from the
trial's log (`measure`), as a recorded trial's are.

Agents are named: `dialog` in either seat (percepts only); `oracle` in either seat cheats (the
Commander is handed the true pose, the Driver answers from its true view without turning);
`persona:NAME` in the Driver's seat is the dialog Driver speaking as a frozen Driver persona
(`sim.language.driver_personas`), slips and all."""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from enum import StrEnum
from functools import cache
from typing import Any, TypeVar

import numpy as np

from sim.agents.dialog_commander import DialogCommander
from sim.agents.dialog_driver import DialogDriver
from sim.agents.oracle_commander import OracleCommander
from sim.agents.oracle_driver import OracleDriver
from sim.agents.route import Router
from sim.core.dynamics import Pose, snap_pose
from sim.core.geometry import HEADINGS
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.language.driver_personas import DriverPersona
from sim.language.driver_phrasing import PersonaDriverPhrasing
from sim.language.phrases import Phrases, Phrasing
from sim.trial import events as ev
from sim.trial.agent import Agent
from sim.trial.commands import Abort, Action
from sim.trial.events import LoggedEvent
from sim.trial.offline import OfflineTrial
from sim.trial.percepts import Heard, Percept
from sim.trial.state import fold
from sim.trial.table import SILENCE, Caps, Table
from sim.trial.vocabulary import Outcome, Phase, Role

J = TypeVar("J")  # a job of `iter_results`
R = TypeVar("R")  # and its result
TARGET_ORDER = ("jar", "mug", "paddle")  # every benchmark trial's order
BUNDLED_START_MIN_M = 1.0  # a bundled maze's start: at least this far (path) from the first target
MARK_WITHIN_M = 0.5  # a first mark this close (TD) to the true pose counts as a good one


class CommanderName(StrEnum):
    DIALOG = "dialog"
    ORACLE = "oracle"  # cheats: the true pose


class DriverName(StrEnum):
    DIALOG = "dialog"
    ORACLE = "oracle"  # cheats: answers from its true view
    # The dialog Driver in a frozen persona's words.
    PERSONA_TERSE = "persona:terse"
    PERSONA_CHATTY = "persona:chatty"
    PERSONA_TYPOS = "persona:typos"
    PERSONA_LANDMARKS = "persona:landmarks"
    PERSONA_UNSURE = "persona:unsure"

    @property
    def persona(self) -> DriverPersona | None:
        return DriverPersona(self.removeprefix("persona:")) if self.startswith("persona:") else None


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
    bumps: int = 0  # moves that ran into a wall
    # Forward moves the Driver would not make, a wall in its way: known from the dialog Driver
    # offline (the log has only its words), None otherwise.
    refused_for_walls: int | None = None
    instructions: int = 0  # the Commander's messages
    ended: str = "finished"  # or why it was aborted (an agent's cap, both seats silent)
    seconds: float = 0.0
    update_s: list[float] = field(default_factory=list)  # the Commander's time per Driver message
    dialog: list[tuple[str, str]] = field(default_factory=list)

    @property
    def completed(self) -> bool:
        return self.targets_confirmed == self.targets_total


def play(
    commander: Agent, driver: Agent, graph: NavGraph, rays: RayTable, spec: TrialSpec, caps: Caps | None = None
) -> TrialResult:
    """One trial from `spec.start`; an agent with a `pose` (the oracles) is handed the true pose."""
    t0 = time.perf_counter()
    table = Table({Role.DRIVER: driver, Role.COMMANDER: commander}, [name for name, _ in spec.targets], caps)
    trial = OfflineTrial(spec.maze, list(spec.targets), spec.start, graph, rays, table)
    update_s: list[float] = []

    async def wake(role: Role, agent: Agent, percept: Percept) -> list[Action]:
        if isinstance(agent, OracleCommander | OracleDriver):
            agent.pose = trial.pose
        started = time.perf_counter()
        actions = agent.perceive(percept)
        if role == Role.COMMANDER and isinstance(percept, Heard) and percept.speaker == Role.DRIVER:
            update_s.append(time.perf_counter() - started)
        return actions

    asyncio.run(table.play(trial, wake))
    if not trial.state.over:
        trial.apply(Abort(SILENCE))
    out = measure(trial.log, dict(spec.targets), graph, rays, time.perf_counter() - t0)
    out.update_s = update_s
    if isinstance(driver, DialogDriver):
        out.refused_for_walls = driver.refused_for_walls
    return out


def measure(
    log: Sequence[LoggedEvent], objects: dict[str, tuple[float, float]], graph: NavGraph, rays: RayTable, seconds: float
) -> TrialResult:
    """A trial's figures, from its log alone (the poses the simulator logged are the truth)."""
    state = fold(log)
    router = Router(graph, rays, Phrases(Phrasing.SCRIPTED))
    out = TrialResult(state.maze, len(state.targets), moves=state.moves, seconds=seconds)
    pose: tuple[float, float, float] | None = None
    legs: set[int | None] = set()
    for logged in log:
        event = ev.typed(logged)
        match event:
            case ev.PoseSampled(x=x, y=y, heading=heading):
                pose = (x, y, heading)
            case ev.PhaseChanged(phase=Phase.NAVIGATING, target_index=k) if k not in legs:
                legs.add(k)
                if pose is not None and k is not None:
                    at = snap_pose(graph, *pose)
                    goal = graph.nearest_node(*objects[state.targets[k]])
                    out.shortest += int(router.moves_to_go(goal)[at.node, at.heading])
            case ev.Localized(x=x, y=y) if out.first_estimate_td_m is None and pose is not None:
                out.first_estimate_td_m = graph.topological_distance((x, y), pose[:2])
            case ev.MoveExecuted(outcome=Outcome.COLLISION):
                out.bumps += 1
            case ev.Chat(role=role, text=text):
                out.messages += 1
                out.instructions += role == Role.COMMANDER
                out.dialog.append((str(role), text))
            case ev.TargetConfirmed(truly_within=truly):
                out.targets_confirmed += 1
                out.false_confirmations += truly is False
            case ev.TargetRejected():
                out.rejections += 1
            case ev.PhaseChanged(phase=Phase.ABORTED, reason=reason):
                out.ended = reason or "aborted"
    if not math.isfinite(out.first_estimate_td_m or 0.0):
        out.first_estimate_td_m = None
    return out


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
    legs begun; first_estimate_td_m the mean over trials whose Commander marked an estimate;
    first_mark_within_0_5m the share of all trials whose first mark was within MARK_WITHIN_M (TD);
    bumps_per_instruction all moves into a wall or refused for one (where the Driver's refusals
    are known) over all the Commander's messages."""
    firsts = [r.first_estimate_td_m for r in results if r.first_estimate_td_m is not None]
    return {
        "trials": len(results),
        "completed": float(np.mean([r.completed for r in results])) if results else 0.0,
        "targets_confirmed_mean": float(np.mean([r.targets_confirmed for r in results])) if results else 0.0,
        "moves_ratio": sum(r.moves for r in results) / max(1, sum(r.shortest for r in results)),
        "messages_mean": float(np.mean([r.messages for r in results])) if results else 0.0,
        "first_estimate_td_m": float(np.mean(firsts)) if firsts else None,
        "false_confirmations": sum(r.false_confirmations for r in results),
        "first_mark_within_0_5m": float(
            np.mean([r.first_estimate_td_m is not None and r.first_estimate_td_m <= MARK_WITHIN_M for r in results])
        )
        if results
        else 0.0,
        "bumps_per_instruction": sum(r.bumps + (r.refused_for_walls or 0) for r in results)
        / max(1, sum(r.instructions for r in results)),
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
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    # Not a multiprocessing Pool: its workers are daemons, which may start no processes of their
    # own (a recording worker's server draws frames in a render pool).
    with ProcessPoolExecutor(processes, mp_context=get_context("spawn")) as pool:
        yield from pool.map(worker, jobs)


@dataclass(frozen=True)
class Job:
    spec: TrialSpec
    commander: CommanderName
    driver: DriverName
    benchmark: str | None = None  # a benchmark clone's root; None: the library's bundled mazes


@cache
def world(benchmark: str | None, name: str) -> tuple[Maze, NavGraph, RayTable]:
    """A maze with the robot's graph and its views, loaded once per process (graphs and views
    cached on disk)."""
    if benchmark is not None:
        from sim.tasks.benchmark import Benchmark

        bench = Benchmark(benchmark)
        maze, cache_dir = bench.maze(name), bench.cache_dir
    else:
        from sim.tasks.library import MazeLibrary

        maze, cache_dir = MazeLibrary().load(name), None
    graph = NavGraph.for_robot(maze, cache_dir=cache_dir)
    return maze, graph, RayTable.build(maze, graph, cache_dir=cache_dir)


def run_job(job: Job) -> TrialResult:
    spec = job.spec
    maze, graph, rays = world(job.benchmark, spec.maze)
    commander: Agent = (
        DialogCommander(maze, spec.seed)
        if job.commander == CommanderName.DIALOG
        else OracleCommander(graph, rays, list(spec.targets), seed=spec.seed)
    )
    driver: Agent
    if job.driver == DriverName.ORACLE:
        driver = OracleDriver(rays, spec.seed)
    else:
        persona = job.driver.persona
        phrasing = PersonaDriverPhrasing(persona, spec.seed) if persona is not None else None
        driver = DialogDriver(spec.seed, phrasing=phrasing)
    return play(commander, driver, graph, rays, spec)
