"""Self-play through the trial core: whole trials with agents in both seats, each an ordinary
trial recorded in a data directory (the platform's runtime, event log and simulator backend, run in
this process, several trials at once), read back from its log into the figures of `robotslang
eval selfplay` (`sim.agents.selfplay.TrialResult`). Replay and every export work on them as on
any trial. The robot starts where the platform puts a trial's robot (`Mazes.start_pose`, seeded by
the trial's id), not at a benchmark's recorded start; the trial clock and the moves' pace are the
platform's (settings from the environment)."""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Sequence
from pathlib import Path

from app.trial import events as ev
from app.trial.setup import create_trial
from app.trial.state import fold
from app.trial.vocabulary import Phase
from sim.agents.route import Router
from sim.agents.selfplay import TARGET_ORDER, TrialResult
from sim.core.dynamics import snap_pose
from sim.language.phrases import Phrases, Phrasing

POLL_S = 0.2


def record_trials(
    data_dir: Path,
    benchmark: Path | None,
    mazes: Sequence[str],
    commander: str,
    driver: str,
    concurrency: int,
    timeout_s: float,
) -> list[TrialResult]:
    """One recorded trial per maze (targets in the benchmark's order), `concurrency` at a time; a
    trial not over after `timeout_s` is aborted, the reason logged."""
    from app.drivers.registry import available_agents
    from app.main import build_services
    from app.settings import Settings
    from app.trial.vocabulary import Role

    settings = Settings(data_dir=data_dir, benchmark=benchmark)
    services = build_services(settings)
    try:
        agents = {role: available_agents(services.agents, role) for role in (Role.COMMANDER, Role.DRIVER)}
        ids = []
        with services.db.begin() as db:
            for maze in mazes:
                trial = create_trial(
                    db,
                    team_id=None,
                    maze=maze,
                    targets=list(TARGET_ORDER),
                    backend="sim",
                    driver=driver,
                    commander=commander,
                    commander_id=None,
                    layouts=services.mazes.layouts(),
                    now_ns=services.clock.now_ns(),
                    agents=agents[Role.DRIVER],
                    commanders=agents[Role.COMMANDER],
                )
                ids.append(trial.id)
        seconds = asyncio.run(_play_all(services, ids, concurrency, timeout_s))
        return [result_of(services, trial_id, s) for trial_id, s in zip(ids, seconds, strict=True)]
    finally:
        services.log.close()
        services.trials.backends.renderer.close()
        services.engine.dispose()


async def _play_all(services, ids: Sequence[int], concurrency: int, timeout_s: float) -> list[float]:
    gate = asyncio.Semaphore(concurrency)

    async def one(trial_id: int) -> float:
        async with gate:
            t0 = time.perf_counter()
            runtime = await services.hub.get(trial_id)
            while not runtime.state.over and time.perf_counter() - t0 < timeout_s:
                await asyncio.sleep(POLL_S)
            if not runtime.state.over:
                runtime.abort(f"self-play: not over after {timeout_s:g} s")
            await runtime.close()
            return time.perf_counter() - t0

    try:
        return list(await asyncio.gather(*(one(i) for i in ids)))
    finally:
        await services.hub.close()


def result_of(services, trial_id: int, seconds: float) -> TrialResult:
    """A recorded trial's figures, from its log alone (the poses the simulator logged are the truth)."""
    events = services.log.load(trial_id)
    state = fold(events)
    maze = services.mazes.load(state.maze)
    graph, rays = services.mazes.graph(state.maze), services.mazes.rays(state.maze)
    router = Router(graph, rays, Phrases(Phrasing.SCRIPTED))
    out = TrialResult(state.maze, len(state.targets), moves=state.moves, seconds=seconds)
    pose: tuple[float, float, float] | None = None
    legs: set[int | None] = set()
    for logged in events:
        event = ev.typed(logged)
        match event:
            case ev.PoseSampled(x=x, y=y, heading=heading):
                pose = (x, y, heading)
            case ev.PhaseChanged(phase=Phase.NAVIGATING, target_index=k) if k not in legs:
                legs.add(k)
                if pose is not None and k is not None:
                    at = snap_pose(graph, *pose)
                    goal = graph.nearest_node(*maze.objects[state.targets[k]])
                    out.shortest += int(router.moves_to_go(goal)[at.node, at.heading])
            case ev.Localized(x=x, y=y) if out.first_estimate_td_m is None and pose is not None:
                out.first_estimate_td_m = graph.topological_distance((x, y), pose[:2])
            case ev.Chat(role=role, text=text):
                out.messages += 1
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
