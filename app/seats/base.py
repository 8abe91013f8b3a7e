"""Agents in a trial's seats: what the seat hands them when it creates them.

An agent is a `sim.trial.agent.Agent`: reset with a `SeatInfo` (its role and how many targets the
trial has), it then perceives, one at a time and in the log's order, what a person's page in its
seat shows, as the trial core's typed percepts (`sim.trial.percepts.SeatView` says which), and
answers each with the seat's actions (`sim.trial.commands`), carried out under the same rules as
a person's. It is never woken by a timer.

The Driver perceives the chat (`Heard`, its own too), its frame (`Saw`: the simulator's rays, or
the rays perceived from a rover's pixels) at the start and after each of its moves' outcome
(`Moved`), claims (`Claimed`), verdicts (`Judged`) and phase changes (`PhaseBegan`, with the
target's number, never its name); never a pose, a map, a graph or a maze name. A driver spec is
`agent:<name>` or `oracle:<name>`: a baseline that cheats, handed the maze, the targets and the
true pose (`Oracle`); oracles never rank with the agents.

The Commander perceives the map of the trial's maze (`Seating.maze`, the maze its page draws),
the chat, phase changes with the name of the target the trial has reached, each claim with the
claim frame's rays (`Claimed`) and the verdicts; never the true pose, the Driver's frame stream
or its moves.
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
