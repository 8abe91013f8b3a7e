"""What the parts around a trial may do with it: narrow interfaces, so a robot backend or an
agent in a seat never holds the runtime itself (and never reaches into it)."""

from __future__ import annotations

from typing import Any, Protocol

from app.trial.state import TrialState
from app.trial.vocabulary import FrameSource, Move, Outcome, Role


class Connection(Protocol):
    """One seat's way out: a socket, a relayed socket, an agent, the rover."""

    @property
    def role(self) -> str:
        """The seat's role (read-only here, so a seat may hold it as a `Role`)."""

    def deliver(self, message: dict[str, Any]) -> None:
        """Queue a message for this seat; never blocks."""


class TrialView(Protocol):
    trial_id: int

    @property
    def state(self) -> TrialState:
        """The trial as its log says now (read it; change it only through the methods)."""

    def join(self, conn: Connection) -> None: ...

    def leave(self, conn: Connection) -> None: ...

    def report_bad_message(self, role: Role, error: str) -> None:
        """Record a message that was refused (from a rover, a camera, an agent)."""


class RobotTrial(TrialView, Protocol):
    """The trial as a robot backend sees it: it fills the robot seat and records cameras."""

    def record_frame(self, jpeg: bytes, capture_ns: int, width: int, height: int, source: FrameSource) -> int:
        """Store one camera image and its `frame` event; returns the frame id."""

    def record_pose(self, pose: tuple[float, float, float]) -> None:
        """A pose (x, y, heading) of the robot measured from outside it (the overhead tracker)."""


class SeatTrial(TrialView, Protocol):
    """The trial as an agent's seat sees it: it may speak in the chat, and end the trial on its caps."""

    def say(self, role: Role, text: str) -> None: ...

    def abort(self, reason: str | None = None) -> None:
        """End the trial, aborted, with the reason logged (an agent's cap)."""


class DriverTrial(SeatTrial, Protocol):
    """The trial as an agent Driver's seat sees it: no true pose, no map, no particle filter."""

    async def request_move(self, action: Move) -> Outcome:
        """Move the robot under the same rules as a person's move; returns what became of it."""

    def claim(self) -> None:
        """Claim the current target (raises `Refused` when not allowed now)."""


class CommanderTrial(SeatTrial, Protocol):
    """The trial as an agent Commander's seat sees it: what a person's Commander socket may send."""

    def localize(self, x: float, y: float, heading: float | None) -> None:
        """Mark the Driver on the map (a `localization` event), as a person's `localize` message does."""

    def judge(self, confirmed: bool) -> None:
        """Confirm or reject the pending claim (raises `Refused` when there is none)."""
