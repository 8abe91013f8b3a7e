"""The agent Driver's seat on a live server: how long a Commander waits for `agent:dialog`.

`robotslang serve` as a process on loopback; for each of the first N bundled generated mazes a
trial with `agent:dialog` in the Driver's seat and a Commander over a real websocket that asks
"what do you see?", marks the robot, then, as a person reading the map would, types the scripted
Commander's next instruction (`sim.agents.oracle_commander`, planned from the simulator's pose
events in the log) each time the Driver has answered, until the Driver claims the first target
or 30 instructions. Printed: the answer time to the question (no moves), the answer time to an
instruction (the moves it carried out included) and per move, and the share of first targets
claimed and confirmed within 2 robot lengths.

    python -m bench.agent_seat --trials 5 --json
"""

from __future__ import annotations

import argparse
import asyncio
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from app.main import build_services
from app.settings import Settings
from bench.live import SeatClient, ServerProcess, make_trial, settings_env
from bench.report import percentile
from sim.agents.oracle_commander import OracleCommander
from sim.core.dynamics import snap_pose
from sim.core.geometry import SUCCESS_RADIUS_M
from sim.core.observations import RayTable
from sim.trial.agent import SeatInfo
from sim.trial.percepts import PhaseBegan
from sim.trial.state import fold
from sim.trial.vocabulary import Phase, Role

MAX_INSTRUCTIONS = 30
ANSWER_TIMEOUT_S = 120.0


def pose_of(services, trial: int) -> tuple[float, float, float]:
    poses = [e.payload for e in services.log.load(trial) if e.kind == "pose"]
    return poses[-1]["x"], poses[-1]["y"], poses[-1]["heading"]


def moves_of(services, trial: int) -> int:
    """Every move the agent asked for, executed or refused (a run of refusals logs its count)."""
    state = fold(services.log.load(trial))
    return state.moves + state.refused


async def play(server, services, maze: str, out: dict[str, list]) -> None:
    trial = make_trial(services, maze, targets=("mug", "paddle", "jar"), driver="agent:dialog", team=f"bench {maze}")
    async with SeatClient(server.ws_url, services.seats.issue(trial, "commander")) as commander:
        await commander.event("phase", phase="localizing", timeout=ANSWER_TIMEOUT_S)

        async def say(text: str) -> tuple[str, float]:
            begun, sent = len(commander.received), time.perf_counter()
            await commander.send("chat", text=text)
            answer = await commander.event("chat", role="driver", start=begun, timeout=ANSWER_TIMEOUT_S)
            return answer["payload"]["text"], time.perf_counter() - sent

        _, waited = await say("hi! what do you see?")
        out["question_s"].append(waited)
        await commander.send("localize", x=1.0, y=1.0)
        await commander.event("phase", phase="navigating")
        graph = services.mazes.graph(maze)
        m = services.mazes.load(maze)
        person = OracleCommander(graph, RayTable.build(m, graph), [("mug", m.objects["mug"])])
        person.reset(SeatInfo(Role.COMMANDER, 3))
        person.pose = snap_pose(graph, *pose_of(services, trial))
        (first,) = person.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
        text = first.text
        for _ in range(MAX_INSTRUCTIONS):
            before = moves_of(services, trial)
            answer, waited = await say(text)
            made = moves_of(services, trial) - before
            out["instruction_s"].append(waited)
            if made:
                out["per_move_s"].append(waited / made)
            if "found" in answer:
                claimed = await commander.event("target_claimed", timeout=ANSWER_TIMEOUT_S)
                assert claimed["payload"]["target_index"] == 0
                x, y, _ = pose_of(services, trial)
                out["reached"].append(
                    float(np.hypot(x - m.objects["mug"][0], y - m.objects["mug"][1])) <= SUCCESS_RADIUS_M
                )
                return
            person.pose = snap_pose(graph, *pose_of(services, trial))
            text = person.instruction(plain="?" in answer)
    out["reached"].append(False)


async def run(trials: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        settings = Settings(data_dir=Path(tmp) / "var", secret_key="bench-agent-seat")
        services = build_services(settings)
        server = ServerProcess(settings_env(settings)).start()
        out: dict[str, list] = {"question_s": [], "instruction_s": [], "per_move_s": [], "reached": []}
        try:
            mazes = [n for n in services.mazes.names() if n.startswith("gen-")][:trials]
            for maze in mazes:
                await play(server, services, maze, out)
        finally:
            server.stop()
            services.engine.dispose()
    answers = {"question_answer": "question_s", "instruction_answer": "instruction_s", "per_move": "per_move_s"}
    return {
        "trials": len(out["reached"]),
        "first_target_reached": round(sum(out["reached"]) / len(out["reached"]), 3),
        **{f"{name}_p{q}_s": round(percentile(out[key], q), 3) for name, key in answers.items() for q in (50, 95)},
        "instructions": len(out["instruction_s"]),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=5, help="bundled generated mazes, one trial each")
    parser.add_argument("--json", action="store_true", help="print JSON only")
    args = parser.parse_args()
    result = asyncio.run(run(args.trials))
    print(json.dumps(result) if args.json else json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
