"""The learned Driver through the rover's whole wire path against the pure simulator (the
`agent` part of `bench.robot_loop`).

For each NDH episode (val_seen jar episodes, whose start is the recorded pose): the pure
simulator (`models.evaluate.evaluate_agent`) and then a real trial on a virtual rover:
`robotslang serve` and `robotslang robot virtual --start` as separate processes, the trial's
Driver seat `agent:seq2seq` (observing the rays it perceives from the rover's frames, counting
its poses by its own odometry), a Commander socket that marks the start so navigation begins. The
episode's dialog history is written into the trial's log before anyone joins, as the benchmark
gives it to its agent. Both paths get the same cap on moves; TD through the rover is measured
from the rover's true pose (its truth file) where the agent claimed or ran out of moves.

The checkpoint is the one given, else whichever Driver the package ships
(`models.shipped.default_checkpoint()`, `models/checkpoints/ndh_driver.pt`).
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
import tempfile
import time
from pathlib import Path

MAX_MOVES = 40  # per episode, both paths (the benchmark's cap is higher; this bounds the bench's time)
FAST_PULSES = {"forward_s": 0.15, "left_s": 0.15, "right_s": 0.15}  # the same motion, sooner
EPISODE_TIMEOUT_S = 90.0  # an episode still driving then is measured where it stands


def choose_episodes(bench, library, n: int | None) -> list:
    """The first `n` (None: all) val_seen jar episodes whose maze has a map and whose start fits
    the rover (26 of the benchmark's 76)."""
    from sim.core.geometry import heading_angle
    from sim.robot.rover import Rover, RoverPose
    from sim.tasks.benchmark import recorded_start

    chosen = []
    names = set(library.names())
    for inst in bench.split("val_seen"):
        if len(inst.agent_pose) <= 2 or inst.run not in names:
            continue
        graph = bench.graph(inst.run)
        start = recorded_start(graph, inst)
        x, y = graph.nodes[start.node]
        pose = RoverPose(float(x), float(y), float(heading_angle(start.heading)))
        try:
            Rover(library.load(inst.run), pose)
        except ValueError:
            continue  # the rover's body does not fit at this node
        chosen.append((inst, pose))
        if n is not None and len(chosen) == n:
            break
    return chosen


def sim_tds(bench, checkpoint: Path, instances) -> list[float]:
    from models.data import EpisodeSet, World
    from models.evaluate import evaluate_agent
    from models.train import load_agent

    agent, tokenizer, ckpt = load_agent(checkpoint)
    world = World.build(bench, sorted({i.run for i in instances}))
    episodes = EpisodeSet.build(bench, world, "val_seen", tokenizer, instances=instances)
    results = evaluate_agent(
        agent, bench, world, episodes, ckpt["train_config"]["blind"], "bench", max_actions=MAX_MOVES
    )
    by_idx = {r.inst_idx: r.td for r in results}
    return [by_idx[i.inst_idx] for i in instances]


def agent_figures(
    benchmark: Path | None, checkpoint: Path | None, n: int | None, seed: int, log, calibration=None
) -> dict:
    if benchmark is None or not Path(benchmark).is_dir():
        return {
            "skipped": "no benchmark: give --benchmark PATH or set ROBOTSLANG_BENCHMARK "
            "(the NDH episodes and their mazes come from it)",
            "episodes": 0,
        }
    from models.shipped import default_checkpoint
    from sim.tasks.benchmark import Benchmark
    from sim.tasks.library import MazeLibrary

    checkpoint = checkpoint or default_checkpoint()
    if checkpoint is None:
        return {
            "skipped": "no seq2seq checkpoint: give --checkpoint PATH or set ROBOTSLANG_SEQ2SEQ_CHECKPOINT "
            "(this copy ships none in models/checkpoints/)",
            "episodes": 0,
        }
    bench = Benchmark(benchmark)
    library = MazeLibrary(benchmark=Path(benchmark))
    chosen = choose_episodes(bench, library, n)
    if not chosen:
        return {"skipped": "no val_seen jar episode whose start fits the rover", "episodes": 0}
    instances = [inst for inst, _ in chosen]
    log(f"agent: {checkpoint}, {len(chosen)} episodes in the pure simulator")
    td_sim = sim_tds(bench, Path(checkpoint), instances)
    with tempfile.TemporaryDirectory(prefix="robot-loop-") as tmp:
        td_rover, moves_rover = asyncio.run(
            _rover_tds(Path(benchmark), Path(checkpoint), chosen, bench, Path(tmp), calibration, log)
        )
    sim_mean, rover_mean = sum(td_sim) / len(td_sim), sum(td_rover) / len(td_rover)
    return {
        "episodes": len(chosen),
        "td_sim_mean": sim_mean,
        "td_rover_mean": rover_mean,
        "gap": rover_mean - sim_mean,
        "gap_fraction": (rover_mean - sim_mean) / sim_mean if sim_mean > 0 else None,
        "within_10_percent": abs(rover_mean - sim_mean) <= 0.1 * sim_mean,
        "td_sim": td_sim,
        "td_rover": td_rover,
        "max_moves": MAX_MOVES,
        "moves_rover": moves_rover,
        "episode_timeout_s": EPISODE_TIMEOUT_S,
        "checkpoint": str(checkpoint),
        "inst_idx": [i.inst_idx for i in instances],
    }


async def _rover_tds(
    benchmark: Path, checkpoint: Path, chosen, bench, tmp: Path, calibration, log
) -> tuple[list[float], list[int]]:
    from tqdm import tqdm

    from app.main import build_services
    from app.rover.records import create_robot
    from app.rover.virtual.truth import read_truth
    from app.settings import Settings
    from bench.live import CLI, REPO, SeatClient, ServerProcess, make_trial, settings_env
    from robot_client.calibration import Calibration
    from sim.trial.events import LoggedEvent

    settings = Settings(
        data_dir=tmp / "var",
        secret_key="bench-robot-loop",
        benchmark=benchmark,
        seq2seq_checkpoint=checkpoint,
        min_move_interval_s=0,
    )
    services = build_services(settings)
    if calibration is not None:
        calibration.save(settings.camera_calibration)  # the lab's camera: the software rover's
    timings = tmp / "timings.json"
    Calibration(**FAST_PULSES).save(timings)
    server = ServerProcess(settings_env(settings)).start()
    tds, moves = [], []
    try:
        for k, (inst, start) in enumerate(tqdm(chosen, desc="agent on the virtual rover", file=sys.stderr)):
            graph = bench.graph(inst.run)
            with services.db.begin() as db:
                robot, token = create_robot(db, f"bench rover {k}")
                backend = f"robot:{robot.id}"
            targets = [inst.target] + [t for t in ("jar", "mug", "paddle") if t != inst.target]
            trial = make_trial(services, inst.run, targets, "agent:seq2seq", team=f"bench {k}", backend=backend)
            _seed_dialog(services, trial, inst, LoggedEvent)
            truth = tmp / f"truth-{k}.jsonl"
            rover = subprocess.Popen(
                [*CLI, "robot", "virtual", "--server", server.url, "--token", token, "--maze", inst.run]
                + ["--seed", str(k), "--fps", "10", "--truth", str(truth)]
                + ["--calibration", str(timings), "--start", f"{start.x},{start.y},{start.theta}"],
                env=server.env,
                cwd=REPO,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            try:
                async with SeatClient(server.ws_url, services.seats.issue(trial, "commander")) as commander:
                    await commander.event("phase", phase="localizing", timeout=EPISODE_TIMEOUT_S)
                    await commander.send("localize", x=start.x, y=start.y)
                    moves.append(await _until_claim_or_moves(services, trial))
            finally:
                rover.terminate()
                rover.wait(timeout=20)
            end = [s for s in read_truth(truth) if not s.moving and s.move_id <= MAX_MOVES][-1]
            node = graph.nearest_node(end.x, end.y)
            goal = graph.nearest_node(*inst.target_pose)
            tds.append(float(graph.dist[node, goal]))
    finally:
        server.stop()
        services.engine.dispose()
    return tds, moves


def _seed_dialog(services, trial: int, inst, LoggedEvent) -> None:
    """The episode's dialog history, as the trial's first chat lines."""
    roles = {"oracle": "commander", "navigator": "driver"}
    events = services.log.load(trial)
    seq, t_ns = events[-1].seq, events[-1].t_ns
    for role, text in inst.dialog:
        seq, t_ns = seq + 1, t_ns + 1
        services.log.append(trial, LoggedEvent(seq, "chat", t_ns, {"role": roles[role], "text": text}))


async def _until_claim_or_moves(services, trial: int) -> int:
    """Wait for the agent's claim, its last allowed move or the episode's time; returns its moves."""
    deadline = time.monotonic() + EPISODE_TIMEOUT_S
    while True:
        events = services.log.load(trial)
        done = sum(e.kind == "move_executed" and e.payload["outcome"] != "refused" for e in events)
        if any(e.kind == "target_claimed" for e in events) or done >= MAX_MOVES or time.monotonic() > deadline:
            return done
        await asyncio.sleep(0.25)
