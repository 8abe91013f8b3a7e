"""Agents in the Driver's seat: what the seat hands them when it creates them.

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
    """What a driver's factory gets besides the server's parts (`DriverParts`)."""

    seed: int  # the trial's id: an agent's chance moves repeat per trial
    oracle: Oracle | None = None  # for `oracle:` drivers only
