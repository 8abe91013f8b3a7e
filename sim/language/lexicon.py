"""From a dialog's words to facts about what the robot sees.

A Driver's description ("a red wall to my left, yellow far ahead, no blue", "I'm in a corridor",
"facing the red and yellow corner") becomes `Fact`s: a label, a shape or a pair of labels side by
side, in the sectors named (front / left / behind / right; none named: anywhere in view), near or
far, asserted or negated. A Commander's question is read the same way ("your" as "my"), and the
Driver's yes / no answer asserts or negates it. `turn_steps` reads a reported turn ("I turned
around") as heading steps of 45 degrees, counter-clockwise.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, replace
from enum import StrEnum

from sim.core.labels import OBJECT_LABELS, Label
from sim.language.sectors import SECTOR_HEADING_OFFSET, SECTOR_WORDS, Sector
from sim.language.vocab import CAMERA_COLOUR_WORDS, LABEL_WORDS, NUMBER_WORDS, correct, number


class ViewKind(StrEnum):
    LABEL = "label"  # the label is seen in the sectors
    EDGE = "edge"  # the maze's edge (the table's white border) is seen in the sectors
    CORRIDOR = "corridor"  # open space: the sector's rays travel far
    CORNER = "corner"  # walls close ahead and to one side
    DEAD_END = "dead_end"  # walls close ahead, left and right
    NEXT_TO = "next_to"  # two labels side by side in one view


class Distance(StrEnum):
    ANY = "any"
    NEAR = "near"
    FAR = "far"


class Source(StrEnum):
    DESCRIPTION = "description"  # the Driver's own words
    ANSWER = "answer"  # a Commander's question the Driver answered yes / no / with a side


@dataclass(frozen=True)
class Fact:
    kind: ViewKind
    sectors: tuple[Sector, ...]  # alternatives ("ahead to the right"); (ANY,) when none named
    label: Label | None = None
    other: Label | None = None  # the second label of NEXT_TO
    distance: Distance = Distance.ANY
    negated: bool = False
    source: Source = Source.DESCRIPTION


@dataclass(frozen=True)
class QuestionFacts:
    facts: tuple[Fact, ...]
    labels: tuple[Label, ...]  # in order of mention
    sectors: tuple[Sector, ...]
    choice: bool  # "left or right?": a yes / no answer says nothing
    turn: int  # heading steps the question asks for first ("turn around: what do you see?")


LABELS = {**LABEL_WORDS, **CAMERA_COLOUR_WORDS, "pong": Label.PADDLE}  # "ping-pong" is read as one word
# ldh_features' sector words, and the variants that a parser of free text also meets.
SECTORS = {**SECTOR_WORDS, "infront": Sector.FRONT, "rear": Sector.BEHIND}
# "right" that means "directly" ("right in front", "right behind"), not the side.
_SIDE_OF = {"my", "your", "ur", "the", "to", "on"}  # "to my right", "on the right": the side
_RIGHT_AS_NEAR = {"in", "behind", "ahead", "next", "by", "beside", "there", "here", "now", "at", "up", "on"}
# "back" that is a move or a return, not the sector behind.
_BACK_NOT_SECTOR = {"up", "to", "out", "into", "down"}
# "behind" a thing, not the Driver's back: "a bit of green peekin out behind it" (on its left) put
# green behind a person, and the Commander's mark 45 degrees off.
_BEHIND_A_THING = {"it", "that", "this", "them", "those", "these", "the", "a"}
_AT = (("am", "at"), ("m", "at"), ("found", "the"), ("found", "a"))  # "i'm at the jar": near it
NEAR_WORDS = {"close", "closely", "directly", "immediately", "immediate", "near", "nearby", "just", "touching"}
FAR_WORDS = {"far", "distance", "distant", "end", "down", "away", "across", "farther", "further", "long"}
NEGATIONS = {
    "no",
    "not",
    "nothing",
    "none",
    "without",
    "never",
    "neither",
    "nor",
    "dont",
    "doesnt",
    "cant",
    "isnt",
    "arent",
}
CORRIDOR_WORDS = {"corridor", "hallway", "hall", "opening", "open", "gap", "path", "passage", "way", "aisle"}
EDGE_WORDS = {"edge", "border", "boundary"}
CORNER_WORDS = {"corner", "intersection", "junction"}
DEAD_END = ("dead", "end")
_NEGATED_NOUNS = {"wall", "walls", "more", "other", *CORRIDOR_WORDS, *CORNER_WORDS}
_SAYING = {"i", "there", "it", "its", "is", "are", "see", "can", "have", "also"}
_LISTED_FILLER = {"a", "an", "the", "some", "one", "two", "part", "of", "wall", "walls", "both", *_SAYING}
RELATION_WORDS = {"next", "beside", "attached", "connected", "connect", "connects", "adjacent", "between", "joined"}
YES = {"yes", "y", "yeah", "yep", "yup", "yea", "ya", "correct", "affirmative", "sure", "indeed", "right"}
NO = {"no", "nope", "nah", "negative"}
_WH = {"where", "what", "which", "how", "why"}
_AUX = {"is", "are", "should", "shall", "does", "do", "can", "could", "would", "will", "was", "were"}
_QUESTION_START = _WH | _AUX | {"am", "did", "have", "any"}
_TOKEN = re.compile(r"[a-z0-9]+")
_NOT_A_WAY = (("no", "way"), ("way", "off"), ("way", "away"))  # "no way through", "a good way off": no corridor
_CHUNK = re.compile(r"[,.;!?:]|\bbut\b|\bthen\b")
# A comma in a list of labels ("green, white and blue walls ahead") is an "and", not a new part.
_LISTED = "|".join(LABELS)
_LISTED_COMMA = re.compile(rf"\b({_LISTED})\s*,\s*(?:and\s+)?(?=(?:a |the )?(?:{_LISTED})\b)")
_TURN = re.compile(r"\b(?:turn(?:ed|ing)?|rotat(?:e|ed|ing)|spun|spin(?:ning)?|face[sd]?|facing)\b")
LEFT_STEPS = SECTOR_HEADING_OFFSET[Sector.LEFT]
AROUND_STEPS = SECTOR_HEADING_OFFSET[Sector.BEHIND]


def tokens(text: str) -> list[str]:
    """Lower-case words, spelling corrected (`vocab.correct`); "n't" as "not", the objects'
    hyphenated names as one word, and the two-word colours the landmarks have in the simulator's
    camera as one (`vocab.OBJECT_LOOKS`: "light blue" is the jar there, not a blue wall)."""
    text = (
        text.lower()
        .replace("can't", "can not")
        .replace("won't", "will not")
        .replace("n't", " not")
        .replace("ping-pong", "pong")
        .replace("end of the maze", "edge")
        .replace("light blue", "cyan")
        .replace("olive green", "olive")
    )
    return [correct(w) for w in _TOKEN.findall(text)]


def _right_as_near(words: list[str], k: int) -> bool:
    """Whether `words[k]` is "right" that says near ("right there", "right in front"), not the side
    ("to my right there is a blue wall")."""
    return (
        words[k] == "right"
        and k + 1 < len(words)
        and words[k + 1] in _RIGHT_AS_NEAR
        and not (k and words[k - 1] in _SIDE_OF)
    )


def _sectors(words: list[str]) -> list[tuple[int, Sector]]:
    """(position, sector) of each direction word; "sides" ("both sides"), "either side" and "each
    side" are left and right."""
    out = []
    for k, w in enumerate(words):
        nxt = words[k + 1] if k + 1 < len(words) else ""
        if _right_as_near(words, k):
            continue
        if w == "back" and nxt in _BACK_NOT_SECTOR or w == "behind" and nxt in _BEHIND_A_THING:
            continue
        if w in SECTORS:
            out.append((k, SECTORS[w]))
        elif _both_sides(words, k) or (w == "between" and _walls_of_one_colour(words[k + 1 : k + 4])):
            out += [(k, Sector.LEFT), (k, Sector.RIGHT)]
    return out


