"""What an agent in a seat perceives and what it may do: typed percepts in, typed turns out.

An agent is woken by what a person in its seat would react to (a chat message, the frame after its
move, a judged claim, a phase change), never by a timer, and answers with zero or more turns."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol

from sim.robot.perception import RayObservation


class Phase(StrEnum):
    WAITING = "waiting"
    LOCALIZING = "localizing"
    NAVIGATING = "navigating"
    FINISHED = "finished"
    ABORTED = "aborted"


class Speaker(StrEnum):
    COMMANDER = "commander"
    DRIVER = "driver"


class Move(StrEnum):
    """The Driver's moves."""

    FORWARD = "forward"
    LEFT = "left"
    RIGHT = "right"


class MoveResult(StrEnum):
    OK = "ok"
    COLLISION = "collision"
    REFUSED = "refused"


@dataclass(frozen=True)
class Heard:
    """Any chat message, the agent's own too."""

    speaker: Speaker
    text: str


@dataclass(frozen=True)
class Saw:
    """The Driver's frame: the simulator's rays at that frame, or perceived from a rover's pixels;
    None where unreadable. Driver seat only."""

    frame_id: int
    rays: RayObservation | None


@dataclass(frozen=True)
class Moved:
    move: Move
    result: MoveResult
    reason: str | None = None


@dataclass(frozen=True)
class Claimed:
    """The Driver claimed (the Commander hears it). `rays`: the claim frame as the Commander's seat
    perceives it from its pixels (None where not given, or unreadable); the Commander's only view
    through the camera (issue 23; defaults keep issue 22's callers)."""

    target_index: int
    rays: RayObservation | None = None


@dataclass(frozen=True)
class Judged:
    confirmed: bool
    target_index: int


@dataclass(frozen=True)
class PhaseChanged:
    """`target`: the target's name, for the Commander's seat only, as its page learns each target
    when the trial reaches it; None for the Driver (issue 23; the default keeps issue 22's callers)."""

    phase: Phase
    target_index: int | None
    targets_total: int
    target: str | None = None


Percept = Heard | Saw | Moved | Claimed | Judged | PhaseChanged


@dataclass(frozen=True)
class DoMove:
    move: Move


@dataclass(frozen=True)
class DoClaim:
    """Driver: "I found the target"."""


@dataclass(frozen=True)
class DoJudge:
    """Commander: confirm / reject the pending claim."""

    confirmed: bool


@dataclass(frozen=True)
class DoSay:
    text: str


@dataclass(frozen=True)
class DoLocalize:
    """The Commander's estimate of the Driver's pose."""

    x: float
    y: float
    heading: float | None


@dataclass(frozen=True)
class DoWait:
    """Nothing until the next percept."""


Turn = DoMove | DoClaim | DoJudge | DoSay | DoLocalize | DoWait


@dataclass(frozen=True)
class SeatInfo:
    role: Speaker
    targets_total: int  # the Driver's page shows "target k of 3"-style progress, never the object's name


class Agent(Protocol):
    def reset(self, info: SeatInfo) -> None: ...

    def perceive(self, percept: Percept) -> list[Turn]: ...
