"""The closed vocabularies of the maze dialogs and typo-tolerant word matching.

The words are those the benchmark's Drivers and Commanders use (train split): wall colours, the
three objects, sides, turn sizes, counts. Both readers of the dialog use them: the Driver's
instruction parser (`instructions`) and the localizer's lexicon (`lexicon`). A misspelt word ("rigth", "yelow") is matched to the
vocabulary word within one edit (two for words of 8 letters or more); common English words are never corrected,
so "that" stays "that" rather than becoming "what"."""

from __future__ import annotations

import re
from collections.abc import Sequence
from enum import StrEnum
from functools import lru_cache

from sim.core.labels import Label
from sim.language import sectors
from sim.language.sectors import SECTOR_HEADING_OFFSET, Sector


class Side(StrEnum):
    AHEAD = "ahead"
    LEFT = "left"
    RIGHT = "right"
    BEHIND = "behind"


# The view sector of each side, and the heading steps of 45 degrees (counter-clockwise) from the
# Driver's heading to look at it.
SIDE_SECTOR = {Side.AHEAD: Sector.FRONT, Side.LEFT: Sector.LEFT, Side.BEHIND: Sector.BEHIND, Side.RIGHT: Sector.RIGHT}
SIDE_STEPS = {side: SECTOR_HEADING_OFFSET[sector] for side, sector in SIDE_SECTOR.items()}
SIDE_PHRASE = {Side.AHEAD: "ahead", Side.LEFT: "on my left", Side.RIGHT: "on my right", Side.BEHIND: "behind me"}

# The LDH features' colour and object words (what the `colours` localizer reads), and more that the
# dialog agents read: the maze's border, grey for white, other names for the objects.
LABEL_WORDS: dict[str, Label] = {
    **sectors.LABEL_WORDS,
    "border": Label.WHITE,  # the maze's edge
    "boundary": Label.WHITE,
    "grey": Label.WHITE,
    "gray": Label.WHITE,
    "blocks": Label.JAR,
    "cubes": Label.JAR,
    "bat": Label.PADDLE,  # "ping-pong bat" (val_seen)
    "racket": Label.PADDLE,  # "table-tennis-racket" (train split)
    "racquet": Label.PADDLE,
    # "a brownish wall way in the back" (a person driving in the ninth play) was no wall at all
    "reddish": Label.RED,
    "bluish": Label.BLUE,
    "blueish": Label.BLUE,
    "greenish": Label.GREEN,
    "brownish": Label.BROWN,
    "yellowish": Label.YELLOW,
    "whitish": Label.WHITE,
    "greyish": Label.WHITE,
    "grayish": Label.WHITE,
}
# The landmarks as the simulator's camera shows them, solids in their map colours (`OBJECT_LOOKS`):
# a person driving names them so ("something pink ahead"). Read only as written, never as what a
# misspelling stands for ("real" is not "teal"); no benchmark turn uses them.
CAMERA_COLOUR_WORDS = {
    "pink": Label.MUG,
    "cyan": Label.JAR,
    "turquoise": Label.JAR,
    "teal": Label.JAR,
    "olive": Label.PADDLE,
    "khaki": Label.PADDLE,
}
# How the Commander and the Driver name each object.
OBJECT_WORDS = {Label.JAR: "jar of blocks", Label.MUG: "coffee mug", Label.PADDLE: "ping-pong paddle"}
# What each looks like in the simulator's camera: a solid in its map colour (`sim.core.labels`).
OBJECT_LOOKS = {Label.JAR: "light blue", Label.MUG: "pink", Label.PADDLE: "olive green"}