def _both_sides(words: list[str], k: int) -> bool:
    """Whether `words[k]` says both sides: "sides" ("both sides", "the sides"), "either side"."""
    return words[k] == "sides" or words[k] == "side" and k > 0 and words[k - 1] in ("either", "each")


def _walls_of_one_colour(words: list[str]) -> bool:
    """ "(between) yellow walls": one colour on both sides, not "between blue and white"."""
    return sum(w in LABELS for w in words) == 1 and "walls" in words and "and" not in words


def _labels(words: list[str]) -> list[tuple[int, Label]]:
    """(position, label) of each label word; a label named twice in a row ("white edge wall",
    "ping-pong paddle") once."""
    out: list[tuple[int, Label]] = []
    for k, w in enumerate(words):
        if w in LABELS and not (out and out[-1][1] == LABELS[w] and k - out[-1][0] <= 2):
            out.append((k, LABELS[w]))
    return out


def _few_steps(words: list[str]) -> bool:
    """ "a step", "a step or two", "2 steps": a distance of at most two steps."""
    counted = [n for n in (number(w) for w in words) if n is not None]
    return bool({"step", "steps"} & set(words)) and all(n <= 2 for n in counted)


def _distance(words: list[str]) -> Distance:
    # "not far" is near: a far word after "not" counts for near; so does "a step or two away".
    denied = {
        k
        for k, w in enumerate(words)
        if w in FAR_WORDS and k > 0 and (words[k - 1] == "not" or _few_steps(words[max(0, k - 4) : k]))
    }
    near = (
        bool(denied)
        or any(w in NEAR_WORDS for w in words)
        or any(_right_as_near(words, k) for k in range(len(words)))
        or any(_has(words, phrase) for phrase in _AT)
        or any(
            words[k : k + 3] == ["in", "front", "of"] and words[k + 3 : k + 4] not in (["me"], [])
            for k in range(len(words))
        )
    )
    far = (
        any(w in FAR_WORDS and k not in denied for k, w in enumerate(words)) or _has(words, ("way", "off"))
    ) and not _has(words, DEAD_END)
    if near == far:
        return Distance.ANY
    return Distance.NEAR if near else Distance.FAR


def _negations(words: list[str]) -> list[int]:
    """Positions of the words that negate what follows them; "no" only when a wall or a label
    follows ("no red wall"), not as an answer ("no, my left", "no there is a red dead end")."""
    return [
        k
        for k, w in enumerate(words)
        if w in NEGATIONS
        and (w != "no" or (k + 1 < len(words) and (words[k + 1] in LABELS or words[k + 1] in _NEGATED_NOUNS)))
    ]


def _has(words: list[str], phrase: tuple[str, ...]) -> bool:
    n = len(phrase)
    return any(tuple(words[k : k + n]) == phrase for k in range(len(words) - n + 1))


@dataclass
class _Piece:
    """One part of a sentence between "and"s: its labels and direction words."""

    words: list[str]
    labels: list[tuple[int, Label]]
    sectors: list[tuple[int, Sector]]
    joined: bool = False  # directions joined by "and": each one holds


