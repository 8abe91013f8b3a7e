"""A trial's events: one pydantic model per kind; its fields are the stored JSON payload.

`LoggedEvent` is an event as the log holds it (seq, kind, stamp, payload dict): what the exports
and the replay read. `typed(logged)` gives the model. Payloads keep the shape they have always
had, so logs written before these models existed read the same.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field

from sim.core.rays import RayObservation
from sim.trial.vocabulary import FrameSource, Move, Outcome, Phase, PoseSource, Role


@dataclass(frozen=True)
class LoggedEvent:
    seq: int
    kind: str
    t_ns: int
    payload: dict[str, Any]

    def is_(self, *models: type[Event]) -> bool:
        """Whether this event is of one of these kinds: readers name the models, never the strings."""
        return any(self.kind == model.kind for model in models)


class Event(BaseModel):
    model_config = ConfigDict(frozen=True, extra="ignore")
    kind: ClassVar[str]
    omit_if_none: ClassVar[tuple[str, ...]] = ()  # keys stored only when set

    def payload(self) -> dict[str, Any]:
        data = self.model_dump(mode="json")
        for key in self.omit_if_none:
            if data.get(key) is None:
                data.pop(key, None)
        return data


class TrialCreated(Event):
    kind = "trial_created"
    omit_if_none = ("start", "join_timeout_s", "seed", "time_cap_s")
    maze: str
    targets: list[str]
    backend: str
    driver: str
    commander: str = "human"  # logs from before agent Commanders have no such key
    # The simulated robot's start (x, y, theta), where one was chosen (a benchmark's recorded start
    # in self-play); without it the simulator backend draws one. The experimenter's record only.
    start: tuple[float, float, float] | None = None
    # A study's lobby paired the seats: one still unopened this long after creation aborts the
    # trial. In the log, so a restarted server (or another process) keeps the same deadline.
    join_timeout_s: float | None = None
    # The agents' seed, where one was chosen (self-play repeats an offline trial); else the trial's id.
    seed: int | None = None
    # A study's practice: once its clock has run this long the trial is aborted (the time is up).
    time_cap_s: float | None = None


class Connected(Event):
    kind = "connect"
    role: Role


class Disconnected(Event):
    kind = "disconnect"
    role: Role


class PhaseChanged(Event):
    kind = "phase"
    omit_if_none = ("reason",)
    phase: Phase
    target_index: int | None = None
    reason: str | None = None  # why the trial was aborted, where one was given (logs before it have none)


class Paused(Event):
    kind = "paused"
    omit_if_none = ("note",)
    reason: str
    note: str | None = None  # the experimenter's words on why, where typed (seats see it)


class Resumed(Event):
    kind = "resumed"
    reason: str


class Restarted(Event):
    """The first event a server writes on reopening a running trial: the clock stopped at the
    event before, so the time the server was down is not scored, and it stays stopped for the
    seats of the process before (`paused`: their pause reasons, as `Paused` would add them)."""

    kind = "restarted"
    paused: list[str] = []


class StillAway(Event):
    """Logged every `AWAY_MARK_S` while a participant of a running trial is away: the server was
    up at this stamp. After a crash the grace period goes on from the last event before it, so
    the time away before the crash counts and the downtime does not."""

    kind = "still_away"
    roles: list[Role]


class Chat(Event):
    kind = "chat"
    role: Role
    text: str


class MoveRequested(Event):
    kind = "move_requested"
    move_id: str
    action: Move


class MoveExecuted(Event):
    kind = "move_executed"
    omit_if_none = ("reason",)
    move_id: str
    action: Move
    outcome: Outcome
    collision: bool = False
    reason: str | None = None


class MovesRefused(Event):
    """A run of move requests refused as they came (the trial not running, a move still
    executing, too soon after the last), for one reason: logged once, with how many, when the
    run ends (another event, another reason, or `REFUSED_RUN_S` after its first), so a flood of
    requests is not a flood of events. A move the robot refused after it was asked for is a
    `MoveExecuted` with outcome `refused`."""

    kind = "moves_refused"
    reason: str
    count: int = 1


class FrameRecorded(Event):
    """A camera image stored. `rays` and `jpeg` are what it shows, for the seats of the process that
    recorded it (the simulator's rays, the image itself); never logged: the file holds the image."""

    model_config = ConfigDict(frozen=True, extra="ignore", arbitrary_types_allowed=True)
    kind = "frame"
    frame_id: int
    source: FrameSource = FrameSource.DRIVER
    path: str
    capture_ns: int
    width: int
    height: int
    mime: str = "image/jpeg"
    rays: RayObservation | None = Field(default=None, exclude=True)
    jpeg: bytes | None = Field(default=None, exclude=True, repr=False)


class PoseSampled(Event):
    kind = "pose"
    x: float
    y: float
    heading: float
    source: PoseSource = PoseSource.SIM


class Localized(Event):
    kind = "localization"
    x: float
    y: float
    heading: float | None = None


class TargetClaimed(Event):
    kind = "target_claimed"
    target: str
    target_index: int
    frame_id: int


class TargetConfirmed(Event):
    kind = "target_confirmed"
    target: str
    target_index: int
    within_m: float | None = None  # ground truth where the backend knows the pose
    truly_within: bool | None = None


class TargetRejected(Event):
    kind = "target_rejected"
    target: str
    target_index: int
    within_m: float | None = None
    truly_within: bool | None = None


class BadMessage(Event):
    kind = "bad_message"
    role: Role
    error: str


KINDS: dict[str, type[Event]] = {cls.kind: cls for cls in Event.__subclasses__()}  # every kind above


def typed(event: LoggedEvent) -> Event | None:
    """The model of a logged event; None for a kind this code does not know."""
    cls = KINDS.get(event.kind)
    return None if cls is None else cls.model_validate(event.payload)
