"""The agent Driver's turn (issue 22): an agent is woken by what a person in the Driver's seat
would react to, answers through the trial like a person, is handed nothing a person is not
(no pose, map, graph or maze name), and is stopped by its caps with the reason in the log."""

from __future__ import annotations

import asyncio
import dataclasses
import subprocess
import sys
from enum import Enum

import numpy as np
import pytest
from sqlalchemy import select

from app.db.models import Event
from app.rover.records import create_robot
from app.seats.base import Seating
from app.seats.registry import register_driver
from bench.live import REPO
from sim.agents.dialog_driver import DialogDriver
from sim.agents.stepwise import StepwiseDriver
from sim.core.rays import RayObservation
from sim.trial.agent import SeatInfo
from sim.trial.commands import Claim
from sim.trial.percepts import Declined, Heard, Moved, PauseSet, PhaseBegan, Saw
from sim.trial.vocabulary import Move, Outcome, Phase, Role
from tests.app.live import cli, experimenter_client
from tests.app.rover_lab import MAZE, START_S, TARGETS

PRIVILEGED = {"pose", "x", "y", "heading", "maze", "graph", "map", "target", "targets", "true_pose", "belief"}


class RecordingDialogDriver(DialogDriver):
    """The dialog Driver, keeping every input it is handed for the test to read."""

    def __init__(self, seating: Seating, inputs: list) -> None:
        self.inputs: list = []  # its constructor resets it: not an input from the seat
        super().__init__(seed=seating.seed)
        self.inputs = inputs
        inputs.append(seating)

    def reset(self, info):
        self.inputs.append(info)
        super().reset(info)

    def perceive(self, percept):
        self.inputs.append(percept)
        return super().perceive(percept)


def assert_unprivileged(value) -> None:
    """Only words, counts, flags, closed vocabularies and rays: no coordinate, no name of a place."""
    if isinstance(value, RayObservation):
        assert {f.name for f in dataclasses.fields(value)} <= {
            "labels",
            "depth",
            "too_close",
            "valid",
            "forward_blocked",
            "problem",
        }
        assert all(np.shape(getattr(value, f)) == (13,) for f in ("labels", "depth", "too_close", "valid"))
        return
    if dataclasses.is_dataclass(value):
        for field in dataclasses.fields(value):
            # A field only the Commander's seat fills (`PhaseBegan.target`) reaches the Driver empty.
            held = getattr(value, field.name)
            assert field.name not in PRIVILEGED or held is None, f"{type(value).__name__}.{field.name}"
            assert_unprivileged(held)
        return
    assert value is None or isinstance(value, (str, int, bool, Enum)), f"{value!r} handed to an agent"
    assert not isinstance(value, float)


def events_of(services, trial_id: int, kind: str) -> list[dict]:
    with services.db() as db:
        rows = db.scalars(select(Event).where(Event.trial_id == trial_id, Event.kind == kind).order_by(Event.seq))
        return [e.payload for e in rows]


async def held_still(runtime, seconds: float) -> bool:
    """No move asked for during `seconds` (polled, so a move at any moment is seen)."""
    for _ in range(round(seconds / 0.05)):
        if runtime.state.move_ids:
            return False
        await asyncio.sleep(0.05)
    return True


def test_the_agent_waits_answers_moves_when_told_and_sees_only_what_a_driver_sees(server, trials):
    inputs: list = []
    register_driver("agent:test-recording", lambda services, seating: RecordingDialogDriver(seating, inputs))
    services = server.services
    maze = services.mazes.names()[0]
    trial = trials.new(maze=maze, driver="agent:test-recording")

    async def command():
        async with trial.seat("commander") as commander:
            await commander.event("phase", phase="localizing", timeout=30)
            runtime = services.hub.peek(trial.id)
            assert await held_still(runtime, 1.0)  # nobody has spoken: it neither moves nor talks
            assert not [m for m in commander.received if m.get("kind") == "chat"]
            start = len(commander.received)
            await commander.send("chat", text="what do you see?")
            answer = await commander.event("chat", role="driver", start=start, timeout=30)
            await commander.send("localize", x=1.0, y=1.0)
            await commander.event("phase", phase="navigating")
            assert await held_still(runtime, 1.0)  # marked on the map, it waits to be told
            start = len(commander.received)
            await commander.send("chat", text="turn left")
            report = await commander.event("chat", role="driver", start=start, timeout=30)
            return runtime, answer["payload"]["text"], report["payload"]["text"]

    runtime, answer, report = asyncio.run(command())
    moves = events_of(services, trial.id, "move_executed")
    chats = events_of(services, trial.id, "chat")
    backend = runtime.robot.backend
    observed_now = backend.rays.observation(*backend.grid_pose) if backend is not None else None
    assert answer and report
    assert [m["action"] for m in moves] == ["left", "left"]  # a right angle: two 45-degree turns
    assert all(m["outcome"] == "ok" for m in moves)
    assert {"role": "driver", "text": answer} in chats and {"role": "driver", "text": report} in chats
    seating, info, *percepts = inputs
    assert seating == Seating(seed=trial.id) and seating.oracle is None
    assert info == SeatInfo(Role.DRIVER, 3)
    for value in (info, *percepts):
        assert_unprivileged(value)
    assert Heard(Role.COMMANDER, "what do you see?") in percepts
    assert Heard(Role.DRIVER, answer) in percepts  # its own words too, as the page shows them
    phases = [(p.phase, p.target_index) for p in percepts if isinstance(p, PhaseBegan)]
    assert phases == [(Phase.LOCALIZING, 0), (Phase.NAVIGATING, 0)]
    # It saw its first frame before the question, and the frame after its move right after the move.
    saws = [i for i, p in enumerate(percepts) if isinstance(p, Saw)]
    asked = percepts.index(Heard(Role.COMMANDER, "what do you see?"))
    turned = [i for i, p in enumerate(percepts) if p == Moved(Move.LEFT, Outcome.OK)]
    assert saws[0] < asked and len(turned) == 2 and all(i + 1 in saws for i in turned)
    after = percepts[turned[-1] + 1]
    assert observed_now is not None and after.rays is not None
    assert np.array_equal(after.rays.labels, observed_now.labels)  # the simulator's rays at that frame