def _pieces(chunk: list[str]) -> list[_Piece]:
    """Split at "and"; a part naming no label lends its directions to the part before
    ("white to my left and right"), a part naming no direction takes the next one's when that
    one names a direction but no label ("blue walls in front and to my left")."""
    parts: list[list[str]] = [[]]
    for w in chunk:
        if w == "and":
            parts.append([])
        else:
            parts[-1].append(w)
    pieces = [_Piece(p, _labels(p), _sectors(p)) for p in parts if p]
    merged: list[_Piece] = []
    for piece in _shared(pieces):
        if merged and not piece.labels and piece.sectors and not _negations(piece.words):
            prev = merged[-1]
            offset = len(prev.words)
            prev.words = prev.words + piece.words
            prev.sectors = prev.sectors + [(k + offset, s) for k, s in piece.sectors]
            prev.joined = True
            continue
        merged.append(piece)
    return merged


def _listed(piece: _Piece) -> bool:
    """A part that only names labels ("a brown", "i see red walls", "some part of white walls"):
    the direction the next part names is theirs too."""
    return bool(piece.labels) and not piece.sectors and all(w in LABELS or w in _LISTED_FILLER for w in piece.words)


def _shared(pieces: list[_Piece]) -> list[_Piece]:
    """Labels listed before a part that names labels and a direction are seen there too: "a brown
    and red wall to my left", "green walls and a red wall are in front of me"."""
    out: list[_Piece] = []
    for piece in pieces:
        # every listed part before it, "green and white and blue walls ahead"
        while (
            out
            and _listed(out[-1])
            and piece.labels
            and piece.sectors
            and piece.words[0] not in _SAYING  # "... and there is a blue wall on my left": a view of its own
            and not _negations(out[-1].words)
        ):
            listed = out.pop()
            offset = len(listed.words)
            piece = _Piece(
                listed.words + piece.words,
                listed.labels + [(k + offset, lab) for k, lab in piece.labels],
                [(k + offset, s) for k, s in piece.sectors],
            )
        out.append(piece)
    return out


def _label_facts(piece: _Piece, distance: Distance) -> list[Fact]:
    """Each label in the sectors named in its piece: every direction word counts. A piece naming
    as many directions as labels pairs them in order ("blue left, red right"); otherwise each
    label is seen in one of the sectors named (all of them when joined by "and", which
    `_pieces` merged: then each direction is a fact of its own)."""
    words = piece.words
    neg_at = _negations(words)
    out = []
    sectors = [s for _, s in piece.sectors]
    both = "between" in words or any(_both_sides(words, k) for k in range(len(words)))
    joined = len(set(sectors)) > 1 and (piece.joined or both)
    for k, label in piece.labels:
        negated = any(n < k for n in neg_at)
        if not sectors:
            groups: list[tuple[Sector, ...]] = [(Sector.ANY,)]
        elif len(piece.labels) > 1 and len(piece.sectors) == len(piece.labels):
            # "brown to the left blue to the right": labels and directions paired in order
            groups = [(piece.sectors[[p for p, _ in piece.labels].index(k)][1],)]
        elif joined:
            groups = [(s,) for s in dict.fromkeys(sectors)]
        else:
            groups = [tuple(dict.fromkeys(sectors))]
        kind = ViewKind.EDGE if label == Label.WHITE and EDGE_WORDS & set(words[k : k + 3]) else ViewKind.LABEL
        out += [Fact(kind, g, label, distance=distance, negated=negated) for g in groups]
    return out


def _shape_facts(piece: _Piece, sectors: tuple[Sector, ...]) -> list[Fact]:
    words = piece.words
    negated = bool(_negations(words))
    out = []
    if _has(words, DEAD_END):
        out.append(Fact(ViewKind.DEAD_END, (Sector.FRONT,), negated=negated))
    elif any(w in CORRIDOR_WORDS for w in words) and not any(_has(words, p) for p in _NOT_A_WAY):
        out.append(Fact(ViewKind.CORRIDOR, sectors if sectors != (Sector.ANY,) else (Sector.FRONT,), negated=negated))
    if any(w in CORNER_WORDS for w in words):
        out.append(Fact(ViewKind.CORNER, (Sector.FRONT,), negated=negated))
    return out


def _relation_facts(words: list[str], sectors: tuple[Sector, ...]) -> list[Fact]:
    """Two labels side by side: "red next to yellow", "between blue and white", "the red and
    yellow corner", "a yellow wall ... and a red wall next to it"."""
    labels = _labels(words)
    out = []
    for k, w in enumerate(words):
        if w == "between":
            pair = [lab for p, lab in labels if p > k][:2]
        elif w == "and" and k > 0 and words[k - 1] in LABELS:
            # "a brown and (a) red wall", "white and yellow": one thing of two colours
            after = [lab for p, lab in labels if p == k + 1 or (p == k + 2 and words[k + 1] in ("a", "an", "the"))]
            pair = [LABELS[words[k - 1]], *after[:1]]
        elif w in CORNER_WORDS:
            pair = [lab for p, lab in labels if k - 6 <= p < k][-2:]
        elif w in RELATION_WORDS and not (w == "next" and words[k + 1 : k + 3] == ["to", "me"]):
            before = [lab for p, lab in labels if p < k]
            after = [lab for p, lab in labels if p > k]
            pair = [before[-1], after[0]] if before and after else before[-2:]
        else:
            continue
        if len(pair) == 2 and pair[0] != pair[1]:
            out.append(Fact(ViewKind.NEXT_TO, sectors, pair[0], pair[1]))
    return out


