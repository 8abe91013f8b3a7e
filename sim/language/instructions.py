"""What a Commander's message asks the Driver to do, as typed instructions.

A message is cut into clauses (at punctuation, "then", "and", "after that"); each clause is
matched against the maze's closed vocabulary, with misspellings corrected (`vocab.words`). The
result keeps the message's order: "turn right at the red wall" is a forward-until-red then a right
turn. Negation excludes a colour from the wall to stop at ("turn left at the wall, not the red
one"); counts say how many steps, turns ("twice", "two right turns") or openings ("the second left"); history points
back to the start or to the place of an earlier turn ("go back to where you turned right first")."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from enum import StrEnum

from sim.core.labels import OBJECT_LABELS, Label
from sim.language.vocab import (
    LABEL_WORDS,
    ORDINAL_WORDS,
    SHARP_WORDS,
    SLIGHT_WORDS,
    Side,
    number,
    times_turned,
    turns_to,
    words,
)


class AskedAbout(StrEnum):
    VIEW = "view"  # what do you see?
    SIDE = "side"  # what is on your left?
    IS_THERE = "is_there"  # is there a red wall ahead?
    DISTANCE = "distance"  # how many steps to the wall in front of you?


class Place(StrEnum):
    START = "start"
    TURN = "turn"  # where the Driver turned (side, nth)


@dataclass(frozen=True)
class Turn:
    eighths: int  # 45-degree steps, counter-clockwise (left) positive
    # "turn left until you see the mug": on, 45 degrees at a time (the way `eighths` says), until
    # `until` is in view (`facing`: until it is ahead); no walk.
    until: Label | None = None
    facing: bool = False


@dataclass(frozen=True)
class Forward:
    steps: int | None = None  # grid moves; None: until `until` (or a wall) is reached
    until: Label | None = None  # the wall colour or object to stop at; None: any wall
    exclude: frozenset[Label] = frozenset()  # "not the red one"


@dataclass(frozen=True)
class TakeOpening:
    side: Side  # LEFT or RIGHT
    nth: int  # "the second left": the second opening on that side


@dataclass(frozen=True)
class Target:
    label: Label  # "the next objective is a mug"
    side: Side | None = None  # "the mug is on your right"


@dataclass(frozen=True)
class Ask:
    question: AskedAbout
    side: Side | None = None
    label: Label | None = None
    look_around: bool = False  # "look around and tell me"


@dataclass(frozen=True)
class GoBack:
    place: Place
    side: Side | None = None  # for TURN: which way it turned
    nth: int = 1  # for TURN: first, second ... such turn


@dataclass(frozen=True)
class Stop:
    claim: bool  # "you're there" / "that's it": claim the target; "stop": just stop


@dataclass(frozen=True)
class Unclear:
    text: str


Instruction = Turn | Forward | TakeOpening | Target | Ask | GoBack | Stop | Unclear
MOVING = (Turn, Forward, TakeOpening, GoBack)  # the instructions that move the robot


@dataclass(frozen=True)
class Parsed:
    instructions: tuple[Instruction, ...] = field(default=())

    @property
    def moves(self) -> bool:
        return any(isinstance(i, MOVING) for i in self.instructions)

    @property
    def unclear(self) -> bool:
        """Nothing but clauses not understood ("ok", "got it" are understood: nothing to do)."""
        return bool(self.instructions) and all(isinstance(i, Unclear) for i in self.instructions)


_CLAUSE = re.compile(r"[,.;!]+|(?<!should )\bthen\b|\band\b|\bafter that\b|(?<!right )\bnow\b|\bright now\b")
PRESS_FOUND = r"(?:say|press|hit|click|tap|push) (?:the )?(?:i )?found"  # the Driver's "I found the target" button
_CLAIM = re.compile(
    r"\b(you(?:re| are) (?:there|here|right by it|at it)|(?:should be|is) right (?:there|here)|thats it|thats the spot|you found it|found it"
    r"|you found the (?:target|jar|mug|cup|paddle|bat|one)"
    r"|claim|take (?:a |the )?(?:picture|photo|snapshot)|send (?:a )?(?:picture|photo)"
    rf"|{PRESS_FOUND}|(?:thats|this is|that is) (?:the (?:target|one|spot)|it))\b"
)
_STOP = re.compile(r"\b(stop|halt|hold on|wait)\b")
_UTURN = re.compile(r"\b(u-turn|u turn|turn around|spin around|180|turn back|about face|uturn)\b")
_SIDE_PHRASE = re.compile(
    r"\b(?:on|to|at) your (left|right)\b|\bon the (left|right)\b|\bbehind you\b|\bin front of you\b"
)
_GO = re.compile(
    r"\b(go|move|drive|continue|keep|head|proceed|straight|forward|forwards|reach|towards|toward"
    r"|until|steps|step|up to|follow|along)\b"
)
# "the second left", "the 2nd opening on your left", "the next gap to the right"
_OPENING = re.compile(
    rf"\b({'|'.join(ORDINAL_WORDS)}) (?:(?:opening|gap|hallway|hall|corridor|passage|turn|turning|way|entrance)s? )?"
    r"(?:(?:on|to) (?:your|the) )?(left|right)\b"
)
_UNTIL = re.compile(r"\b(until|till|to|towards|toward|reach|reached|at|up to|see)\b")
BACK_START = re.compile(r"\b(start|started|beginning|began|starting)\b")
_QUESTION = re.compile(
    r"\?|^(what|whats|where|is|are|do|does|can you see|describe|any|how)\b|\bsurroundings\b|^location\b|\byour location\b"
    r"|\btell me (?:what|your|about)\b|\bdescribe\b"
)
_FIND = re.compile(
    r"\b(?:(?:and )?(?:you )?(?:should|will|can|have to|need to|lets|let us) )?(?:go )?(?:to )?(?:find|look for|search for)\b.*$"
)
_EXPECT = re.compile(
    r"\b(?:you should|you will|you'll|should) (?:then )?(?:see|have|be facing)\b|\b(?:should be|are|is) (?:on|to) your\b"
)
_LOOK = re.compile(r"\b(look around|spin around|around you|all around|look all around|turn around)\b")


def _labels(ws: list[str]) -> list[Label]:
    return [LABEL_WORDS[w] for w in ws if w in LABEL_WORDS]


def _side(ws: list[str]) -> Side | None:
    for w in reversed(ws):
        if w in ("left", "right"):
            return Side(w)
        if w in ("behind", "back"):
            return Side.BEHIND
        if w in ("ahead", "front", "forward"):
            return Side.AHEAD
    return None


def _turn_size(ws: list[str]) -> int:
    if SLIGHT_WORDS.intersection(ws) or "45" in ws:
        return 1
    if SHARP_WORDS.intersection(ws) or "135" in ws:
        return 3
    return 2


# "how many steps until the wall in front of you?", "how far away is the white wall in front of
# you, a few steps or far?": a person commanding the agent got its view again, never a count.
_HOW_FAR_AHEAD = re.compile(
    r"\bhow (?:far|many steps|many moves|many forwards|close)\b(?: \w+){0,8} (?:wall|ahead|in front|front of)\b"
)


def asks_distance(message: str) -> bool:
    """Whether a message asks how far the wall ahead is."""
    return bool(_HOW_FAR_AHEAD.search(" ".join(words(message))))


def asks_to_look(message: str) -> bool:
    """Whether a message asks the Driver to look all around (turn in place: eight moves)."""
    return bool(_LOOK.search(" ".join(words(message))))


# A turn that goes on until something is seen: "turn left until you see the mug", "rotate till the
# red wall is in front of you", "keep spinning right until blue is in view". Its "how" (the words
# between the verb and "until") names no walk: "turn left and go until ..." is two clauses.
_TURN_UNTIL = re.compile(
    r"\b(?:keep (?:on )?)?(?:turn|turning|rotate|rotating|spin|spinning|pivot|pivoting|swivel|swivelling)\b"
    r"(?P<how>(?: \w+){0,4}?) (?:until|till|til|untill) (?P<what>.+)$"
)
_SEEN = re.compile(r"\b(?:see|seeing|spot|notice|find|view|visible|sight|face|facing|front|ahead)\b")
_FACING = re.compile(r"\b(?:face|facing|front|ahead)\b")


# "turn so the green wall is behind you", "turn around so the yellow wall is behind you": a person
# commanding the agent Driver got a walk and no turn.
_BACK_TO = re.compile(
    r"\b(?:turn|rotate|spin)\b(?: \w+){0,3}? so (?:that )?(?:the )?(?P<what>(?:\w+ ){1,3}?)(?:is|are) "
    r"(?:right |directly )?(?:behind you|at your back|behind)\b"
)


def turned_back_to(message: str) -> Label | None:
    """The wall or object a message says to turn one's back to, where it says so."""
    found = _BACK_TO.search(" ".join(words(message)))
    labels = _labels(found.group("what").split()) if found else []
    return labels[0] if labels else None


