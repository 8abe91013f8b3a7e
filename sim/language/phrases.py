"""The Commander's words: the scripted templates (app/demo's Commander), the same with turns said as
presses of the buttons (the dialog Commander's), the frozen held-out set and the frozen personas.

Each kind of instruction has its templates; the scripted set is one template per kind, the words the
project's scripted Commander has always used; the held-out set (`held_out_commander.json`) was
paraphrased from the train split's Commander turns and frozen before the Driver's parser was tuned.
The personas (`personas/commander_*.json`: terse, chatty, typos, landmarks, metric) were written by
someone who had not read the parsers, from the train split's human turns, and frozen (their hashes
below) before the Driver's understanding was developed against them."""

from __future__ import annotations

import hashlib
import json
import random
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import NotRequired, TypedDict

HELD_OUT_PATH = Path(__file__).with_name("held_out_commander.json")
NUMBER_NAMES = "zero one two three four five six seven eight nine ten eleven twelve thirteen fourteen fifteen sixteen seventeen eighteen nineteen twenty".split()  # noqa: SIM905


class Phrasing(StrEnum):
    SCRIPTED = "scripted"
    HELD_OUT = "held_out"
    BUTTONS = "buttons"  # the scripted words with each turn as presses of Left or Right: the dialog Commander's


class Persona(StrEnum):
    """The frozen Commander personas: how five kinds of person phrase the same instructions."""

    TERSE = "terse"
    CHATTY = "chatty"
    TYPOS = "typos"
    LANDMARKS = "landmarks"
    METRIC = "metric"

    @property
    def path(self) -> Path:
        return PERSONAS_DIR / f"commander_{self.value}.json"


PERSONAS_DIR = Path(__file__).with_name("personas")
# sha256 of each persona's file as frozen: a persona is never edited to fit the parser.
PERSONA_SHA256 = {
    Persona.TERSE: "a49dcede09c3868301258789535ab90ddb5db0bff986f27fae20661cecac38fc",
    Persona.CHATTY: "2a1715787146e2f021d9b8e4661cb97fe814813481a90f844bf316b09f261d07",
    Persona.TYPOS: "fcc0eaa30440e9ee993ee8e06130bbc1a290a21814b3f4db1b1c59379805a866",
    Persona.LANDMARKS: "da1a9a5b65623effde90611d30bf397acf3efa911edc2c3675d5e5a4ecc8f19f",
    Persona.METRIC: "8eac56f8dd1a290da6a609aa7bdcfc4a576403bdac3289e6181a91cddfa06664",
}
STEP_CM = 7  # a forward move, for the personas that count in centimetres


class PhraseKind(StrEnum):
    ANNOUNCE = "announce"
    ASK_VIEW = "ask_view"
    FORWARD = "forward"
    FORWARD_THEN_TURN = "forward_then_turn"
    TURN_AT_WALL = "turn_at_wall"
    UNTIL_TARGET = "until_target"
    THERE = "there"
    REJECT = "reject"
    UNTIL_WALL = "until_wall"  # added after the frozen sets: theirs is the scripted set's


# A phrasing's JSON file (held_out_commander.json, personas/commander_*.json): per kind of
# instruction its templates, "turn" by 45-degree steps ("1" to "4").
class PhrasingFile(TypedDict):
    about: str
    numbers: str  # "digits" or "words"
    units: NotRequired[str]  # "cm": forward moves in centimetres
    turn: dict[str, list[str]]
    announce: list[str]
    ask_view: list[str]
    forward: list[str]
    forward_then_turn: list[str]
    turn_at_wall: list[str]
    until_target: list[str]
    there: list[str]
    reject: list[str]
    until_wall: NotRequired[list[str]]


@dataclass(frozen=True)
class Phrasebook:
    """One phrasing's templates: per kind of instruction, per turn (in 45-degree steps, 1 to 4),
    and how numbers are written ("digits" or "words"; steps in "cm" for the metric persona)."""

    numbers: str
    kinds: dict[PhraseKind, list[str]]
    turns: dict[int, list[str]]
    units: str | None = None

    @classmethod
    def from_json(cls, data: PhrasingFile) -> Phrasebook:
        return cls(
            numbers=data["numbers"],
            kinds={
                PhraseKind.ANNOUNCE: data["announce"],
                PhraseKind.ASK_VIEW: data["ask_view"],
                PhraseKind.FORWARD: data["forward"],
                PhraseKind.FORWARD_THEN_TURN: data["forward_then_turn"],
                PhraseKind.TURN_AT_WALL: data["turn_at_wall"],
                PhraseKind.UNTIL_TARGET: data["until_target"],
                PhraseKind.THERE: data["there"],
                PhraseKind.REJECT: data["reject"],
                PhraseKind.UNTIL_WALL: data.get("until_wall", SCRIPTED.kinds[PhraseKind.UNTIL_WALL]),
            },
            turns={int(steps): templates for steps, templates in data["turn"].items()},
            units=data.get("units"),
        )


