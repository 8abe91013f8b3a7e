"""A Driver agent offline, with the oracle Commander (`run`) or with a recorded human Commander's
messages (`replay`): the trial's turn-taking without a server. The simulator's stepper rules move
the Driver on the graph; the RayTable row of each pose is the Driver's `Saw` (frames are not
rendered). The Driver gets percepts only; the oracle Commander is handed the true pose."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

from sim.agents.oracle_commander import OracleCommander
from sim.core.dynamics import Action, Pose
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.trial.agent import Agent, SeatInfo
from sim.trial.commands import Claim, Judge, Localize, RequestMove, Say
from sim.trial.percepts import Claimed, Heard, Judged, Moved, Percept, PhaseBegan, Saw
from sim.trial.vocabulary import Outcome, Phase, Role

MAX_MESSAGES = 80
MAX_REJECTIONS = 3


@dataclass
class LegResult:
    success: bool = False
    moves: int = 0
    shortest: int = 0  # the fewest moves (turns count) from the start to the target's nearest node
    messages: int = 0
    claims: int = 0
    rejected: int = 0
    dialog: list[tuple[str, str]] = field(default_factory=list)  # (oracle|navigator, text)
    reply_s: list[float] = field(default_factory=list)  # the Driver's time to answer a message
    act_s: list[float] = field(default_factory=list)  # the Driver's time to decide a move


def run(
    driver: Agent,
    commander: OracleCommander,
    start: Pose,
    phase: Phase,
    max_moves: int,
    max_driver_messages: int = MAX_MESSAGES,
) -> LegResult:
    """Play from `start` in `phase` (LOCALIZING: the exchange up to the Commander's estimate or
    `max_driver_messages`; NAVIGATING: target 0 of the commander's targets until confirmed or a cap)."""
    out = LegResult()
    index = 0 if phase == Phase.NAVIGATING else None
    if index is not None:
        goal = commander.graph.nearest_node(*commander.targets[0][1])
        out.shortest = int(commander.moves_to_go(goal)[start.node, start.heading])
    commander.pose = start
    driver.reset(SeatInfo(Role.DRIVER, len(commander.targets)))
    commander.reset(SeatInfo(Role.COMMANDER, len(commander.targets)))
    queue: deque[tuple[str, Percept]] = deque()
    change = PhaseBegan(phase, index, len(commander.targets))
    queue += [("driver", change), ("driver", Saw(0, commander.view(start))), ("commander", change)]
    frame = 0
    driver_messages = 0
    while queue:
        who, percept = queue.popleft()
        if who == "driver":
            t0 = time.perf_counter()
            turns = driver.perceive(percept)
            spent = time.perf_counter() - t0
            if isinstance(percept, Heard) and percept.speaker == Role.COMMANDER:
                out.reply_s.append(spent)
            if any(isinstance(t, RequestMove) for t in turns):
                out.act_s.append(spent)
        else:
            turns = commander.perceive(percept)
        for turn in turns:
            if isinstance(turn, Say):
                out.messages += 1
                out.dialog.append(("navigator" if who == "driver" else "oracle", turn.text))
                speaker = Role.DRIVER if who == "driver" else Role.COMMANDER
                queue += [("driver", Heard(speaker, turn.text)), ("commander", Heard(speaker, turn.text))]
                driver_messages += who == "driver"
            elif isinstance(turn, RequestMove):
                out.moves += 1
                pose, collided = commander.graph.moves.step(commander.pose, Action.of(turn.move))
                commander.pose = pose
                frame += 1
                result = Outcome.COLLISION if collided else Outcome.OK
                queue += [("driver", Moved(turn.move, result)), ("driver", Saw(frame, commander.view(pose)))]
            elif isinstance(turn, Claim):
                out.claims += 1
                queue.append(("commander", Claimed(0)))
            elif isinstance(turn, Judge):
                queue.append(("driver", Judged(turn.confirmed, 0)))
                if turn.confirmed:
                    out.success = True
                    return out
                out.rejected += 1
            elif isinstance(turn, Localize):
                return out
        if out.moves >= max_moves or out.messages >= MAX_MESSAGES or out.rejected >= MAX_REJECTIONS:
            break
        if phase == Phase.LOCALIZING and driver_messages >= max_driver_messages:
            break
    return out


def replay(
    driver: Agent, graph: NavGraph, rays: RayTable, start: Pose, dialog: Sequence[tuple[str, str]], max_moves: int
) -> list[int]:
    """An NDH episode: the recorded Commander's messages (role "oracle") reach the Driver one at a
    time, each once it has finished with the last (spoken or stopped moving); it ends at the Driver's
    claim, after the last message, or at `max_moves`. Returns the nodes it stood on, start first."""
    driver.reset(SeatInfo(Role.DRIVER, 1))
    pose, nodes, moves = start, [start.node], 0
    driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 1))
    driver.perceive(Saw(0, rays.observation(*pose)))
    for role, message in dialog:
        if role != "oracle":
            continue
        turns = driver.perceive(Heard(Role.COMMANDER, message))
        while True:
            if any(isinstance(t, Claim) for t in turns) or moves >= max_moves:
                return nodes
            move = next((t for t in turns if isinstance(t, RequestMove)), None)
            if move is None:
                break
            pose, collided = graph.moves.step(pose, Action.of(move.move))
            moves += 1
            nodes.append(pose.node)
            result = Outcome.COLLISION if collided else Outcome.OK
            turns = driver.perceive(Moved(move.move, result)) + driver.perceive(Saw(moves, rays.observation(*pose)))
    return nodes