@dataclass(frozen=True)
class TurnUntil:
    """A message's turn that goes on until `until` is in view (`facing`: ahead); `side`: the way
    it names, if any; `walk`: the message also says to walk, elsewhere than in that clause
    ("..., then go to it")."""

    side: Side | None
    until: Label
    facing: bool
    walk: bool


def turn_until(message: str) -> TurnUntil | None:
    """The message's turn until something is in view, where it has one: the trained reader has no
    form for it (it reads a turn and a walk to the thing, or a turn and a check)."""
    said = [" ".join(words(c)) for c in clauses(message)]
    for k, clause in enumerate(said):
        found = _TURN_UNTIL.search(clause)
        if found is None or _GO.search(found.group("how")):
            continue
        what = found.group("what")
        labels = _labels(what.split())
        if not labels or not _SEEN.search(what):
            continue
        rest = [c for j, c in enumerate(said) if j != k] + [clause[: found.start()]]
        return TurnUntil(
            _side([w for w in found.group("how").split() if w in ("left", "right")]),
            labels[0],
            facing=bool(_FACING.search(what)),
            walk=any(_GO.search(c) for c in rest),
        )
    return None


# Presses of the Driver's buttons counted ("press left twice", "click forward 3 times, then right
# once"): each press one move, a step or a turn of 45 degrees, however a turn is said elsewhere. The
# dialog Commander says its turns so (`Phrasing.BUTTONS`): people told "turn left" pressed once.
_PRESS = re.compile(
    r"\b(?:press|pressing|click|clicking|tap|tapping|hit|hitting)\b(?= (?:\w+ ){0,2}(?:forward|up|left|right)\b)"
)
_BUTTON = re.compile(r"\b(forward|up|left|right)(?: (?:button|arrow|key))?(?: (\w+)(?: (?:times|time|x))?)?")
_BARE_PRESS = re.compile(rf"(?:then |and |now )?(?:the )?{_BUTTON.pattern}")  # "..., then left once"
_PRESSES = {"once": 1, "twice": 2, "thrice": 3}
_WALK_ON = re.compile(r"\b(?:until|till|til|untill|all the way)\b")


