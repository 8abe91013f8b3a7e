"""The trial core (`sim/trial`) as its users rely on it: it imports neither the web app nor the
camera stack, and agents at its table play under the trial's rules whichever referee holds the
trial (here the offline one): a refused action is logged and perceived, caps end the trial with
words and a reason, two agents waiting on each other end it too."""

from __future__ import annotations

import asyncio
import subprocess
import sys

import pytest

from sim.agents.selfplay import TrialSpec, play
from sim.core.dynamics import Pose
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.tasks.library import BUNDLED_DIR, MazeLibrary
from sim.trial import events as ev
from sim.trial.agent import SeatInfo
from sim.trial.commands import Action, Claim, RequestMove
from sim.trial.offline import OfflineTrial
from sim.trial.percepts import Declined, Percept, PhaseBegan, Saw
from sim.trial.table import SILENCE, Caps, Table
from sim.trial.vocabulary import Move, Phase, Role

CORE = ("vocabulary", "specs", "events", "state", "commands", "decide", "percepts", "agent", "table")


def test_the_trial_core_imports_neither_the_web_app_nor_the_camera_stack():
    imports = "; ".join(f"import sim.trial.{name}" for name in CORE)
    loaded = subprocess.run(
        [sys.executable, "-c", f"{imports}; import sys; print(' '.join(sys.modules))"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    heavy = [m for m in loaded if m.split(".")[0] in ("app", "fastapi", "sqlalchemy", "torch", "cv2", "models")]
    assert not heavy and not [m for m in loaded if m.startswith("sim.robot")], heavy


class Scripted:
    """An agent that answers each percept with the actions `answer(percept)` gives; it keeps what it perceived."""

    def __init__(self, answer=lambda percept: []) -> None:
        self.answer, self.perceived = answer, []

    def reset(self, info: SeatInfo) -> None:
        self.info = info

    def perceive(self, percept: Percept) -> list[Action]:
        self.perceived.append(percept)
        return self.answer(percept)


@pytest.fixture(scope="module")
def world():
    library = MazeLibrary(bundled=BUNDLED_DIR)
    maze = library.load(library.names()[0])
    graph = NavGraph.for_robot(maze)
    return maze, graph, RayTable.build(maze, graph)


def played(world, driver: Scripted, commander: Scripted, caps: Caps | None = None) -> OfflineTrial:
    maze, graph, rays = world
    targets = [(name, maze.objects[name]) for name in ("jar", "mug", "paddle")]
    table = Table({Role.DRIVER: driver, Role.COMMANDER: commander}, [name for name, _ in targets], caps)
    trial = OfflineTrial(maze.name, targets, Pose(0, 0), graph, rays, table)

    async def wake(role, agent, percept):
        return agent.perceive(percept)

    asyncio.run(table.play(trial, wake))
    return trial


def logged(trial: OfflineTrial, model: type[ev.Event]) -> list[ev.Event]:
    return [e for e in map(ev.typed, trial.log) if isinstance(e, model)]


def test_a_refused_action_is_logged_and_the_agent_hears_why(world):
    claim_at_once = Scripted(lambda p: [Claim()] if isinstance(p, Saw) else [])
    trial = played(world, claim_at_once, Scripted())
    (declined,) = [p for p in claim_at_once.perceived if isinstance(p, Declined)]
    assert declined.action == Claim() and "marked the robot on the map" in declined.reason
    (bad,) = logged(trial, ev.BadMessage)
    assert bad.role == Role.DRIVER and bad.error == declined.reason
    assert not logged(trial, ev.TargetClaimed)


def test_the_drivers_first_frame_comes_once_the_trial_runs(world):
    driver = Scripted()
    played(world, driver, Scripted())
    assert isinstance(driver.perceived[0], PhaseBegan) and driver.perceived[0].phase == Phase.LOCALIZING
    assert isinstance(driver.perceived[1], Saw) and driver.perceived[1].rays is not None


def test_the_moves_cap_ends_the_trial_with_the_agents_words_and_the_reason(world):
    restless = Scripted(lambda p: [RequestMove(Move.LEFT)] if isinstance(p, Saw) else [])
    trial = played(world, restless, Scripted(), Caps(moves_per_target=3))
    assert trial.state.moves == 3 and trial.state.phase == Phase.ABORTED
    assert trial.state.abort_reason == "agent Driver's cap: 3 moves for target 1"
    assert "I have made 3 moves" in logged(trial, ev.Chat)[-1].text


def test_two_agents_waiting_on_each_other_end_the_trial(world):
    maze, graph, rays = world
    spec = TrialSpec(maze.name, Pose(0, 0), tuple((t, maze.objects[t]) for t in ("jar", "mug", "paddle")), 0)
    result = play(Scripted(), Scripted(), graph, rays, spec)
    assert result.ended == SILENCE and result.targets_confirmed == 0 and result.messages == 0