_SENTENCE = re.compile(r"[.!?]")


def _chunks(text: str) -> list[tuple[str, list[str]]]:
    """The parts of a message, each with the words of a heading its sentence opened with, where
    one names where and no label: "straight ahead, far away: a brown wall, a thin yellow post" (a
    person's list of what was ahead was read as seen anywhere)."""
    out = []
    for sentence in _SENTENCE.split(text):
        head, colon, rest = sentence.partition(":")
        said = tokens(head)
        header = said if colon and _sectors(said) and not _labels(said) else []
        out += [(chunk, header) for chunk in _CHUNK.split(rest if header else sentence)]
    return out


def facts(text: str, asked: bool = False) -> list[Fact]:
    """The facts one message states, in order; a part that asks about what it names ("where is
    the edge?") states none, unless `asked`: then the facts a question asks about are read too. A
    part that names only how far ("..., really close", "... and it looks right there", "it's a good
    way off") says it of the labels the part before named without a distance."""
    out: list[Fact] = []
    last: list[int] = []  # where in `out` the last part's labels of no distance are
    for chunk, header in _chunks(_LISTED_COMMA.sub(r"\1 and ", text.lower().replace("n't", " not"))):
        words = tokens(chunk)
        if not words or not asked and asks_about(words):
            continue
        if header and _labels(words) and not _sectors(words):
            words += header
        named = tuple(dict.fromkeys(s for _, s in _sectors(words))) or (Sector.ANY,)
        out += _relation_facts(words, named)
        for piece in _pieces(words):
            distance = _distance(piece.words)
            if not piece.labels and distance != Distance.ANY and last:
                for k in last:
                    out[k] = replace(out[k], distance=distance)
                last = []
                continue
            said = _label_facts(piece, distance)
            if piece.labels:
                last = [len(out) + k for k, f in enumerate(said) if f.distance == Distance.ANY and not f.negated]
            out += said
            own = tuple(dict.fromkeys(s for _, s in piece.sectors)) or (Sector.ANY,)
            out += _shape_facts(piece, own)
    return out


def turn_steps(text: str) -> int:
    """Heading steps (45 degrees, counter-clockwise) of a turn the message reports or asks for;
    0 when it names none."""
    words = tokens(text)
    if not _TURN.search(" ".join(words)) and not _has(words, ("u", "turn")):
        return 0
    if "around" in words or "180" in words or _has(words, ("u", "turn")):
        return AROUND_STEPS
    turn_at = next(k for k, w in enumerate(words) if _TURN.fullmatch(w) or w == "u")
    after = words[turn_at + 1 : turn_at + 6]
    if words[turn_at] in {"face", "faces", "faced", "facing"}:
        return 0  # "facing" describes, it does not turn
    if "left" in after:
        return LEFT_STEPS
    if "right" in after:
        return -LEFT_STEPS
    return 0


def asked(before: Iterable[tuple[bool, str]]) -> str | None:
    """The Commander's latest question since the Driver last spoke: what a Driver's next turn
    answers. `before`: the dialog so far, as (said by the Commander, text)."""
    for by_commander, text in reversed(list(before)):
        if not by_commander:
            return None
        if is_question(text):
            return text
    return None


_POINTING = {"the", "that", "this", "those", "these", "it", "they", "there"}


def asks_about(words: list[str]) -> bool:
    """A question about what it names, which states none of it: "where is the edge", "should the
    red walls be on my left", "is that the right way" (where "should I turn right at the white
    wall" says there is a white wall)."""
    return words[0] in _WH or words[0] in _AUX and len(words) > 1 and words[1] in _POINTING


def is_question(text: str) -> bool:
    words = tokens(text)
    return text.strip().endswith("?") or bool(words and words[0] in _QUESTION_START)


class Asked(StrEnum):
    """What a Driver's question asks the Commander."""

    WHY = "why"  # "why not?": why it rejected a claim, or why this way
    WHICH_WAY = "which_way"  # "which way?", "left or right?", "where should i go?"
    HOW_FAR = "how_far"  # "how far?", "how many steps?", "where is the jar?", "what do i look for?"
    WHERE_AM_I = "where_am_i"  # "where am i?"
    LOOKS = "looks"  # "what does the mug look like?"
    WHICH_ONE = "which_one"  # "which white wall?": the thing the instruction named is not clear
    TURN_SIZE = "turn_size"  # "sharply right = like 90 degrees?", "how many times do i press right?"
    IS_IT = "is_it"  # "is that the jar?", "is the red thing the jar?": what it looks like in the camera
    SHOULD_CLAIM = "should_claim"  # "should i press i found the target?"
    NEAR_WHAT = "near_what"  # "which wall colour is the paddle next to?", "near what?"
    THERE = "there"  # "hello??", "u there?": a message that only calls the Commander
    AGAIN = "again"  # "say again?", "u said right once then left once?? which": the instruction again


