"""CPU of a trial's live particle filter (`app.perception.belief.TrialBelief`) per move, as the
server runs it on simulator trials: noting the move and keeping the frame (the event loop), the
filter's turn (folding the move in, weighing by the frame: the worker thread), and the watch
page's message. A wandering Driver on bundled mazes, each frame the simulator backend's own
(`SimulatorBackend.frame_at`); times are the thread's CPU (`time.thread_time`), so other load on
the machine does not count. `--perceive` weighs by the frame's pixels as a rover's filter does,
`--particles-fixed` keeps 1500 particles when converged: both together are the filter as it ran
before it was made cheap.

    ROBOTSLANG_BENCHMARK=../shared/robotslang python -m bench.belief [--trials 4] [--moves 30] [--json]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from app.backends.sim import SimulatorBackend
from app.clock import ServerClock
from app.perception.belief import CONVERGED_PARTICLES, TrialBelief
from app.perception.cameras import SIM_CALIBRATION
from sim.core.dynamics import Action, Pose
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.robot.camera import CameraCalibration
from sim.tasks.library import MazeLibrary

PARTS = ("event loop", "filter turn", "message")


def run(trials: int, moves: int, perceive: bool, converged_particles: int | None, seed: int = 0) -> dict:
    library = MazeLibrary()
    calibration = CameraCalibration.load(SIM_CALIBRATION)
    rng = np.random.default_rng(seed)
    cpu: dict[str, list[float]] = {part: [] for part in PARTS}
    first_ms, particles = [], []
    for t, name in enumerate(library.names()[:trials]):
        maze = library.load(name)
        graph = NavGraph.build(maze)
        sim = SimulatorBackend(maze, graph, RayTable.build(maze, graph), Pose(0, 0), ServerClock())
        pose = Pose(int(rng.integers(graph.n)), int(rng.integers(8)))
        belief = TrialBelief(maze, calibration, seed=t, converged_particles=converged_particles)
        for i in range(moves + 1):
            collided = False
            if i > 0:
                action = Action.FORWARD if rng.random() < 0.7 else Action(rng.choice([Action.LEFT, Action.RIGHT]))
                pose, collided = graph.moves.step(pose, action)
            jpeg, observation = sim.frame_at(pose)  # rendered before the clock starts
            started = time.thread_time()
            if i > 0:
                belief.moved(None if collided else action.word, time.monotonic_ns())
            belief.offer(jpeg, time.monotonic_ns(), None if perceive else observation)
            loop_s = time.thread_time() - started
            started = time.thread_time()
            belief.step()
            turn_s = time.thread_time() - started
            started = time.thread_time()
            belief.message()
            message_s = time.thread_time() - started
            if i == 0:
                first_ms.append(1e3 * (loop_s + turn_s + message_s))
            else:
                for part, s in zip(PARTS, (loop_s, turn_s, message_s)):
                    cpu[part].append(1e3 * s)
                particles.append(len(belief.filter.particles))
    per_move = {part: float(np.mean(v)) for part, v in cpu.items()}
    total = np.sum([cpu[p] for p in PARTS], axis=0)
    return {
        "trials": trials,
        "moves_per_trial": moves,
        "perceive_pixels": perceive,
        "converged_particles": converged_particles,
        "first_frame_ms": float(np.mean(first_ms)),
        "per_move_ms": per_move,
        "per_move_total_ms": float(total.mean()),
        "per_move_p99_ms": float(np.percentile(total, 99)),
        "mean_particles": float(np.mean(particles)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=4)
    parser.add_argument("--moves", type=int, default=30)
    parser.add_argument("--perceive", action="store_true", help="weigh by the frame's pixels, as on a rover")
    parser.add_argument("--particles-fixed", action="store_true", help="1500 particles even when converged")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    result = run(args.trials, args.moves, args.perceive, None if args.particles_fixed else CONVERGED_PARTICLES)
    if args.json:
        print(json.dumps(result))
        return
    print(f"first frame (uniform belief): {result['first_frame_ms']:.1f} ms CPU")
    for part, ms in result["per_move_ms"].items():
        print(f"  {part:12s} {ms:7.2f} ms")
    print(
        f"per move: {result['per_move_total_ms']:.2f} ms CPU (p99 {result['per_move_p99_ms']:.2f} ms), "
        f"{result['mean_particles']:.0f} particles on average"
    )


if __name__ == "__main__":
    main()
