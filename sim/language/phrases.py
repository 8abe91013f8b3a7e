"""The Commander's words: the scripted templates (app/demo's Commander) and the frozen held-out set.

Each kind of instruction has its templates; the scripted set is one template per kind, the words the
project's scripted Commander has always used; the held-out set (`held_out_commander.json`) was
paraphrased from the train split's Commander turns and frozen before the Driver's parser was tuned."""

from __future__ import annotations

import json
import random
from enum import StrEnum
from pathlib import Path
from typing import Any

HELD_OUT_PATH = Path(__file__).with_name("held_out_commander.json")
NUMBER_NAMES = "zero one two three four five six seven eight nine ten eleven twelve thirteen fourteen fifteen sixteen seventeen eighteen nineteen twenty".split()  # noqa: SIM905


class Phrasing(StrEnum):
    SCRIPTED = "scripted"
    HELD_OUT = "held_out"


class Kind(StrEnum):
    ANNOUNCE = "announce"
    ASK_VIEW = "ask_view"
    FORWARD = "forward"
    FORWARD_THEN_TURN = "forward_then_turn"
    TURN_AT_WALL = "turn_at_wall"
    UNTIL_TARGET = "until_target"
    THERE = "there"
    REJECT = "reject"


SCRIPTED: dict[str, Any] = {
    "numbers": "digits",
    Kind.ANNOUNCE: ["now find the {thing}"],
    Kind.ASK_VIEW: ["hi! what do you see around you? look around and tell me"],
    "turn": {"1": ["turn slightly {d}"], "2": ["turn {d}"], "3": ["turn sharply {d}"], "4": ["turn around"]},
    Kind.FORWARD: ["go forward about {n} steps"],
    Kind.FORWARD_THEN_TURN: ["go forward about {n} steps, then {turn}"],
    Kind.TURN_AT_WALL: ["{turn} at the {wall}"],
    Kind.UNTIL_TARGET: ["go forward until you see the {thing}"],
    Kind.THERE: ["the {thing} should be right there"],
    Kind.REJECT: ["no, that is not it"],
}


def load(phrasing: Phrasing) -> dict[str, Any]:
    if phrasing == Phrasing.SCRIPTED:
        return SCRIPTED
    held_out: dict[str, Any] = json.loads(HELD_OUT_PATH.read_text())
    return held_out


class Phrases:
    """Templates of one phrasing, filled in; which template of a kind is drawn from `seed`."""

    def __init__(self, phrasing: Phrasing, seed: int = 0) -> None:
        self.templates = load(phrasing)
        self._rng = random.Random(seed)

    def _pick(self, options: list[str]) -> str:
        return options[self._rng.randrange(len(options))]

    def number(self, n: int) -> str:
        return NUMBER_NAMES[n] if self.templates["numbers"] == "words" and n < len(NUMBER_NAMES) else str(n)

    def turn(self, eighths: int) -> str | None:
        """A turn of `eighths` 45-degree steps (left positive) in words; None for no turn."""
        eighths = (eighths + 4) % 8 - 4
        if eighths == 0:
            return None
        side = "left" if eighths > 0 else "right"
        return self._pick(self.templates["turn"][str(min(abs(eighths), 4))]).format(d=side)

    def say(self, kind: Kind, **slots: str | int) -> str:
        if "n" in slots:
            slots["n"] = self.number(int(slots["n"]))
        return self._pick(self.templates[kind]).format(**slots)
