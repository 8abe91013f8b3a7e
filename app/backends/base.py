"""`RobotBackend`: the robot seat of a trial.

The trial runtime only talks to this protocol; the simulator (`app.backends.sim`) and the
remote rover (`app.rover.backend`) implement it. Actions are the Driver's three moves.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from sim.trial.vocabulary import Move, Outcome, PoseSource

if TYPE_CHECKING:
    from sim.core.rays import RayObservation


@dataclass(frozen=True)
class MoveOutcome:
    """What became of one move: `ok`, `collision` (the robot did not move) or `refused`."""

    action: Move
    outcome: Outcome
    reason: str | None = None


@dataclass(frozen=True)
class Frame:
    """One encoded camera image and when it was captured (server clock, nanoseconds)."""

    jpeg: bytes
    capture_ns: int
    width: int
    height: int
    observation: RayObservation | None = None  # the 13 rays, where known without perceiving (simulator)


class BackendUnavailable(RuntimeError):
    """The robot cannot be reached (not connected, or lost); the message says which and why."""


@runtime_checkable
class RobotBackend(Protocol):
    """The robot seat. `execute` returns once the move is done (or refused); each executed
    move is followed by at least one frame on `frames()`.

    `pose_source` says where `pose()` comes from: the simulator's own truth (`sim`), known as
    soon as a move ends and recorded by the runtime then, or a tracker outside the robot
    (`tracker`), which records its poses itself as it sees them."""

    pose_source: PoseSource

    async def connect(self) -> None: ...

    async def execute(self, action: Move) -> MoveOutcome: ...

    def frames(self) -> AsyncIterator[Frame]: ...

    def pose(self) -> tuple[float, float, float] | None:
        """True pose (x, y, theta) in metres/radians where known (simulator, overhead tracker)."""
        ...

    async def close(self) -> None: ...
