"""Commander turns by paraphrase, labelled by construction: the moves people give (turns of every
size, counted walks, walks up to a wall or an object, going back, stopping) in the many ways
English says them, joined into chains and padded with the filler, hedges and slips of a chat.

The recorded Commanders almost never count steps or hedge a turn's size (the train split has 4
"slight" and no "steps"), and the rules label only the words they were written for, so without
these the reader met counts, small turns and chatty turns only in the platform's own words. Each
turn's program is built with its words, not parsed from them. The phrasings come from the train
split's words and everyday English; none of the benchmark's val_seen or test text, the gold set or
the frozen personas is read here.
"""

from __future__ import annotations

import random
from collections.abc import Callable

from sim.core.labels import WALL_LABELS
from sim.language.meaning import Clause, Op, Program
from sim.language.phrases import NUMBER_NAMES
from sim.language.reader import STEP_M

Move = tuple[str, Program]

_TURNS: dict[int, list[str]] = {
    1: [
        "turn slightly {d}",
        "turn {d} a little",
        "turn a little to the {d}",
        "slight {d}",
        "bear {d}",
        "veer {d} a bit",
        "angle {d} a bit",
        "turn {d} 45 degrees",
        "turn 45 degrees to your {d}",
        "just a small turn {d}",
        "ease {d} a little",
        "turn {d} a touch",
        "nudge {d}",
        "half turn {d}",
    ],
    2: [
        "turn {d}",
        "take a {d}",
        "make a {d} turn",
        "make a {d}",
        "go {d}",
        "hang a {d}",
        "turn to your {d}",
        "turn to the {d}",
        "take the {d}",
        "{d} turn",
        "turn {d} 90 degrees",
        "rotate {d}",
        "face {d}",
    ],
    3: [
        "turn sharply {d}",
        "sharp {d}",
        "hard {d}",
        "make a sharp {d} turn",
        "turn {d} 135 degrees",
        "turn most of the way {d}",
    ],
    4: [
        "turn around",
        "turn back",
        "u turn",
        "make a u-turn",
        "do a uturn",
        "spin around",
        "turn 180 degrees",
        "turn all the way around",
        "face the other way",
        "reverse direction",
        "do a 180",
        "turn round",
        "about turn",
        "flip around",
    ],
}
_FORWARD = [
    "go forward {n} steps",
    "move forward {n}",
    "{n} steps forward",
    "go straight {n} steps",
    "go ahead {n} steps",
    "drive {n} steps",
    "forward {n}",
    "straight {n}",
    "{n} more steps",
    "move up {n} steps",
    "take {n} steps forward",
    "go {n} steps",
    "roll forward {n} steps",
    "move about {n} steps ahead",
    "keep going straight for {n} steps",
    "go down the hallway for about {n} steps",
    "go along the wall for {n} steps",
    "continue ahead for {n} steps",
    "go straight, about {n} steps",
]
_UNTIL = [
    "go forward until the {x}",
    "go straight until you reach the {x}",
    "keep going until you hit the {x}",
    "go all the way to the {x}",
    "drive up to the {x}",
    "go till the {x}",
    "head to the {x}",
    "move toward the {x} until you get there",
    "continue to the {x}",
    "go straight to the {x}",
    "go forward until the {x} is in front of you",
    "go forward until the {x} is right in front of you",
    "go right up to the {x}",
]
# A turn where something is reached: a walk to it, then the turn (docs/language_gold.md).
_TURN_AT = [
    "turn {d} at the {x}",
    "make a {d} at the {x}",
    "take a {d} at the {x}",
    "turn {d} when you reach the {x}",
    "once you reach the {x}, turn {d}",
    "when you get to the {x} turn {d}",
    "at the {x} turn {d}",
    "turn {d} before the {x}",
    "take a {d} after the {x}",
    "make a {d} turn around the end of the {x}",
    "turn {d} around the {x}",
    "go to the {x} and turn {d}",
]
_TURN_AROUND_AT = ["u turn at the {x}", "turn around at the {x}", "make a u-turn after the {x}"]
_AT_WALL = ["edge", "edge of the maze", "end", "wall", "end of the hallway", "other edge"]
_BACK_TO = [
    "go back to the {x}",
    "head back to the {x}",
    "return to the {x}",
    "trace back to the {x}",
    "back out to the {x}",
    "now go back to the {x}",
    "go back toward the {x}",
]
_FOLLOW = [
    "follow the {c} walls",
    "follow the {c} wall",
    "go along the {c} walls",
    "stay along the {c} walls",
    "stay to the {s} of the {c} walls",
    "keep the {c} walls on your {o}",
    "follow along the {c} walls",
    "keep following the {c} wall",
    "hug the {c} wall",
]
_EXPECT = [
    "you should see the {x} on your {s}",
    "the {x} should be on your {s}",
    "you will see the {x} on your {s}",
    "{x} should be to your {s}",
    "you should have the {x} to your {s}",
]
_BACK = ["back up {n} steps", "go back {n} steps", "reverse {n} steps", "back up {n}", "go backwards {n}"]
_STOP = ["stop", "stop there", "wait", "hold on", "stop right there", "ok stop"]
_JOIN = [", then ", " then ", " and ", ". ", " and then ", ", and then ", ". then ", ", after that ", ", "]
_OPEN = ["ok", "okay so", "alright", "great", "good job", "now", "perfect", "nice", "next", "so", "right now", "cool"]
_ASK = [
    "i think you want to",
    "now i'd like you to",
    "can you",
    "could you",
    "please",
    "you should",
    "you need to",
    "let's",
    "go ahead and",
    "from here",
    "first",
    "i'd say",
]
# Words that say a move's size again, or nothing, after it: no clause of their own.
_AGAIN = {
    Op.TURN: [
        "about {deg} degrees",
        "a {deg} degree turn",
        "roughly {deg}",
        "like a {deg}",
        "not too far",
        "just a normal turn",
        "nothing fancy",
        "for me",
        "here",
    ],
    Op.FORWARD: [
        "nice and straight",
        "straight ahead",
        "nice and slow",
        "no turns yet",
        "for me",
        "or so",
        "carefully",
    ],
}
_CLOSE = ["please", "thanks", "if you can", "ok?", "right?", "and let me know", "and tell me what you see", "sorry"]
_THINGS = {
    "jar": ["jar", "glass jar"],
    "mug": ["mug", "coffee mug", "cup"],
    "paddle": ["paddle", "ping pong paddle", "ping-pong paddle", "bat", "racket"],
}
_ANY_WALL = ["wall", "end", "edge", "end of the hallway"]  # a walk up to whatever wall is ahead