NUMBER_WORDS = {
    "one": 1,
    "two": 2,
    "three": 3,
    "four": 4,
    "five": 5,
    "six": 6,
    "seven": 7,
    "eight": 8,
    "nine": 9,
    "ten": 10,
    "eleven": 11,
    "twelve": 12,
    "thirteen": 13,
    "fourteen": 14,
    "fifteen": 15,
    "sixteen": 16,
    "seventeen": 17,
    "eighteen": 18,
    "nineteen": 19,
    "twenty": 20,
    "thirty": 30,
    "forty": 40,
    "dozen": 12,
    "couple": 2,
    "few": 3,
}
ORDINAL_WORDS = {
    **{"first": 1, "second": 2, "third": 3, "fourth": 4, "fifth": 5, "next": 1},
    **{"1st": 1, "2nd": 2, "3rd": 3, "4th": 4, "5th": 5},
}
# Words that make a turn an eighth ("veer left a bit") or three ("a hard right") rather than two.
SLIGHT_WORDS = frozenset({"slightly", "slight", "bit", "little", "veer", "bear"})
SHARP_WORDS = frozenset({"sharply", "sharp", "hard"})

KEYWORDS = frozenset(
    [*LABEL_WORDS, *NUMBER_WORDS, *ORDINAL_WORDS, *(s.value for s in Side)]
    + [
        "turn",
        "turned",
        "forward",
        "stuck",
        "forwards",
        "straight",
        "around",
        "slightly",
        "slight",
        "sharply",
        "sharp",
        "steps",
        "step",
        "until",
        "wall",
        "walls",
        "stop",
        "there",
        "found",
        "claim",
        "start",
        "started",
        "beginning",
        "back",
        "where",
        "what",
        "see",
        "describe",
        "surroundings",
        "front",
        "corridor",
        "corner",
        "opening",
        "towards",
        "toward",
        "reach",
        "reached",
        "twice",
        "again",
        "move",
        "drive",
        "continue",
        "keep",
        "coffee",
        "objective",
        "target",
        "next",
        "u-turn",
        "spin",
        "rotate",
        "little",
        "veer",
        "bear",
    ]
)
# Common words one edit from a keyword, never corrected.
COMMON = frozenset(
    [
        "nice",
        "fine",
        "line",
        "live",
        "give",
        "dive",
        "walk",
        "call",
        "fall",
        "tall",
        "ball",
        "hall",
        "grown",
        "burn",
        "that",
        "this",
        "then",
        "than",
        "them",
        "they",
        "their",
        "here",
        "have",
        "want",
        "will",
        "with",
        "went",
        "were",
        "what",
        "when",
        "whats",
        "sees",
        "seen",
        "show",
        "slow",
        "sign",
        "step",
        "stay",
        "best",
        "rest",
        "test",
        "cell",
        "tell",
        "well",
        "fell",
        "felt",
        "lift",
        "lent",
        "rent",
        "bend",
        "send",
        "sent",
        "spend",
        "tight",
        "light",
        "night",
        "might",
        "sight",
        "fight",
        "eight",
        "weight",
        "high",
        "right",
        "write",
        "wrote",
        "bright",
        "bring",
        "more",
        "most",
        "made",
        "make",
        "take",
        "also",
        "some",
        "same",
        "done",
        "gone",
        "none",
        "once",
        "only",
        "over",
        "your",
        "yours",
        "very",
        "just",
        "like",
        "good",
        "great",
        "okay",
        "sure",
        "nope",
        "yeah",
        "yes",
        "sorry",
        "wait",
        "hold",
        "look",
        "looks",
        "near",
        "past",
        "last",
        "left",
        "side",
        "sides",
        "mine",
        "black",
        "mind",
        "into",
        "onto",
        "unto",
        "down",
        "town",
        "turns",
        "tune",
        "mouse",
        "house",
        "order",
        # A person's chat ("for a while", "back and forth", "no clue", "sounds good", "i read it"):
        # read as "white", "fourth", "blue", "found", "red", they put colours and claims in words.
        "while",
        "forth",
        "these",
        "read",
        "hear",
        "dear",
        "fear",
        "year",
        "wear",
        "tear",
        "gear",
        "ground",
        "sound",
        "wound",
        "bound",
        "clue",
        "glue",
        "fellow",
        "greet",
        "height",
        "share",
        "stare",
        "smart",
        "seek",
        "star",
        "fire",
        "tone",
        "zone",
        "bone",
    ]
)
_YOU = re.compile(r"\bu\b(?![\s-]*tu)")  # "what do u see": "you", where "u turn" (and "u tuen") is a u-turn
_WORD = re.compile(r"[a-z0-9]+(?:-[a-z]+)?|[?]")