# First match wins: "where am i" before "where to", "what do i look for" before "what does it look like".
# The landmarks by any of their names ("cup", "bat", "pong"), and the target by its roles.
_OBJECTS = "|".join(w for w, label in LABELS.items() if label in OBJECT_LABELS and w not in CAMERA_COLOUR_WORDS)
_TARGET_WORDS = rf"(?:{_OBJECTS}|target|objective|goal)"
_ASKED = (
    # Whole messages only: "hi, red wall on my left" reports.
    (
        Asked.THERE,
        re.compile(
            r"^(?:(?:hello+|helo|hi+|hey+|yo|um+|uh+) ?)*(?:(?:are|r) )?(?:you|u|ya) (?:still )?(?:there|here|with me|around)$"
            r"|^(?:hello+|helo|hi+|hey+|yo)(?: there| again| commander)?$|^(?:anyone|anybody|someone|somebody) (?:there|home)$"
        ),
    ),
    (
        Asked.WHERE_AM_I,
        re.compile(
            r"\bwhere (?:am i|are we|i am)\b|\bdo you know where (?:i am|im|i m|we are|the robot is)\b"
            r"|\bwhat do you see me (?:near|at|by)\b"  # "What do you see me near now?"
            # "could you tell me whether you have a position estimate?" went unanswered
            r"|\b(?:position|location) estimate\b|\b(?:know|found) (?:my|our|the robot s) (?:position|location)\b"
            r"|\bhave you (?:localized|localised|found) (?:me|us|the robot)\b"
        ),
    ),
    (
        Asked.SHOULD_CLAIM,
        re.compile(
            r"\b(?:should|do|can|shall) i (?:claim|say found)\b"
            r"|\b(?:should|do|can|shall) i (?:press|click|hit) (?:\w+ ){0,3}(?:found|target)\b"
        ),
    ),
    (
        Asked.NEAR_WHAT,
        re.compile(
            rf"\b(?:near|next to|by|beside) what\b|\bwhich (?:wall )?colou?r(?: wall)? (?:is )?(?:the )?{_TARGET_WORDS}\b"
            rf"|\bwhat (?:colou?r )?(?:wall )?is (?:the )?{_TARGET_WORDS} (?:near|next to|by|beside)\b"
            # "what colour walls are near the mug? I can look for them"
            rf"|\bwhat colou?r (?:walls? )?(?:are|is) (?:\w+ )?(?:near|next to|by|beside|around) (?:the )?{_TARGET_WORDS}\b"
            rf"|\bis (?:the )?{_TARGET_WORDS} (?:near|next to|by|beside|close to) (?:the |a )?\w+ walls?\b"  # "Is the paddle near the red wall?"
        ),
    ),
    (
        Asked.IS_IT,
        re.compile(
            rf"\b(?:is|are) (?:that|this|it|those|these|the \w+(?: \w+)?) (?:the |your |my |our )?{_TARGET_WORDS}\b"
            rf"|\bwhich (?:one|thing) is (?:the )?{_TARGET_WORDS}\b"
            # "yo i see smth yellowish olive way off on the left. is that it?" (not "is this it?", said
            # with a claim at the target)
            r"|\b(?:is|could) that (?:be )?(?:it|the one|the target)\b"
        ),
    ),
    (
        # Before "how many": how far to turn, not to go. Asked, not said: "turned right 45 degrees" reports.
        Asked.TURN_SIZE,
        re.compile(
            r"\bhow (?:many|much) degrees\b|\b(?:is that|is it|so|like|thats|that is|about) \d+ degrees\b"
            r"|\bhow (?:sharp(?:ly)?|much|far|many times) (?:do i |should i |to )?turn\b"
            r"|\bhow many (?:times|clicks|presses)\b|\bhow sharp(?:ly)?\b"
            r"|\bturn (?:left|right) how (?:much|far|many)\b|\bone (?:click|press|time) or two\b"
            r"|\bone (?:click|press|time)\b(?: \w+){0,4} or two\b"  # "one press of the left button, or two presses?"
        ),
    ),
    (
        Asked.HOW_FAR,  # and where the target is, or what to look for: the same answer
        re.compile(
            rf"\bhow (?:far|many|much|long)\b|\b(?:is it|am i|are we|is the (?:{_OBJECTS}|target)) (?:\w+ )?(?:close|near|far)\b"
            rf"|\bwhere(?:s| is)?(?: the| my)? (?:{_TARGET_WORDS}|it)\b"
            rf"|\b(?:which|what) (?:way|direction|side) (?:\w+ ){{0,2}}(?:{_TARGET_WORDS})\b"  # "which direction the jar is"
            r"|\bwhat (?:do|should) i (?:look|search) for\b|\bwhat am i looking for\b"
        ),
    ),
    # Asked, not said: "looks like a dead end" describes.
    (
        Asked.LOOKS,
        re.compile(
            r"\b(?:what|how) (?:does|do|did|will) (?:\w+ ){0,4}look(?: like)?\b"
            rf"|\bwhat colou?r (?:is|s) (?:it|the (?:{_OBJECTS}|target))\b"  # "what color is the mug"
            r"|\bhow (?:do|will|would|can) i (?:know|tell|recogni[sz]e)\b|\bwill i (?:actually |even )?see (?:it|the)\b"
            # "What colour should I look for?", "what I should see when I get close to the paddle?"
            r"|\bwhat colou?r (?:\w+ ){0,3}(?:look|search|watch) (?:out )?for\b|\bwhat (?:should|will|would) i see\b|\bwhat i (?:should|will|would) see\b"
        ),
    ),
    (Asked.WHY, re.compile(r"\bwhy\b")),
    (
        Asked.WHICH_ONE,  # and where a walk ends: "so go fwd till where exactly?"
        re.compile(
            r"\bwhich (?:\w+ ){0,2}(?:wall|walls|one|ones|corner|corridor|opening|gap|turn)\b|\b(?:till|until|up to) where\b"
        ),
    ),
    (
        Asked.WHICH_WAY,
        re.compile(r"\b(?:which|what) (?:way|direction|side)\b|\bleft or right\b|\bright or left\b|\bwhere\b"),
    ),
    (
        Asked.AGAIN,
        re.compile(
            r"^(?:what|huh|pardon|come again|again|what did you say)(?: please)?$|\bwhich$"
            r"|\b(?:say|tell me) (?:that|it) again\b|\brepeat (?:that|it|the (?:last )?instruction|please)\b|^repeat$"
        ),
    ),
)
DISTANCE_WINDOW = 8  # words after "a wall right in front" that may still say how far it is
_COUNT = rf"(?:\d+|zero|(?:a )?(?:{'|'.join(NUMBER_WORDS)}))"  # "3", "three", "a few"
# A report of not having moved at all ("I pressed forward six times but I don't think I actually
# moved", "nothing happened", "it didnt budge"): a walk cut short before its first step.
_NOT_MOVED = re.compile(
    r"\b(?:did not|didnt|dont think i|do not think i|does not|doesnt|wont|will not|would not|wouldnt)"
    r" (?:actually |really |even )?(?:move|moved|budge|budged|go anywhere)\b|\bnothing (?:happened|happens)\b"
)
# A report of an instruction not carried out in full, the Driver stopped on its way ("i hit a wall
# after three steps", "only 2 steps, then a wall", "stopped at three", "i could not go further").
_FELL_SHORT = re.compile(
    rf"{_NOT_MOVED.pattern}|"
    r"\b(?:hit|bumped|bump|bumps|bumping|bumpd|crashed|ran into|blocked|stuck|can only go|in my way|no way forward)\b"
    r"|\bforward (?:\w+ ){0,2}(?:does not|doesnt|wont|will not|isnt|is not) work"
    r"|^(?:i )?(?:cant|cannot|can not)\b(?! (?:see|find|tell|understand|say))"  # "cant, wall rite there"
    r"|\b(?:can not|cannot|cant|could not|unable to) (?:go|move|drive) (?:any )?(?:forward|ahead|on|further|farther)\b"
    rf"|\b(?:wall|stopped|stuck|blocked) (?:after|at) {_COUNT}\b"
    rf"|\bonly (?:got )?{_COUNT} steps?\b"
)
# The steps a Driver says it made before it stopped ("after three steps", "only got 2 steps in",
# "stopped at 3", "2 done", "maybe two steps?").
# "only moved 3 times then bump": "moved" is read as "move".
_WALKED = re.compile(rf"\b(?:after|at|got|only|maybe|go|move|made) ({_COUNT})\b|\b({_COUNT}) (?:steps? )?done\b")
# The presses of a walk a Driver says bumped: its last ones, the robot at a wall ("the last 3 presses
# did not move the robot", as the Driver's page says it; "bumped twice", "2 of them bumped").
_TIMES = {"once": 1, "twice": 2, "thrice": 3}
_PRESSES_SAID = {**_TIMES, "press": 1, "both": 2}  # "the last press ...", "both forwards bumped"
_BUMPED = re.compile(
    rf"\blast ({_COUNT}|one|press) (?:\w+ ){{0,2}}(?:did not|didnt|do not|dont|were|was|are|just) (?:\w+ )?(?:move|moved|bump|bumps|bumped|blocked)\b"
    rf"|\bbump(?:ed|s)? ({_COUNT}|{'|'.join(_TIMES)})(?: times)?\b(?! (?:steps|presses))"
    # "the 2 forwards bumped", "those 7 forwards all bumped", "bumped again both forwards"
    rf"|\b({_COUNT}|both) (?:\w+ ){{0,2}}(?:bumped|were bumps|bumps)\b|\bbumped (?:again )?(both)\b"
)
# A walk that bumped at its first press: no step made ("bumped on the very first forward").
_FIRST_BUMPED = re.compile(
    r"\b(?:bumped|bump|hit|blocked|stuck) (?:\w+ ){0,2}(?:on|at) the (?:very )?first\b"
    # "tried to go forward but I bumped into the green wall right away", "the fwd bumped rite away"
    r"|\b(?:bumped|bump|hit) (?:\w+ ){0,4}(?:right|rite|straight) away\b|\b(?:bumped|bump|hit) (?:\w+ ){0,4}immediately\b"
)
# A wall that bars the way where the Driver stands ("there is a wall right in front of me");
# "close ahead" is not: a step may still be free.
_WALL_RIGHT_AHEAD = re.compile(
    r"\bwall (?:is )?(?:right|directly|just|immediately) (?:in front|ahead)\b"
    r"|\b(?:right|directly|just|immediately) (?:in front of me|ahead) (?:is|there is) (?:a|the) wall\b"
    r"|\bfacing (?:a|the) wall\b"
    # A person's words for a wall that fills the camera: "right up against a wall", "nose to nose with
    # a big red wall", "it fills most of the picture" ("really close" alone is near, a step or more).
    r"|\bup against (?:a|the) (?:\w+ ){0,2}wall\b|\bnose to nose with\b|\bnose (?:against|on|into|at) (?:a|the)\b"
    r"|\bwall (?:right |just )?in my face\b"  # "white wall in my face. gap on the left"
    r"|\b(?:fills|filling|covers|all over) (?:\w+ ){0,2}(?:the )?(?:picture|screen|view|camera|image)\b"
)