SCRIPTED = Phrasebook(
    numbers="digits",
    kinds={
        PhraseKind.ANNOUNCE: ["now find the {thing}"],
        PhraseKind.ASK_VIEW: ["hi! what do you see around you? look around and tell me"],
        PhraseKind.FORWARD: ["go forward about {n} steps"],
        PhraseKind.FORWARD_THEN_TURN: ["go forward about {n} steps, then {turn}"],
        PhraseKind.TURN_AT_WALL: ["{turn} at the {wall}"],
        PhraseKind.UNTIL_TARGET: ["go forward until you see the {thing}"],
        PhraseKind.THERE: ["the {thing} should be right there"],
        PhraseKind.REJECT: ["no, that is not it"],
        PhraseKind.UNTIL_WALL: ["go forward until the {wall}"],
    },
    turns={1: ["turn slightly {d}"], 2: ["turn {d}"], 3: ["turn sharply {d}"], 4: ["turn around"]},
)


# The dialog Commander's words: people driving for it took "turn left" for one press of Left (45
# degrees) as often as for two, and were lost from the first leg; a count of presses is read one
# way. A turn at a wall is a walk to it, then the presses ("press left twice at the white wall"
# reads as pressing there, wherever that is).
BUTTONS = Phrasebook(
    numbers="digits",
    kinds=SCRIPTED.kinds | {PhraseKind.TURN_AT_WALL: ["go forward until the {wall}, then {turn}"]},
    turns={1: ["press {d} once"], 2: ["press {d} twice"], 3: ["press {d} 3 times"], 4: ["press left 4 times"]},
)


def load(phrasing: Phrasing | Persona) -> Phrasebook:
    if phrasing == Phrasing.SCRIPTED:
        return SCRIPTED
    if phrasing == Phrasing.BUTTONS:
        return BUTTONS
    if isinstance(phrasing, Persona):
        raw = phrasing.path.read_bytes()
        if hashlib.sha256(raw).hexdigest() != PERSONA_SHA256[phrasing]:
            raise ValueError(
                f"{phrasing.path} is not the frozen persona (its sha256 changed); personas are never edited"
            )
        return Phrasebook.from_json(json.loads(raw))
    return Phrasebook.from_json(json.loads(HELD_OUT_PATH.read_text()))


def style(name: str) -> Phrasing | Persona:
    """A phrasing by its name: "scripted", "held_out" or "persona:NAME"."""
    if name.startswith("persona:"):
        return Persona(name.removeprefix("persona:"))
    return Phrasing(name)


class Phrases:
    """Templates of one phrasing, filled in; which template of a kind is drawn from `seed`."""

    def __init__(self, phrasing: Phrasing | Persona, seed: int = 0) -> None:
        self.book = load(phrasing)
        self._rng = random.Random(seed)

    def _pick(self, options: list[str]) -> str:
        return options[self._rng.randrange(len(options))]

    def number(self, n: int) -> str:
        if self.book.units == "cm":
            return str(n * STEP_CM)
        return NUMBER_NAMES[n] if self.book.numbers == "words" and n < len(NUMBER_NAMES) else str(n)

    def turn(self, eighths: int) -> str | None:
        """A turn of `eighths` 45-degree steps (left positive) in words; None for no turn."""
        eighths = (eighths + 4) % 8 - 4
        if eighths == 0:
            return None
        side = "left" if eighths > 0 else "right"
        return self._pick(self.book.turns[min(abs(eighths), 4)]).format(d=side)

    def say(self, kind: PhraseKind, **slots: str | int) -> str:
        n = int(slots["n"]) if "n" in slots else None
        if n is not None:
            slots["n"] = self.number(n)
        text = self._pick(self.book.kinds[kind]).format(**slots)
        # "about 1 steps" read as a machine's words: one step is a step.
        return text.replace(f"{slots['n']} steps", f"{slots['n']} step") if n == 1 else text