def _distance(a: str, b: str, limit: int) -> int:
    """Optimal string alignment distance (edits, adjacent swaps count one), capped at limit + 1."""
    if abs(len(a) - len(b)) > limit:
        return limit + 1
    prev2: list[int] = []
    prev = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        cur = [i] + [0] * len(b)
        for j, cb in enumerate(b, 1):
            cur[j] = min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (ca != cb))
            if i > 1 and j > 1 and ca == b[j - 2] and a[i - 2] == cb:
                cur[j] = min(cur[j], prev2[j - 2] + 1)
        prev2, prev = prev, cur
    return prev[-1]


# A chat's shorthand for the maze's words ("turn r", "fwd 3", "l 2"): one or two letters no
# speller would correct, and "r" read as nothing made the reader guess a left turn.
SHORTHAND = {
    "ur": "your",
    "l": "left",
    "lef": "left",
    "r": "right",
    "lft": "left",
    "rt": "right",
    "fwd": "forward",
    "fw": "forward",
    "str8": "straight",
    "lil": "little",
}


@lru_cache(maxsize=1 << 16)
def correct(word: str) -> str:
    """The vocabulary word a misspelling or shorthand stands for, or the word itself (remembered:
    an unknown word is measured against every keyword, and the agents read each message's words
    several times over)."""
    if word in SHORTHAND:
        return SHORTHAND[word]
    if len(word) < 4 or word in KEYWORDS or word in COMMON or not word.isalpha():
        return word
    limit = 1 if len(word) < 8 else 2  # two edits turn "follow" into "yellow"
    best, best_d = word, limit + 1
    for key in sorted(KEYWORDS):
        d = _distance(word, key, limit)
        if d < best_d:
            best, best_d = key, d
    return best


def words(text: str) -> list[str]:
    """Lower-case words of `text`, spelling corrected; "?" kept as a word."""
    text = _YOU.sub("you", text.lower().replace("'", "").replace("u-turn", "uturn")).replace("-", " ")
    return [correct(w) for w in _WORD.findall(text)]


def number(word: str) -> int | None:
    """3 for "3" or "three"; None for anything else."""
    if word.isdigit():
        return int(word)
    return NUMBER_WORDS.get(word)


# "right" that means "directly" ("right up to the jar", "right in front", "right now") or "correct"
# ("that's right") in a Commander's instruction, not a turn: by the word after it, or before it.
# ("right at the red wall" is a turn there; a Driver's "right at" is where a wall is not,
# `lexicon`'s own test.)
_RIGHT_AS_DIRECTLY = frozenset({"in", "behind", "ahead", "next", "by", "beside", "there", "here", "now", "up", "on"})
_RIGHT_AS_CORRECT = frozenset({"thats", "its", "is", "alright", "all"})
# Words before "right" that make it the turn whatever follows ("take a right in front of the jar").
_TURN_LEAD = frozenset(
    {"a", "the", "your", "turn", "turning", "take", "make", "look", "hang", "bear", "veer", "hard", "sharp"}
)


def turns_to(ws: Sequence[str], k: int) -> bool:
    """Whether `ws[k]` can be the side of a turn: "left", or "right" that does not mean "directly"
    or "correct"."""
    if ws[k] == "left":
        return True
    if ws[k] != "right":
        return False
    after = ws[k + 1] if k + 1 < len(ws) else ""
    before = ws[k - 1] if k > 0 else ""
    return before in _TURN_LEAD or after not in _RIGHT_AS_DIRECTLY and before not in _RIGHT_AS_CORRECT


def times_turned(ws: Sequence[str]) -> int:
    """How many times words say to make their turn: 2 for "twice", "two right turns" or "left 2
    times", and so on up to a whole circle's four; else 1."""
    if "twice" in ws:
        return 2
    for i, w in enumerate(ws):
        n = number(w)
        if n is not None and 2 <= n <= 4 and {"turns", "times"} & set(ws[i + 1 : i + 3]):
            return n
    return 1


def wall_name(label: Label) -> str:
    """ "red wall", "coffee mug": how a label is named in a sentence."""
    return OBJECT_WORDS.get(label, f"{label.word} wall")