def asks(text: str) -> Asked | None:
    """What a Driver's message asks the Commander, where it asks one of `Asked`."""
    return next(iter(asks_all(text)), None)


def asks_all(text: str) -> list[Asked]:
    """Each of `Asked` a Driver's message asks, first first ("what color is the mug n is it
    close?": how far, and how it looks)."""
    said = " ".join(tokens(text))
    return [kind for kind, pattern in _ASKED if pattern.search(said)]


def only_asks(text: str) -> bool:
    """Whether every sentence of a message is a question ("why not?", "how far? which way?"): it
    reports nothing done."""
    sentences = [s for s in re.split(r"(?<=[.,;!?])", text) if tokens(s)]
    return bool(sentences) and all(is_question(s) or asks(s) is not None for s in sentences)


# A Driver saying back what it understood, and asking ("i am not sure i got 'x'. do you mean:
# turning left 90 degrees?", "you mean turn left?"): its reading.
_ASKED_BACK = re.compile(r"\b(?:do you mean|did you mean|you mean)\b[:,]?\s*(.+?)\s*\??\s*$")
# A Driver that did not understand the last instruction ("sorry, i did not understand '...'").
_NOT_UNDERSTOOD = re.compile(
    r"\b(?:did not|do not|dont|didnt) (?:understand|get)\b|\bwhat do you mean\b|\bconfused\b"
    r"|\bsay (?:it|that) (?:another|a different) way\b"
)


