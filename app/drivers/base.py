"""Agents in a trial's seats: what the seat hands them when it creates them.

An agent Driver is a `sim.agents.turns.Agent`: it is reset with a `SeatInfo` (its role and how many
targets the trial has) and then perceives, one at a time and in the log's order, what a human
Driver's browser receives, as typed percepts: every chat message (`Heard`, its own too), its
frame (`Saw`: the simulator's rays at that frame, or the rays perceived from a rover's pixels)
at the start and after each of its moves' outcome (`Moved`; after a move not made, the frame as
it stands), its claims (`Claimed`), the Commander's verdicts (`Judged`) and phase changes
(`PhaseChanged`, with the target's number, never its name). It answers each with turns (`DoSay`, `DoMove`, `DoClaim`, `DoWait`) that the
seat carries out through `DriverTrial`, so each is an event in the log like a person's. It is
never woken by a timer, and never handed a pose, a map, a graph or a maze name.

A driver spec is `agent:<name>` (sees only the above) or `oracle:<name>`: a baseline that cheats,
handed the maze, the targets and the true pose (`Oracle`); oracles never rank with the agents.

An agent Commander perceives what a human Commander's page receives: the map of the trial's maze
with its landmarks (`Seating.maze`, the maze the page draws), the chat (`Heard`), phase changes
with the name of the target the trial has reached (`PhaseChanged.target`), each claim with the
rays its seat perceives from the claim frame's pixels (`Claimed`), and the verdicts (`Judged`).
It answers with `DoSay`, `DoLocalize` (its estimate on the map) and `DoJudge`. It never gets the
true pose, the Driver's frame stream or its moves (the move count the page shows it does not need).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Oracle:
    """What only an `oracle:` driver is handed: the maze, the targets in order and the true pose."""

    maze: str
    targets: tuple[str, ...]
    true_pose: Callable[[], tuple[float, float, float] | None]


@dataclass(frozen=True)
class Seating:
    """What a driver's factory gets besides the server's parts (`AgentParts`)."""

    seed: int  # the trial's id: an agent's chance moves repeat per trial
    oracle: Oracle | None = None  # for `oracle:` drivers only
    maze: str | None = None  # for Commanders only: the maze their map shows
    partner_human: bool = True  # a person holds the other seat (an agent talks to them as to a person)
