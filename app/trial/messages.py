"""What a seat may send over its socket: one pydantic model per message, a discriminated union.

Every message carries the seat's token (checked on each message, not only at connect). Types are
strict: a coordinate "0.5" or true is a bad message, not a number (integers are numbers).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

from app.trial import vocabulary as v
from app.trial.vocabulary import Role
from sim.core.geometry import TABLE_HEIGHT_M, TABLE_WIDTH_M

MAX_CHAT_CHARS = 500


class _Message(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    token: str = Field(max_length=512)


class Chat(_Message):
    type: Literal["chat"]
    text: str = Field(min_length=1, max_length=MAX_CHAT_CHARS)


class Move(_Message):
    type: Literal["move"]
    action: v.Move
    move_id: str | None = Field(default=None, max_length=64)


class Localize(_Message):
    type: Literal["localize"]
    x: float = Field(ge=0.0, le=TABLE_WIDTH_M)
    y: float = Field(ge=0.0, le=TABLE_HEIGHT_M)
    heading: float | None = Field(default=None, ge=-7.0, le=7.0)  # radians


class Claim(_Message):
    type: Literal["claim"]


class Confirm(_Message):
    type: Literal["confirm"]


class Reject(_Message):
    type: Literal["reject"]


class Ping(_Message):
    type: Literal["ping"]


SeatMessage = Annotated[Chat | Move | Localize | Claim | Confirm | Reject | Ping, Field(discriminator="type")]
seat_message = TypeAdapter(SeatMessage)

# Which role may send which message.
ALLOWED: dict[str, set[str]] = {
    Role.COMMANDER: {"chat", "localize", "confirm", "reject", "ping"},
    Role.DRIVER: {"chat", "move", "claim", "ping"},
}