def asked_back(text: str) -> str | None:
    """The reading a Driver says back and asks about, if it does ("do you mean: ...?")."""
    found = _ASKED_BACK.search(text.lower())
    return found.group(1) if found else None


def not_understood(text: str) -> bool:
    """Whether a Driver's message says it did not understand what it was told."""
    return bool(_NOT_UNDERSTOOD.search(" ".join(tokens(text))))


# A Driver's words with its claim: "found it", "is this the jar?", "i think i'm at the cup?".
_CLAIMS = re.compile(rf"\bfound\b|\b(?:i am at|im at|i m at) the (?:{_OBJECTS})\b")
# ... said, not asked: "this is the jar", "i think i'm there" (not "how do i know when im there?").
_CLAIMS_SAID = re.compile(rf"\bthis is the (?:{_OBJECTS})\b|\bi (?:am|m) there\b|\bim there\b")


def claims(text: str) -> bool:
    """Whether a Driver's message goes with its claim of the target."""
    sentences = [s for s in re.split(r"(?<=[.,;!?])", text) if tokens(s)]
    return any(
        _CLAIMS.search(said := " ".join(tokens(s))) or (not is_question(s) and _CLAIMS_SAID.search(said))
        for s in sentences
    )


# A move the Driver proposes at the end of its message and asks about ("go straight?", "should i
# turn left?", "im gonna go straight down the hallway ok?"): a person asking so was given the next
# instruction without a yes or a no.
_PROPOSED = re.compile(
    r"(?:^|[.!?,;]\s*)(?:(?:so|ok|okay|then|and) )?(?:(?:should|shall|do|can|could) i (?:just )?|i(?:'?m| am) (?:gonna|going to) "
    r"|i(?:'?ll| will) |maybe )?((?:go|turn|keep going|head|drive|move|continue)\b[^.!?,;]*?)(?:,? (?:ok|okay|then))?\s*\?\s*$"
)


_WHERE_TO = re.compile(r"\b(?:where|what|which|how)\b")


def proposed(text: str) -> str | None:
    """The move a Driver's message ends by proposing and asking about, in its words; None where it
    proposes none."""
    found = _PROPOSED.search(text.lower().strip())
    if found is None or _WHERE_TO.search(found.group(1)):  # "go fwd till where exactly?" asks where
        return None
    return found.group(1) if " or " not in found.group(1) else None  # "go straight or left?" asks which


def has_question(text: str) -> bool:
    """Whether any sentence of a message is a question."""
    return any(is_question(s) for s in re.split(r"(?<=[.,;!?])", text) if tokens(s))


# A report of moves made: it opens with an "ok" or names what was done.
_REPORTS_DONE = re.compile(
    r"^(?:ok+|okay|k|alright|all right|done|donee|yes|yep|right|sure)\b"
    r"|\b(?:done|did|went|turned|moved|walked|reached|arrived|finished|made it|now i|i am now|im now)\b"
)


def reports_done(text: str) -> bool:
    """Whether a Driver's message reports moves made ("ok, at the red wall", "turned left, now ...")."""
    return bool(_REPORTS_DONE.search(" ".join(tokens(text))))


def fell_short(text: str) -> bool:
    """Whether a Driver's message says it stopped before it had done what it was told."""
    return bool(_FELL_SHORT.search(" ".join(tokens(text))))


def walked(text: str, counted: int | None = None) -> int | None:
    """The steps a Driver's report of stopping short says it made: those it names, else where it says
    how many presses of a walk of `counted` steps bumped, the rest; None where it says neither."""
    said = " ".join(tokens(text))
    bumped = _BUMPED.search(said)
    if bumped is not None:  # before "did not move": its last presses, not all of them
        said_bumped = next(g for g in bumped.groups() if g is not None)
        presses = _PRESSES_SAID.get(said_bumped) or _count(said_bumped)
        return max(counted - presses, 0) if counted is not None and presses is not None else None
    if _NOT_MOVED.search(said) or _FIRST_BUMPED.search(said):
        return 0
    found = _WALKED.search(said)
    if found is None:
        return None
    return _count(next(g for g in found.groups() if g is not None))


def _count(said: str) -> int | None:
    """The number a `_COUNT` match says ("3", "three", "a few", "zero")."""
    return 0 if said == "zero" else number(said.removeprefix("a "))


_STEPS_AWAY = re.compile(rf"\b({_COUNT}) steps? (?:away|ahead|in front|off|from)\b")


def steps_away(text: str) -> int | None:
    """How many steps off a Driver says what is ahead is ("wall 1 step away", "maybe 3 steps ahead")."""
    found = _STEPS_AWAY.search(" ".join(tokens(text)))
    return None if found is None else _count(found.group(1))


