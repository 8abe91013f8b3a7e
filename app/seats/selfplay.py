"""Self-play through the trial core: whole trials with agents in both seats, each an ordinary
trial recorded in a data directory (the platform's runtime, event log and simulator backend), read
back from its log into the figures of `robotslang eval selfplay` (`sim.agents.selfplay.TrialResult`).
Replay and every export work on them as on any trial. Each trial starts from the pose and with the
agents' seed it is created with (the offline runner's), logged in its `trial_created` event, so it
plays as the offline trial does: the same referee, the same table. The trial clock is the platform's
(settings from the environment) but the agents are unpaced (`agent_pairs_paced=False`): each move
goes as soon as the frame before it is in.

The trials are created here, in one transaction, and then played in `processes` worker processes,
one trial at a time each, every worker with its own server core on the same database: SQLite (WAL,
a 30 s busy timeout) takes the workers' writes one at a time, each trial's events written by the one
process that plays it; with ROBOTSLANG_DATABASE_URL set they all write to that database instead."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from app.trial.setup import create_trial
from sim.agents.selfplay import TARGET_ORDER, TrialResult, iter_results, measure
from sim.trial.state import fold

if TYPE_CHECKING:  # the server's parts load in the worker processes only
    from app.services import Services

POLL_S = 0.2


@dataclass(frozen=True)
class Start:
    """A trial to record: its maze and the robot's start there (x, y, theta)."""

    maze: str
    pose: tuple[float, float, float]
    seed: int  # the agents'


@dataclass(frozen=True)
class Share:
    """One worker's trials (already created) and where they are recorded."""

    data_dir: Path
    benchmark: Path | None
    ids: tuple[int, ...]
    timeout_s: float


def record_trials(
    data_dir: Path,
    benchmark: Path | None,
    starts: Sequence[Start],
    commander: str,
    driver: str,
    processes: int,
    timeout_s: float,
) -> list[TrialResult]:
    """One recorded trial per start (targets in the benchmark's order), in `processes` worker
    processes; a trial not over after `timeout_s` is aborted, the reason logged. Results in the
    order of `starts`."""
    from app.seats.registry import available_seats
    from sim.trial.vocabulary import Role

    services = _services(data_dir, benchmark)  # brings the schema up to date before the workers open it
    try:
        seats = available_seats(services.agents)
        with services.db.begin() as db:
            ids = [
                create_trial(
                    db,
                    team_id=None,
                    maze=start.maze,
                    targets=list(TARGET_ORDER),
                    backend="sim",
                    driver=driver,
                    commander=commander,
                    commander_id=None,
                    layouts=services.mazes.layouts(),
                    now_ns=services.clock.now_ns(),
                    agents=seats[Role.DRIVER],
                    commanders=seats[Role.COMMANDER],
                    start=start.pose,
                    seed=start.seed,
                ).id
                for start in starts
            ]
    finally:
        asyncio.run(services.close())
    n = max(1, min(processes, len(ids)))
    shares = [Share(data_dir, benchmark, tuple(ids[k::n]), timeout_s) for k in range(n)]
    by_id = {r_id: r for played in iter_results(shares, play_share, n) for r_id, r in played}
    return [by_id[i] for i in ids]


def play_share(share: Share) -> list[tuple[int, TrialResult]]:
    """A worker: its own server core on the data directory, its trials one after another."""
    services = _services(share.data_dir, share.benchmark)

    async def play() -> list[tuple[int, TrialResult]]:
        try:
            seconds = await _play_all(services, share.ids, share.timeout_s)
            return [(i, result_of(services, i, s)) for i, s in zip(share.ids, seconds, strict=True)]
        finally:
            await services.close()

    return asyncio.run(play())


def _services(data_dir: Path, benchmark: Path | None) -> Services:
    from app.main import build_services
    from app.settings import Settings

    return build_services(Settings(data_dir=data_dir, benchmark=benchmark, agent_pairs_paced=False))


async def _play_all(services: Services, ids: Sequence[int], timeout_s: float) -> list[float]:
    async def one(trial_id: int) -> float:
        t0 = time.perf_counter()
        runtime = await services.hub.local(trial_id)  # self-play runs its trials in this process
        while not runtime.state.over and time.perf_counter() - t0 < timeout_s:
            await asyncio.sleep(POLL_S)
        if not runtime.state.over:
            runtime.abort(f"self-play: not over after {timeout_s:g} s")
        await runtime.close()
        return time.perf_counter() - t0

    return [await one(i) for i in ids]


def result_of(services: Services, trial_id: int, seconds: float) -> TrialResult:
    """A recorded trial's figures, from its log alone, as an offline trial's are."""
    events = services.log.load(trial_id)
    name = fold(events).maze
    maze, graph, rays = services.mazes.load(name), services.mazes.graph(name), services.mazes.rays(name)
    return measure(events, maze.objects, graph, rays, seconds)
