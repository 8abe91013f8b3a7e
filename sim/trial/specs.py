"""Who holds a seat and what fills the robot seat, as a trial's record names them: parsed once,
here, into typed values (`SeatSpec.parse`, `BackendSpec.parse`), and written back with `str()`.

A seat is `human`, `agent:<name>` (an agent that sees what a person in the seat sees) or
`oracle:<name>` (an agent handed the truth: a baseline that never ranks). The robot seat is
`sim` (the simulator) or `robot:<id>` (a registered rover); backends may register more kinds.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class SeatKind(StrEnum):
    HUMAN = "human"
    AGENT = "agent"
    ORACLE = "oracle"


@dataclass(frozen=True)
class SeatSpec:
    kind: SeatKind
    name: str = ""  # the agent's name (none for a person)

    @classmethod
    def parse(cls, text: str) -> SeatSpec:
        """Raises `ValueError` saying what a seat may be."""
        kind, sep, name = text.partition(":")
        if text == SeatKind.HUMAN:
            return HUMAN
        if sep and name and kind in (SeatKind.AGENT, SeatKind.ORACLE):
            return cls(SeatKind(kind), name)
        raise ValueError(f"seat {text!r}: expected 'human', 'agent:<name>' or 'oracle:<name>'")

    def __str__(self) -> str:
        return str(self.kind) if self.kind == SeatKind.HUMAN else f"{self.kind}:{self.name}"

    @property
    def human(self) -> bool:
        return self.kind == SeatKind.HUMAN


HUMAN = SeatSpec(SeatKind.HUMAN)


class BackendKind(StrEnum):
    SIM = "sim"
    ROBOT = "robot"


@dataclass(frozen=True)
class BackendSpec:
    kind: str  # a `BackendKind` (the backend registry refuses any other)
    arg: str = ""  # what follows the colon: a rover's id

    @classmethod
    def parse(cls, text: str) -> BackendSpec:
        """Raises `ValueError` for a `robot:` spec without a numeric id (other kinds are the
        backend registry's to know)."""
        kind, _, arg = text.partition(":")
        spec = cls(kind, arg)
        if kind == BackendKind.ROBOT and not arg.isdigit():
            raise ValueError(f"backend {text!r}: expected 'robot:<id>'")
        return spec

    @classmethod
    def robot(cls, robot_id: int) -> BackendSpec:
        return cls(BackendKind.ROBOT, str(robot_id))

    def __str__(self) -> str:
        return f"{self.kind}:{self.arg}" if self.arg else self.kind

    @property
    def robot_id(self) -> int | None:
        """The rover's id for `robot:<id>`, else None."""
        return int(self.arg) if self.kind == BackendKind.ROBOT else None


SIM = BackendSpec(BackendKind.SIM)