def press_verb(said: str) -> re.Match[str] | None:
    """Where words (a clause, cleaned) press a button; none in "press forward until the red wall", a walk."""
    return None if _WALK_ON.search(said) else _PRESS.search(said)


def pressed(said: str, pressing: bool) -> list[Instruction] | None:
    """The moves of a clause (cleaned) that presses buttons, or, `pressing` (a clause before it
    did), names them alone ("..., then right once"); None for any other clause."""
    if (verb := press_verb(said)) is not None:
        return _presses(said[verb.end() :])
    return _presses(said) if pressing and _BARE_PRESS.fullmatch(said) else None


def _presses(said: str) -> list[Instruction]:
    """The moves of the buttons named in `said`, each as often as said: a turn per press, as the
    turns of "twice" are counted."""
    out: list[Instruction] = []
    for found in _BUTTON.finditer(said):
        button, times = found.group(1), found.group(2)
        n = _PRESSES.get(times or "", number(times or "") or 1)
        out += [Forward(n)] if button in ("forward", "up") else [Turn(1 if button == "left" else -1)] * n
    return out


def _question(text: str, ws: list[str]) -> Ask:
    if _HOW_FAR_AHEAD.search(text):
        return Ask(AskedAbout.DISTANCE)
    look = bool(_LOOK.search(text))
    labels = _labels(ws)
    side = _side([w for w in ws if w not in ("forward",)])
    if labels and re.search(r"^(is|are|do|does|can|any)\b|\bsee (?:a|any|the)\b|\?$", text):
        return Ask(AskedAbout.IS_THERE, side, labels[0], look)
    if side is not None and re.search(r"\b(what|whats|anything|describe)\b", text) and not look:
        return Ask(AskedAbout.SIDE, side)
    return Ask(AskedAbout.VIEW, None, None, look)


