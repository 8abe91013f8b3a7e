"""What the parts around a trial may do with it: narrow interfaces, so a robot backend or an
agent in a seat never holds the runtime itself (and never reaches into it)."""

from __future__ import annotations

from typing import Protocol

from app.trial.messages import Message
from sim.trial.state import TrialState
from sim.trial.vocabulary import FrameSource, Role


class Connection(Protocol):
    """One seat's way out: a socket, a relayed socket, an agent, the rover."""

    @property
    def role(self) -> str:
        """The seat's role (read-only here, so a seat may hold it as a `Role`)."""

    def deliver(self, message: Message) -> None:
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
