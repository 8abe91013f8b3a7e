"""The rover loop's figures: `python -m bench.robot_loop [--benchmark PATH] [--episodes N] --json`.

Prints one JSON object (progress goes to stderr):

- tracker: the overhead tracker (`sim.robot.tracking`) against the virtual rover's true poses over a
  whole trial: a `sim.robot.rover` trajectory with the default motion noise, filmed by the virtual
  overhead camera at 5 frames per second during and between the pulses.
- perception: `sim.robot.perception` on virtual front-camera frames against `RayTable`'s rays at the
  same true poses (colours calibrated on other poses, as a lab would).
- particle_filter: `sim.robot.localization.ParticleFilter` from a uniform belief on perceived rays.
- agent: one seq2seq checkpoint (`--checkpoint`, else $ROBOTSLANG_SEQ2SEQ_CHECKPOINT, else the
  Driver shipped in `models/checkpoints/`) on the same NDH episodes (val_seen, recorded starts) through
  the pure simulator (`models.evaluate`) and through the whole wire path of the virtual rover
  (`robotslang serve`, `robotslang robot virtual`, the `agent:seq2seq` seat on perceived rays):
  mean topological distance of each, and the gap. TD through the rover is measured from the
  rover's true pose where the agent claimed (or ran out of moves), snapped to the graph.

Without the benchmark the first three run on the bundled mazes and `agent` says why it was
skipped. Defaults fit in 10 minutes on a 2-core machine under load.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from sim.core.navgraph import NavGraph
from sim.robot.camera import FrontCamera
from sim.robot.localization import evaluate_filter
from sim.robot.perception import evaluate_perception, simulated_calibration
from sim.robot.rover import NOISE_MODELS, Move, Rover
from sim.robot.tracking import evaluate_tracker
from sim.tasks.library import MazeLibrary

OVERHEAD_FPS = 5.0
FRAMES_PER_PULSE = 2  # a 0.35-0.4 s pulse spans about two overhead frames at 5 fps


def log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def rover_trajectory(maze, graph: NavGraph, moves: int, seed: int) -> np.ndarray:
    """(N, 3) true poses of a virtual rover wandering `moves` pulses: frames during each pulse
    and one at rest after it, as the overhead camera sees a trial."""
    from app.rover.virtual.command import random_start

    rng = np.random.default_rng(seed)
    rover = Rover(maze, random_start(maze, graph, seed), NOISE_MODELS["default"], seed=seed)
    poses = [(rover.pose.x, rover.pose.y, rover.pose.theta)]
    for _ in range(moves):
        move = Move.FORWARD if rng.random() < 0.7 else (Move.LEFT if rng.random() < 0.5 else Move.RIGHT)
        pulse = rover.plan(move)
        for k in range(1, FRAMES_PER_PULSE + 1):
            p = pulse.pose_at(k / (FRAMES_PER_PULSE + 1))
            poses.append((p.x, p.y, p.theta))
        p = rover.finish(pulse).pose
        poses.append((p.x, p.y, p.theta))
    return np.array(poses)


def tracker_figures(mazes, moves: int, seed: int) -> dict:
    maze, graph = mazes[0]
    poses = rover_trajectory(maze, graph, moves, seed)
    result = evaluate_tracker(maze, poses, seed=seed, fps=OVERHEAD_FPS, progress=True)
    return {**result, "frames": len(poses), "maze": maze.name}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.robot_loop", description=__doc__.split("\n")[0])
    p.add_argument(
        "--benchmark",
        type=Path,
        default=os.environ.get("ROBOTSLANG_BENCHMARK"),
        help="a clone of the RobotSlang benchmark (default $ROBOTSLANG_BENCHMARK)",
    )
    p.add_argument(
        "--episodes",
        type=int,
        default=None,
        help="NDH episodes for the agent part (default: all 26 val_seen jar episodes whose start fits the rover)",
    )
    p.add_argument("--filter-episodes", type=int, default=20, help="particle-filter episodes (20)")
    p.add_argument("--poses", type=int, default=150, help="poses for the perception figures (150)")
    p.add_argument("--moves", type=int, default=60, help="rover moves in the tracker's trial (60)")
    p.add_argument(
        "--checkpoint",
        type=Path,
        default=os.environ.get("ROBOTSLANG_SEQ2SEQ_CHECKPOINT"),
        help="seq2seq checkpoint (default $ROBOTSLANG_SEQ2SEQ_CHECKPOINT, else the shipped Driver)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    args = p.parse_args(argv)

    started = time.monotonic()
    library = MazeLibrary()
    mazes = [(m, NavGraph.build(m)) for m in (library.load(n) for n in library.names()[:3])]
    log(f"mazes: {', '.join(m.name for m, _ in mazes)}")
    out: dict = {"tracker": tracker_figures(mazes, args.moves, args.seed)}
    camera = FrontCamera()
    calibration = simulated_calibration(camera, mazes, seed=args.seed + 1000, progress=True)
    out["perception"] = evaluate_perception(
        [m for m, _ in mazes], n_poses=args.poses, seed=args.seed, camera=camera, calibration=calibration, progress=True
    )
    pf = evaluate_filter(
        [m for m, _ in mazes],
        episodes=args.filter_episodes,
        seed=args.seed,
        camera=camera,
        calibration=calibration,
        progress=True,
    )
    out["particle_filter"] = pf

    from bench.agent_loop import agent_figures

    out["agent"] = agent_figures(args.benchmark, args.checkpoint, args.episodes, args.seed, log, calibration)
    out["seconds"] = round(time.monotonic() - started, 1)
    out["load_average_1m"] = round(os.getloadavg()[0], 2)
    print(json.dumps(_finite(out), indent=None if args.json else 2, allow_nan=False))
    return 0


def _finite(v):
    """JSON has no NaN: a figure that could not be measured is null."""
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_finite(x) for x in v]
    return None if isinstance(v, float) and not math.isfinite(v) else v


if __name__ == "__main__":
    raise SystemExit(main())