def _clause(text: str, prev: Instruction | None) -> list[Instruction]:
    ws = words(text)
    text = " ".join(ws)
    if not ws:
        return []
    cut = ws.index("not") if "not" in ws else len(ws)
    labels, excluded = _labels(ws[:cut]), frozenset(_labels(ws[cut:]))
    if cut == 0:
        if isinstance(prev, Forward) and excluded:
            return [Forward(prev.steps, prev.until if prev.until not in excluded else None, prev.exclude | excluded)]
        return [Unclear(text)]
    if _CLAIM.search(text):
        return [Stop(claim=True)]
    if re.search(r"\b(back|return)\b", text) and (BACK_START.search(text) or "where" in ws):
        if BACK_START.search(text):
            return [GoBack(Place.START)]
        side = _side([w for w in ws if w in ("left", "right")])
        nth = next((ORDINAL_WORDS[w] for w in ws if w in ORDINAL_WORDS and w != "next"), 1)
        return [GoBack(Place.TURN, side, nth)]
    objects = [label for label in labels if label in OBJECT_LABELS]
    side_words = _SIDE_PHRASE.search(text)
    if objects and side_words and not _GO.search(text.replace(side_words.group(0), "")):
        return [Target(objects[0], _side(side_words.group(0).split()))]
    purpose = _FIND.search(text)
    if objects and purpose:
        # "turn left and left again to find the jar", "ok lets find the paddle": the target, and the moves before it
        rest = [i for i in _clause(text[: purpose.start()], prev) if not isinstance(i, Unclear)]
        return [Target(objects[0]), *rest]
    if (
        objects
        and re.search(r"\b(objective|target|next|goal|the|a|should see|will see|looking for)\b", text)
        and not (_GO.search(text))
    ):
        return [Target(objects[0])]
    if labels and not objects and _EXPECT.search(text):
        # "you should have blue walls on your right": a check of the view, answered like a question
        return [Ask(AskedAbout.IS_THERE, _side(ws) or Side.AHEAD, labels[0])]
    if _UTURN.search(text):
        return [Turn(4)]
    opening = _OPENING.search(text)
    if opening and re.search(r"\b(take|make|turn|go)\b", text):
        return [TakeOpening(Side(opening.group(2)), ORDINAL_WORDS[opening.group(1)])]
    # "keep the red wall on your left" places a wall, it is no turn: drop the place before looking for one.
    unplaced = _SIDE_PHRASE.sub(" ", text)
    unplaced_ws = unplaced.split()
    turn_side = _side([w for k, w in enumerate(unplaced_ws) if turns_to(unplaced_ws, k)])
    steps = next((n for n in (number(w) for w in ws) if n is not None and n not in (45, 90, 135, 180)), None)
    out: list[Instruction] = []
    wants_forward = bool(_GO.search(unplaced)) or steps is not None
    stop_at = labels[0] if labels and _UNTIL.search(unplaced) else None
    if turn_side is not None and (stop_at is not None or re.search(r"\b(at|reach|reached) the (?:end|wall)", unplaced)):
        out.append(Forward(None, stop_at, excluded))
    elif wants_forward:
        if steps is not None and re.search(r"\bsteps?\b", text) or steps is not None and turn_side is None:
            out.append(Forward(steps))
        elif stop_at is not None or re.search(r"\b(until|till|end|wall)\b", unplaced):
            out.append(Forward(None, stop_at, excluded))
        elif turn_side is None:
            out.append(Forward(None, objects[0] if objects else None))
    if turn_side is not None:
        size = _turn_size(ws) * (1 if turn_side == Side.LEFT else -1)
        out += [Turn(size)] * times_turned(ws)
    if not out and _STOP.search(text):
        return [Stop(claim=False)]
    if not out and not re.search(
        r"\b(ok|okay|good|great|yes|yeah|nice|perfect|awesome|correct|right|cool|got it|thanks|thank you|thx)\b", text
    ):
        return [Unclear(text)]
    return out


def clauses(message: str) -> list[str]:
    """A message cut into the clauses `parse` reads one at a time (lower case)."""
    return _CLAUSE.split(message.strip().lower())


def parse(message: str) -> Parsed:
    """The instructions of one Commander message, in order."""
    text = message.strip().lower()
    if _QUESTION.search(text) and not _CLAIM.search(" ".join(words(text))):
        ask = _question(" ".join(words(text)), words(text))
        moves: list[Instruction] = []
        if ask.question == AskedAbout.VIEW and _UTURN.search(text) and not ask.look_around:
            moves.append(Turn(4))
        return Parsed(tuple(moves) + (ask,))
    out: list[Instruction] = []
    pressing = False
    for clause in clauses(text):
        last = next((k for k in range(len(out) - 1, -1, -1) if isinstance(out[k], Forward)), None)
        presses = pressed(" ".join(words(clause)), pressing)
        pressing = pressing or presses is not None
        parsed = presses if presses is not None else _clause(clause, out[last] if last is not None else None)
        if last is not None and parsed and isinstance(parsed[0], Forward) and parsed[0].exclude:
            out[last] = parsed[0]  # "..., not the red one" narrows the wall to stop at
            continue
        for instruction in parsed:
            if isinstance(instruction, Forward) and out and out[-1] == Forward():
                out[-1] = instruction  # "continue forward and turn left at the white wall": one walk
                continue
            if instruction == Forward() and out and isinstance(out[-1], Forward):
                continue  # "keep the red wall on your left and go straight": one walk
            out.append(instruction)
    if any(i == Stop(claim=True) for i in out):
        out = [i for i in out if i != Stop(claim=False)]
    return Parsed(tuple(out))
