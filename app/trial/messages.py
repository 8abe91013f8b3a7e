"""What a seat may send over its socket: one pydantic model per message, a discriminated union.

Every message carries the seat's token (checked on each message, not only at connect). Types are
strict: a coordinate "0.5" or true is a bad message, not a number (integers are numbers).
"""

from __future__ import annotations

from enum import StrEnum
from typing import Annotated, Literal

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