def blocked(text: str) -> bool:
    """Whether a Driver's message says its way forward is barred where it stands: it stopped short
    at a wall, or a wall is right in front of it, which it does not then call far off (a person's
    "right in front of me" may only mean ahead: "... right in front of me, it's a good way off")."""
    said = " ".join(tokens(text))
    if _FELL_SHORT.search(said):
        return True
    for found in _WALL_RIGHT_AHEAD.finditer(said):
        after = said[found.end() :].split()[:DISTANCE_WINDOW]
        told = next((k for k, w in enumerate(after) if w in LABELS), len(after))  # up to the next wall named
        # "right" there is "right there" (near) or "on the right" of another wall.
        words = [w for w in after[:told] if w != "right"]
        if _distance(words) != Distance.FAR:
            return True
    return False


def question(text: str) -> QuestionFacts:
    """A Commander's question as the Driver would state its content ("your" read as "my")."""
    mine = " ".join("my" if w == "your" else w for w in re.findall(r"[^\s]+", text.lower()))
    asked = tuple(replace(f, source=Source.ANSWER) for f in facts(mine, asked=True))
    words = tokens(mine)
    return QuestionFacts(
        facts=asked,
        labels=tuple(label for _, label in _labels(words)),
        sectors=tuple(dict.fromkeys(s for _, s in _sectors(words))),
        choice="or" in words,
        turn=turn_steps(mine),
    )


# "not straight ahead, no. ahead is white" answered "is there a red wall ahead of you?" (the
# check went on as if told yes).
_NOT_SO = re.compile(
    r"^not (?:\w+ ){0,3}no\b|^(?:not|never) (?:there|ahead|on (?:my|the) (?:left|right)|straight ahead|in front)\b"
)


def says_no(text: str) -> bool:
    """A reply that opens with a no ("no", "nope, ...", "not straight ahead, no")."""
    words = tokens(text)
    return bool(words) and (words[0] in NO or bool(_NOT_SO.search(" ".join(words))))


# A reply that neither says yes nor no: "sort of?", "not sure", "i dont know", "maybe".
_HEDGE = re.compile(
    r"^(?:um+ |uh+ |hmm+ |well )?(?:sort of|kind of|kinda|maybe|perhaps|not sure|not really sure|i (?:am|m) not sure"
    r"|i (?:do not|dont|don t) know|dunno|idk|hard to (?:say|tell)|i (?:can not|cannot|cant|can t) tell)\b"
)


def hedges(text: str) -> bool:
    """A reply that opens unsure, neither yes nor no."""
    return bool(_HEDGE.search(" ".join(tokens(text))))


# A Driver that doubts the way it is led: lost, going round, or back where it was before.
_DOUBTS = re.compile(
    r"\b(?:(?:we|i) (?:are|re|am|m|feel|think|got|get|getting) (?:\w+ ){0,3}lost|(?:im|iam) (?:\w+ ){0,2}lost|lost again"
    r"|(?:going|go|went|walking|driving|run|running) (?:\w+ ){0,2}in (?:a )?circles?"
    r"|are you sure|(?:been|was|were) here before|back (?:to |at )?where (?:i|we) (?:was|were|started)"
    r"|same (?:place|spot|view) (?:as )?(?:again|before)|wrong way|back and forth"
    # "facing that same white wall again, looks exactly like before", "i think you have me in the
    # wrong spot": a person led round in circles, who was given the next counted walk
    r"|same (?:\w+ ){0,2}(?:wall|corner|place|spot|view) (?:as )?again|(?:exactly|just) like before"
    r"|wrong (?:spot|place|position|location)|(?:have|got) me (?:\w+ ){0,2}wrong"
    # "r u sure u know where i am??" ("r" is read as "right"), "are we goin in circles?", "i think
    # we went backwards?", "this looks like the same hallway as b4"
    r"|right (?:you|u) sure|goin in circles|went backwards|going backwards|gone backwards"
    r"|same (?:hallway|corridor|hall|room) (?:as )?(?:before|b4|again)"
    r"|(?:really|actually) (?:\w+ ){0,3}(?:this|that|the right) way|(?:the )?way i came from)\b"
)


def doubts(text: str) -> bool:
    """Whether a Driver's message says it is lost or doubts the way it is led ("we're lost", "i
    feel like im going in circles", "are you sure this is the way?")."""
    return bool(_DOUBTS.search(" ".join(tokens(text))))


def answer(q: QuestionFacts, text: str) -> list[Fact]:
    """The facts a Driver's reply to `q` states: the question's own facts on "yes", each of them
    negated on "no" (pairs side by side left out: either label may be the one missing), and
    for a reply naming only a side ("left") or only a label ("the edge") the question's first
    label or its side supplies the rest."""
    words = tokens(text)
    if not words:
        return []
    own = facts(text)
    if not q.choice and words[0] in YES and q.facts:
        return [*q.facts, *own]
    if not q.choice and words[0] in NO and q.facts:
        return [replace(f, negated=not f.negated) for f in q.facts if f.kind != ViewKind.NEXT_TO] + own
    sectors = tuple(dict.fromkeys(s for _, s in _sectors(words)))
    labels = [label for _, label in _labels(words)]
    if sectors and not labels and q.labels:
        return [Fact(ViewKind.LABEL, (s,), q.labels[0], source=Source.ANSWER) for s in sectors] + own
    if labels and not sectors and len(q.sectors) == 1:
        return [replace(f, sectors=q.sectors, source=Source.ANSWER) if f.sectors == (Sector.ANY,) else f for f in own]
    return own
