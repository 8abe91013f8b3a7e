"""What an agent in a seat perceives and what it may do: typed percepts in, typed turns out.

An agent is woken by what a person in its seat would react to (a chat message, the frame after its
move, a judged claim, a phase change), never by a timer, and answers with zero or more turns."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol

from robot_client.protocol import Move as Move  # the one move vocabulary: the wire's
from sim.robot.perception import RayObservation


class Phase(StrEnum):
    """Where a trial stands; the values are the strings its event log stores."""

    WAITING = "waiting"
    LOCALIZING = "localizing"
    NAVIGATING = "navigating"
    FINISHED = "finished"
    ABORTED = "aborted"

    @property
    def running(self) -> bool:
        """The phases the trial clock runs in (unless paused)."""
        return self in (Phase.LOCALIZING, Phase.NAVIGATING)

    @property
    def over(self) -> bool:
        return self in (Phase.FINISHED, Phase.ABORTED)


class Speaker(StrEnum):
    COMMANDER = "commander"
    DRIVER = "driver"


class Outcome(StrEnum):
    """What became of a move: executed, bumped into something (the robot stayed), or not executed."""

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
    result: Outcome
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


class TurnKind(StrEnum):
    SAY = "say"
    MOVE = "move"
    CLAIM = "claim"
    JUDGE = "judge"
    LOCALIZE = "localize"


@dataclass(frozen=True)
class Refused:
    """One of its turns was not allowed now, as a person's page shows an error: `reason` says why.
    A move asked for and refused comes as `Moved` (result REFUSED), as the Driver's page hears it."""

    turn: TurnKind
    reason: str


@dataclass(frozen=True)
class Paused:
    """The trial paused (True) or runs again (False); moves and claims are refused while paused."""

    paused: bool


Percept = Heard | Saw | Moved | Claimed | Judged | PhaseChanged | Refused | Paused


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