def _number(rng: random.Random, n: int) -> str:
    style = rng.random()
    if style < 0.2:
        return f"{round(n * STEP_M * 100)} cm"
    return NUMBER_NAMES[n] if style < 0.55 else str(n)


def _typos(rng: random.Random, text: str) -> str:
    """A fast typist's slips: a letter dropped, doubled or two swapped, now and then (never in a
    number: a count misspelt is another count, or none)."""
    words = text.split(" ")
    for _ in range(rng.choice([0, 1, 1, 2])):
        i = rng.randrange(len(words))
        word = words[i]
        if len(word) < 3 or not word.isalpha() or word.lower() in NUMBER_NAMES:
            continue
        k = rng.randrange(len(word) - 1)
        slip = rng.choice(["drop", "double", "swap"])
        if slip == "drop":
            words[i] = word[:k] + word[k + 1 :]
        elif slip == "double":
            words[i] = word[:k] + word[k] + word[k:]
        else:
            words[i] = word[:k] + word[k + 1] + word[k] + word[k + 2 :]
    return " ".join(words)


def paraphrase_examples(seed: int, n: int = 3000) -> list[tuple[str, Program]]:
    """`n` Commander turns with the programs they mean."""
    rng = random.Random(seed)

    def turn() -> Move:
        size = rng.choice([1, 2, 2, 3, 4])
        side = rng.choice(["left", "right"])
        text = rng.choice(_TURNS[size]).format(d=side)
        eighths = 4 if size == 4 else size * (1 if side == "left" else -1)
        return text, (Clause.of(Op.TURN, eighths=eighths),)

    def forward() -> Move:
        steps = rng.randint(1, 15)
        text = rng.choice(_FORWARD).format(n=_number(rng, steps)).replace("cm steps", "cm")
        return text, (Clause.of(Op.FORWARD, steps=steps, until=None),)

    def until() -> Move:
        kind = rng.random()
        if kind < 0.5:
            label = rng.choice(WALL_LABELS).word
            words, until = f"{label} wall{rng.choice(['', 's'])}", label
        elif kind < 0.75:
            until = rng.choice(list(_THINGS))
            words = rng.choice(_THINGS[until])
        else:
            until, words = "wall", rng.choice(_ANY_WALL)
        return rng.choice(_UNTIL).format(x=words), (Clause.of(Op.FORWARD, steps=None, until=until),)

    def back() -> Move:
        steps = rng.randint(1, 6)
        text = rng.choice(_BACK).format(n=_number(rng, steps)).replace("cm steps", "cm")
        return text, (Clause.of(Op.BACK, place="previous", steps=steps),)

    def place() -> tuple[str, str]:
        """Something a walk ends at, in words, and its `until`."""
        kind = rng.random()
        if kind < 0.65:
            label = rng.choice(WALL_LABELS).word
            return f"{label} wall{rng.choice(['', 's', 's'])}", label
        if kind < 0.8:
            until = rng.choice(list(_THINGS))
            return rng.choice(_THINGS[until]), until
        return rng.choice(_AT_WALL), "wall"

    def turn_at() -> Move:
        words, until = place()
        walk = Clause.of(Op.FORWARD, steps=None, until=until)
        if rng.random() < 0.15:
            return rng.choice(_TURN_AROUND_AT).format(x=words), (walk, Clause.of(Op.TURN, eighths=4))
        side = rng.choice(["left", "right"])
        turning = Clause.of(Op.TURN, eighths=2 if side == "left" else -2)
        return rng.choice(_TURN_AT).format(d=side, x=words), (walk, turning)

    def back_to() -> Move:
        words, until = place()
        program = (Clause.of(Op.BACK, place="previous", steps=None), Clause.of(Op.FORWARD, steps=None, until=until))
        return rng.choice(_BACK_TO).format(x=words), program

    def follow() -> Move:
        label = rng.choice(WALL_LABELS).word
        side = rng.choice(["left", "right"])
        other = "right" if side == "left" else "left"
        return rng.choice(_FOLLOW).format(c=label, s=side, o=other), (Clause.of(Op.FOLLOW, label=label),)

    def expect() -> Move:
        words, label = place()
        label = label if label != "wall" else rng.choice(WALL_LABELS).word
        words = words if label in _THINGS or label in words else f"{label} walls"
        side = rng.choice(["left", "right"])
        return rng.choice(_EXPECT).format(x=words, s=side), (Clause.of(Op.EXPECT, label=label, side=side),)

    def stop() -> Move:
        return rng.choice(_STOP), (Clause.of(Op.STOP, claim=False),)

    def again(move: Move) -> Move:
        """The move, now and then with its size said again after it."""
        text, program = move
        op = program[0].op
        if op not in _AGAIN or rng.random() > 0.3:
            return move
        degrees = 45 * abs(int(program[0].args[0] or 0)) if op == Op.TURN else 0
        return f"{text}, {rng.choice(_AGAIN[op]).format(deg=degrees)}", program

    makers: list[Callable[[], Move]] = [turn, turn, forward, forward, until, until, back, stop]
    makers += [turn_at, turn_at, back_to, follow, expect]
    out = []
    for _ in range(n):
        moves = [again(rng.choice(makers)()) for _ in range(rng.choice([1, 1, 2, 2, 3]))]
        if any(program[0].op == Op.STOP for _, program in moves) and len(moves) > 1:
            moves = [m for m in moves if m[1][0].op != Op.STOP] or moves[:1]
        text = moves[0][0] if rng.random() < 0.7 else f"{rng.choice(_ASK)} {moves[0][0]}"
        for words, _ in moves[1:]:
            text += rng.choice(_JOIN) + words
        if rng.random() < 0.35:
            text = f"{rng.choice(_OPEN)}{rng.choice([' ', ', '])}{text}"
        if rng.random() < 0.25:
            text = f"{text} {rng.choice(_CLOSE)}"
        if rng.random() < 0.2:
            text = _typos(rng, text)
        if rng.random() < 0.3:
            text = text.capitalize() + rng.choice(["", ".", "!"])
        out.append((text, tuple(clause for _, program in moves for clause in program)))
    return out
