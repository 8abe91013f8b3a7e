"""What a seat may send over its socket: one pydantic model per message, a discriminated union.

Every message carries the seat's token (checked on each message, not only at connect). Types are
strict: a coordinate "0.5" or true is a bad message, not a number (integers are numbers).
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import StrEnum
from typing import Annotated, Literal, NotRequired, TypedDict

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

from sim.core.geometry import TABLE_HEIGHT_M, TABLE_WIDTH_M
from sim.trial.commands import Action, Claim, Judge, Localize, RequestMove, Say
from sim.trial.vocabulary import Move

MAX_CHAT_CHARS = 500


class ServerMessage(StrEnum):
    """The `type` of each message the server sends a seat's or a watcher's socket."""

    WELCOME = "welcome"  # on joining: where the trial stands and the dialog so far
    EVENT = "event"  # one logged event, as this role may hear it
    STATUS = "status"  # the clock, seats and pauses
    ERROR = "error"  # a message refused, with a code
    MOVE_REFUSED = "move_refused"  # to the Driver: its move request refused as it came, and why
    REPLACED = "replaced"  # the seat was opened elsewhere
    BELIEF = "belief"  # the particle filter's, to watchers
    LDH_BELIEF = "ldh_belief"  # the LDH model's, to watchers


Message = Mapping[str, object]  # any message the server sends: one of the typed ones below, or a reply


class EventMessage(TypedDict):
    """One logged event, as a role may hear it (`views.view`)."""

    type: ServerMessage
    seq: int
    kind: str
    t_ns: int
    payload: dict[str, object]


class StatusMessage(TypedDict):
    """Where the trial stands (docs/platform.md, "status")."""

    type: ServerMessage
    phase: str
    target_index: int
    targets_total: int
    elapsed_s: float
    running: bool
    moves: int
    paused: list[str]
    waiting_for: list[str]
    abort_reason: str | None
    pause_note: str | None
    claim_pending: bool
    join_left_s: float | None


class Photo(TypedDict):
    """A frame for a page: a claim's, or the Driver's latest (base64 JPEG; None: not stored)."""

    frame_id: int
    jpeg: str | None


class WelcomeMessage(TypedDict):
    type: ServerMessage
    role: str
    trial_id: int
    phase: str
    target_index: int
    targets_total: int
    connected: list[str]
    seats_needed: list[str]
    paused: list[str]
    pending_claim: bool
    last_seq: int
    history: list[EventMessage]
    status: StatusMessage
    target: NotRequired[str | None]  # the Commander's
    localization: NotRequired[dict[str, object] | None]  # the Commander's own mark; the experimenter's
    claim: NotRequired[Photo]  # the Commander's pending claim
    frame: NotRequired[Photo]  # the Driver's and the experimenter's
    pose: NotRequired[tuple[float, float, float] | None]  # the experimenter's
    targets: NotRequired[list[str]]


class TrialSnapshot(TypedDict):
    """One live trial on the experimenter's dashboard (`/experimenter/api/trials`)."""

    trial_id: int
    phase: str
    target_index: int
    target: str | None
    elapsed_s: float
    moves: int
    collisions: int
    pose: tuple[float, float, float] | None
    paused: list[str]
    pause_note: str | None
    seats: dict[str, bool]
    waiting_for: list[str]
    backend: str
    localization: dict[str, object] | None
    maze: str
    belief: Message | None


class _Message(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    token: str = Field(max_length=512)


class ChatMessage(_Message):
    type: Literal["chat"]
    text: str = Field(min_length=1, max_length=MAX_CHAT_CHARS)


class MoveMessage(_Message):
    type: Literal["move"]
    action: Move
    move_id: str | None = Field(default=None, max_length=64)


class LocalizeMessage(_Message):
    type: Literal["localize"]
    x: float = Field(ge=0.0, le=TABLE_WIDTH_M)
    y: float = Field(ge=0.0, le=TABLE_HEIGHT_M)
    heading: float | None = Field(default=None, ge=-7.0, le=7.0)  # radians


class ClaimMessage(_Message):
    type: Literal["claim"]


class ConfirmMessage(_Message):
    type: Literal["confirm"]


class RejectMessage(_Message):
    type: Literal["reject"]


class PingMessage(_Message):
    type: Literal["ping"]


SeatMessage = Annotated[
    ChatMessage | MoveMessage | LocalizeMessage | ClaimMessage | ConfirmMessage | RejectMessage | PingMessage,
    Field(discriminator="type"),
]
seat_message = TypeAdapter(SeatMessage)


def action_of(message: SeatMessage) -> Action | None:
    """The seat's action a message asks for (None: a ping); which seat may take it is the
    referee's rule (`sim.trial.commands.MAY`)."""
    match message:
        case ChatMessage(text=text):
            return Say(text)
        case MoveMessage(action=move, move_id=move_id):
            return RequestMove(move, move_id)
        case LocalizeMessage(x=x, y=y, heading=heading):
            return Localize(x, y, heading)
        case ClaimMessage():
            return Claim()
        case ConfirmMessage() | RejectMessage():
            return Judge(isinstance(message, ConfirmMessage))
    return None
