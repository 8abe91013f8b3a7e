"""An agent in a seat: reset with what the seat knows from the start, then woken with each percept
(`sim.trial.percepts`), it answers with the seat's actions (`sim.trial.commands.Action`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from sim.trial.commands import Action
from sim.trial.percepts import Percept
from sim.trial.vocabulary import Role


@dataclass(frozen=True)
class SeatInfo:
    role: Role
    targets_total: int  # the Driver's page shows "target k of 3"-style progress, never the object's name


class Agent(Protocol):
    def reset(self, info: SeatInfo) -> None: ...

    def perceive(self, percept: Percept) -> list[Action]: ...
