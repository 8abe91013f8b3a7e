"""The frozen Driver personas: how five kinds of person describe what they see and report on what
they were told (`personas/driver_*.json`: terse, chatty, typos, landmarks, unsure), and how often
each is wrong (a side swapped, a wrong colour, an object missed, a step miscounted).

They were written from the train split's human Driver turns before the Commander's parser was read,
and frozen (their hashes below), so a bench against them measures the Commander on words it was not
fitted to. `sim.language.driver_phrasing` speaks in them."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import NotRequired, TypedDict

from sim.language.phrases import PERSONAS_DIR
from sim.language.vocab import Side


class DriverPersona(StrEnum):
    TERSE = "terse"
    CHATTY = "chatty"
    TYPOS = "typos"
    LANDMARKS = "landmarks"  # leads with objects and landmarks
    UNSURE = "unsure"  # hedges; mixes up left and right more than the others

    @property
    def path(self) -> Path:
        return PERSONAS_DIR / f"driver_{self.value}.json"


# sha256 of each persona's file as frozen: a persona is never edited to fit the Commander's parser.
DRIVER_PERSONA_SHA256 = {
    DriverPersona.TERSE: "1507b44e54bf4a7a5a78ee430116d1e8ee00290f4dc5f19f4e37b4ab87462fd0",
    DriverPersona.CHATTY: "a58c95fd89dd0057b17667b532924298ca86d656bf2c608799f35215dcbf96e1",
    DriverPersona.TYPOS: "36b47af9fa692e4e35dfa40312ff01f171e81bb926003028c5cdecbf2aa86444",
    DriverPersona.LANDMARKS: "72dcee3daec8f9c510b9f89e60099770b0655754a00f24d182ec0264a9b1ad42",
    DriverPersona.UNSURE: "0399ce2b838d34a668b90b16bc40460d6c14b89783e2a67033f3860ed2ea691e",
}


class Slip(StrEnum):
    """The ways a persona is wrong now and then, as people are."""

    SWAP_LEFT_RIGHT = "swap_left_right"  # names the other side
    WRONG_COLOUR = "wrong_colour"  # names a wall by another colour (or answers a colour question wrongly)
    MISS_OBJECT = "miss_object"  # does not mention an object in view
    STEPS_OFF_BY_ONE = "steps_off_by_one"  # drives one step more or fewer than told


class Lead(StrEnum):
    """What a description names first."""

    WALLS = "walls"
    OBJECTS = "objects"


class Message(StrEnum):
    """A persona's kinds of message, each a list of templates."""

    WALL = "wall"  # {colour} {side} {distance}
    OBJECT = "object"  # {thing} {side}
    OPEN = "open"  # {side}
    CORNER = "corner"
    CORRIDOR = "corridor"
    JOIN = "join"
    LOOK_AROUND = "look_around"  # {clauses}
    YES = "yes"  # {colour} {side}, optional
    NO = "no"
    DONE = "done"  # {view}, optional
    BLOCKED = "blocked"  # {n} {view}, optional
    CLAIM = "claim"  # {thing}
    CONFUSED = "confused"
    QUESTION = "question"


class DriverPersonaFile(TypedDict):
    about: str
    numbers: str  # "digits" or "words"
    lead: str
    sides: dict[str, list[str]]
    near: list[str]
    far: list[str]
    things: NotRequired[dict[str, list[str]]]  # "jar", "mug", "paddle": other names for each
    colours: NotRequired[dict[str, list[str]]]  # a colour's spellings
    errors: dict[str, float]
    wall: list[str]
    object: list[str]
    open: list[str]
    corner: list[str]
    corridor: list[str]
    join: list[str]
    look_around: list[str]
    yes: list[str]
    no: list[str]
    done: list[str]
    blocked: list[str]
    claim: list[str]
    confused: list[str]
    question: list[str]


@dataclass(frozen=True)
class DriverPersonaBook:
    """One persona's words: templates per kind of message, the names of sides, distances, things
    and colours, and how often it slips."""

    numbers: str
    lead: Lead
    sides: dict[Side, list[str]]
    near: list[str]
    far: list[str]
    things: dict[str, list[str]]
    colours: dict[str, list[str]]
    slips: dict[Slip, float]
    says: dict[Message, list[str]]

    @classmethod
    def from_json(cls, data: DriverPersonaFile) -> DriverPersonaBook:
        raw: dict[str, list[str]] = {kind.value: data[kind.value] for kind in Message}
        return cls(
            numbers=data["numbers"],
            lead=Lead(data["lead"]),
            sides={Side(side): names for side, names in data["sides"].items()},
            near=data["near"],
            far=data["far"],
            things=data.get("things", {}),
            colours=data.get("colours", {}),
            slips={Slip(slip): p for slip, p in data["errors"].items()},
            says={Message(kind): templates for kind, templates in raw.items()},
        )


def load_driver_persona(persona: DriverPersona) -> DriverPersonaBook:
    raw = persona.path.read_bytes()
    if hashlib.sha256(raw).hexdigest() != DRIVER_PERSONA_SHA256[persona]:
        raise ValueError(f"{persona.path} is not the frozen persona (its sha256 changed); personas are never edited")
    return DriverPersonaBook.from_json(json.loads(raw))