class AlwaysLeft(StepwiseDriver):
    """Turns left on every frame once navigating: it never finds anything."""

    def decide(self):
        return Move.LEFT


def aborted_with(services, trial_id: int) -> tuple[list[dict], list[str]]:
    phases = events_of(services, trial_id, "phase")
    said = [c["text"] for c in events_of(services, trial_id, "chat") if c["role"] == "driver"]
    return phases, said


def test_a_claim_refused_while_paused_is_made_again_once_the_trial_runs(server, trials):
    inputs: list = []
    register_driver("agent:test-recording", lambda services, seating: RecordingDialogDriver(seating, inputs))
    services = server.services
    trial = trials.new(driver="agent:test-recording")
    experimenter = experimenter_client(services, server.url)

    async def command():
        async with trial.seat("commander") as commander:
            await commander.event("phase", phase="localizing", timeout=30)
            await commander.send("localize", x=1.0, y=1.0)
            await commander.event("phase", phase="navigating")
            for _ in range(600):  # its first frame: a claim sends it
                if any(isinstance(p, Saw) for p in inputs):
                    break
                await asyncio.sleep(0.05)
            await asyncio.to_thread(experimenter.post, f"/experimenter/trials/{trial.id}/pause")
            await commander.event("paused", reason="experimenter")
            await commander.send("chat", text="claim it")
            await commander.event("chat", role="driver", timeout=30)  # "i think i found ...", then its claim
            for _ in range(200):
                if events_of(services, trial.id, "bad_message"):
                    break
                await asyncio.sleep(0.05)
            assert "target_claimed" not in commander.kinds()  # refused while paused: no verdict to wait for
            await asyncio.to_thread(experimenter.post, f"/experimenter/trials/{trial.id}/resume")
            await commander.event("target_claimed", timeout=30)

    asyncio.run(command())
    refusals = events_of(services, trial.id, "bad_message")
    assert len(refusals) == 1 and "paused" in refusals[0]["error"]
    refused = [p for p in inputs if isinstance(p, Declined)]
    assert refused == [Declined(Claim(), refusals[0]["error"])]
    paused = [p for p in inputs if isinstance(p, PauseSet)]
    assert paused[:2] == [PauseSet(True), PauseSet(False)]  # (then the Commander's leaving pauses it)
    assert inputs.index(paused[0]) < inputs.index(refused[0]) < inputs.index(paused[1])


@pytest.mark.settings(agent_moves_per_target=3)
def test_the_moves_cap_ends_the_trial_aborted_with_the_reason_logged(server, trials):
    register_driver("agent:test-always-left", lambda services, seating: AlwaysLeft())
    services = server.services
    trial = trials.new(driver="agent:test-always-left")

    async def command():
        async with trial.seat("commander") as commander:
            await commander.event("phase", phase="localizing", timeout=30)
            await commander.send("localize", x=1.0, y=1.0)
            return await commander.event("phase", phase="aborted", timeout=30)

    seen = asyncio.run(command())
    phases, said = aborted_with(services, trial.id)
    moves = events_of(services, trial.id, "move_executed")
    assert len(moves) == 3
    assert phases[-1] == {
        "phase": "aborted",
        "target_index": None,
        "reason": "agent Driver's cap: 3 moves for target 1",
    }
    assert seen["payload"]["reason"] == phases[-1]["reason"]  # the Commander's page hears why
    assert said == ["I have made 3 moves looking for target 1 of 3, the most an agent may; I stop here"]


@pytest.mark.settings(agent_minutes_per_trial=0.02)
def test_the_minutes_cap_ends_the_trial_aborted_with_the_reason_logged(server, trials):
    services = server.services
    trial = trials.new(driver="agent:dialog")

    async def command():
        async with trial.seat("commander") as commander:
            await commander.event("phase", phase="localizing", timeout=30)
            await commander.event("phase", phase="aborted", timeout=30)

    asyncio.run(command())
    phases, said = aborted_with(services, trial.id)
    runtime = services.hub.peek(trial.id)
    assert phases[-1]["reason"] == "agent Driver's cap: 0.02 minutes per trial"
    # Said ahead too (at most two minutes, a fifth of the cap here), so a person commanding knows.
    assert said == [
        "i can drive for 0 more seconds in this trial: my cap is 0.02 minutes",
        "my 0.02 minutes for this trial are over; I stop here",
    ]
    assert runtime is None or runtime.state.active_s(services.clock.now_ns()) >= 1.2


def test_the_cli_lists_the_drivers_and_the_agent_caps(tmp_path):
    env = {
        "ROBOTSLANG_DATA_DIR": str(tmp_path / "var"),
        "ROBOTSLANG_SECRET_KEY": "test-secret",
        "ROBOTSLANG_SEQ2SEQ_CHECKPOINT": str(tmp_path / "missing.pt"),
        "ROBOTSLANG_AGENT_MOVES_PER_TARGET": "120",
    }
    listed = cli("drivers", env=env)
    assert listed.returncode == 0, listed.stderr
    lines = listed.stdout.splitlines()
    assert {"human", "agent:dialog", "agent:random", "oracle:shortest"} <= set(lines)
    assert any(line.startswith("agent:seq2seq  (unavailable:") and "missing.pt" in line for line in lines)
    assert "stops after 120 moves per target or 15 minutes of trial clock" in lines[-1]


@pytest.mark.slow
def test_on_a_virtual_rover_the_agent_sees_rays_perceived_from_its_frames_and_nothing_privileged(
    tmp_path, start, camera_calibration, start_server, trials
):
    """The same seat on `robotslang robot virtual` (a process on loopback): no simulator rays to
    hand over, so the seat perceives each frame's rays itself with the Driver camera's calibration."""
    inputs: list = []
    register_driver("agent:test-recording-rover", lambda services, seating: RecordingDialogDriver(seating, inputs))
    server = start_server(camera_calibration=camera_calibration)
    services = server.services
    with services.db.begin() as db:
        robot, token = create_robot(db, "rover for the agent", "driver")
        robot_id = robot.id
    trial = trials.new(server, MAZE, targets=TARGETS, backend=f"robot:{robot_id}", driver="agent:test-recording-rover")
    with open(tmp_path / "rover.log", "w") as log:
        rover = subprocess.Popen(
            [sys.executable, "-c", "from app.cli import main; main()", "robot", "virtual"]
            + ["--server", server.url, "--token", token, "--maze", MAZE, "--seed", "4", "--fps", "5"]
            + ["--start", f"{start.x},{start.y},{start.theta}"],
            cwd=REPO,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    try:

        async def command():
            async with trial.seat("commander") as commander:
                await commander.event("phase", phase="localizing", timeout=START_S)
                runtime = services.hub.peek(trial.id)
                for _ in range(round(START_S / 0.05)):  # the rover's first frame, as a person waits for it
                    if runtime.state.last_frame_id is not None:
                        break
                    await asyncio.sleep(0.05)
                begun = len(commander.received)
                await commander.send("chat", text="what do you see?")
                await commander.event("chat", role="driver", start=begun, timeout=START_S)
                await commander.send("localize", x=start.x, y=start.y)
                await commander.event("phase", phase="navigating")
                localizing = len(events_of(services, trial.id, "move_executed"))
                begun = len(commander.received)
                await commander.send("chat", text="turn left")
                await commander.event("chat", role="driver", start=begun, timeout=START_S)
                return localizing

        localizing = asyncio.run(command())
        moves = events_of(services, trial.id, "move_executed")
    finally:
        rover.terminate()
        rover.wait(timeout=20)
    # Asked what it sees, it may look around, turning in place; then it turns left as told.
    assert all(m["action"] != "forward" for m in moves[:localizing])
    assert [m["action"] for m in moves[localizing:]] == ["left", "left"]
    seating, info, *percepts = inputs
    assert seating.oracle is None and info == SeatInfo(Role.DRIVER, 3)
    for value in (info, *percepts):
        assert_unprivileged(value)
    saws = [p for p in percepts if isinstance(p, Saw)]
    assert len(saws) >= 3  # the first frame, and the frame after each move
    assert all(s.rays is not None and s.rays.valid.any() for s in saws)  # perceived from the pixels
