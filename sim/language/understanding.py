"""How the agents understand the other seat: the trained reader, and what its readings ask of them.

The Driver agent reads a Commander turn as a program (`program`) and carries it out through the
rules' instructions (`instructions`), the executor it always had; the Commander agent reads a
Driver turn as facts (`facts`) and weighs them in its belief through the lexicon's facts
(`belief_facts`). The Driver reads with the trained reader (`sim.language.reader`) by default, the
Commander by the rules (docs/model_card_language.md says why). `read_back` says the Driver's
instructions in a few words, so an agent can tell a person what it understood before acting on
it; `unread_counts` are the counts a reading left unused, which it says it did not get.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

from sim.core.labels import OBJECT_LABELS, WALL_LABELS, Label
from sim.language import instructions as ins
from sim.language import lexicon
from sim.language.meaning import (
    CLAUSE_FIELDS,
    FACT_FIELDS,
    Clause,
    FactForm,
    FactKind,
    Op,
    Program,
    facts_of,
    program_of,
)
from sim.language.reader import Count, Reader, Role, counts, shipped
from sim.language.sectors import Sector
from sim.language.vocab import (
    CAMERA_COLOUR_WORDS,
    LABEL_WORDS,
    ORDINAL_WORDS,
    SIDE_PHRASE,
    SIDE_SECTOR,
    Side,
    times_turned,
    turns_to,
    wall_name,
    words,
)

M = TypeVar("M", Program, frozenset[FactForm])


@dataclass(frozen=True)
class Understood(Generic[M]):
    meaning: M
    confidence: float
    by_rules: bool  # read by the rules (no reader for this seat's words)
    strange_lead: bool = False  # the reader never met the turn's first word
    ambiguous: bool = False  # the words may well mean another move ("left 1": a turn, or a turn and a step)
    read: str = ""  # a Commander turn's words read, without what `instructing` leaves out


class Understanding:
    """One agent's reading of the other seat's turns: by the given readers, a role without one by the
    rules alone. (The rules as a fallback below a reader's confidence scored no better on val_seen
    at any threshold from 0.5 to 0.9; where the Driver is unsure it asks instead.)"""

    def __init__(self, commander: Reader | None, driver: Reader | None) -> None:
        self.commander_reader = commander
        self.driver_reader = driver

    @classmethod
    def trained(cls) -> Understanding:
        """The readers shipped in the package: what the agents understand with."""
        return cls(shipped(Role.COMMANDER), shipped(Role.DRIVER))

    @classmethod
    def by_rules(cls) -> Understanding:
        """The rules alone (what the readers' own training dialogs are played with)."""
        return cls(None, None)

    def program(self, text: str, before: tuple[str, str] | None = None) -> Understood[Program]:
        """A Commander turn; `before` the turn before it as ("c" or "d", text)."""
        if self.commander_reader is None:
            return Understood(program_of(ins.parse(text)), 1.0, True, read=text)
        text = plainly(text)
        if (pressed := self._pressed(text, before)) is not None:
            return Understood(pressed, 1.0, False, read=text)
        text = instructing(text)
        reading = self.commander_reader.read(text, before)
        assert isinstance(reading.meaning, tuple)  # a Commander reader writes programs
        read = _turned_as_often(_turned_around_as_said(reading.meaning, text), text)
        sided = _sided_walk(read, text)  # a guess between readings a person may mean: asked about
        program = _back_as_said(_openings_as_said(_grounded(sided, text, before), text), text)
        said = words(text)
        program = _walks_as_said(_turned_between(_pairs_as_said(program, said), said), text, said)
        program = _claimed_as_said(_right_as_said(_facing_as_said(program, said), said), said)
        return Understood(program, reading.confidence, False, reading.strange_lead, ambiguous=sided != read, read=text)

    def _pressed(self, text: str, before: tuple[str, str] | None) -> Program | None:
        """A message that counts presses of the Driver's buttons ("press left twice", "click forward
        3 times, then right once"), clause by clause: each press one move, a step or a turn of 45
        degrees (the reader read "press left twice" as two quarter turns, "press forward" as a walk
        to the wall, and "click forward 4 times" as nothing). Clauses with no press are read as
        alone; None where no button is pressed."""
        parts = [(part, " ".join(words(part))) for part in ins.clauses(text)]
        if not any(ins.press_verb(said) for _, said in parts):
            return None
        out: list[Clause] = []
        pressing = False
        for part, said in parts:
            moves = ins.pressed(said, pressing)
            pressing = pressing or moves is not None
            if moves is not None:
                out += program_of(ins.Parsed(tuple(moves)))
            elif said:
                out += [c for c in self.program(part, before).meaning if c.op != Op.UNCLEAR]
        return tuple(out)

    def mended(self, text: str) -> Program:
        """The best reading to offer where the whole reading missed a turn the rules hear (`turns_missed`):
        clause by clause as the rules cut the words, each as the reader reads it alone with the turns
        the rules hear in it and that reading lacks put where the rules put them (before its walks
        or after them); a clause that says not to do something, or that it was not needed ("you
        didn't need to turn around"), gives no move."""
        out: list[Clause] = []
        for part in ins.clauses(text):
            said = words(part)
            if not said or _NOT_DONE.intersection(said):
                continue
            read = [c for c in self.program(part).meaning if c.op != Op.UNCLEAR]
            ruled = program_of(ins.parse(part))
            for left in (True, False):
                turns = [c for c in ruled if _turns(c, left)]
                missing = turns[sum(_turns(c, left) for c in read) :]
                if not missing:
                    continue
                first_walk = next((k for k, c in enumerate(ruled) if c.op == Op.FORWARD), len(ruled))
                before_walks = ruled.index(missing[0]) < first_walk
                at = (
                    next((k for k, c in enumerate(read) if c.op == Op.FORWARD), len(read))
                    if before_walks
                    else len(read)
                )
                read[at:at] = missing
            out += read
        return tuple(out)

    def facts(
        self, text: str, before: tuple[str, str] | None = None, asked: str | None = None
    ) -> Understood[frozenset[FactForm]]:
        """A Driver turn; `asked` the Commander's question it answers, for the rules."""
        if self.driver_reader is None:
            return Understood(facts_of(text, asked), 1.0, True)
        reading = self.driver_reader.read(text, before)
        assert isinstance(reading.meaning, frozenset)  # a Driver reader writes facts
        return Understood(_joined(reading.meaning, facts_of(text, asked), text), reading.confidence, False)


# A clause that says where the Driver is, or what a move is for, and asks nothing done ("i think
# you're in the corridor at the top left", "so you get above the white wall", "if you're right next
# to the mug"), and the clauses that go on describing ("..., facing a red wall"): a person's, into
# which the reader read turns and walks.
_STATE = re.compile(
    r"^(?:ok |okay |so |then )*(?:if |when |since |as |so (?:that )?)?"
    # "ok i'm guessing you're at the bottom of the map" was a walk to the wall
    r"(?:i think |i guess |i believe |it looks like |looks like |(?:i m|im|i am) guessing |i bet |probably |maybe )?"
    r"(?:you are|youre|you re|you have|youve|you get|you will be|youll be)\b"
)
_CLAIMS = ins.Stop(claim=True)
_NOT_TO = re.compile(
    r"\b(?:dont|didnt|do not|did not|never|shouldnt|no need to|neednt)\b (?:\w+ ){0,3}?"
    r"(?:turn|turned|go|went|move|moved|walk|drive|head|press|mean|meant|ask|asked)\b"  # "i didn't ask for 10 more steps"
)
# Chat about the game, not a move: "two down and one to go", "u went 2 far".
_CHATTER = re.compile(
    r"^(?:\w+ )?(?:one|two|three|1|2|3) (?:down|done|(?:more |left )?to go)$|^(?:you|u) went (?:\w+ ){0,2}(?:too|to|2) far\b"
    r"|\b(?:out of time|times up|time is up)\b"  # "ok we're out of time, stopping here": it had driven off
    # Said of what was done: "that was more than 10 steps i think!", "oops that's too much", "you
    # went a bit far but fine", "i was just commenting" (each had been carried out as a move)
    r"|^(?:\w+ )?(?:that (?:was|s|is)|thats) (?:\w+ ){0,2}(?:too|more|less|much|enough)\b|^(?:\w+ )?(?:you|u) went (?:\w+ ){0,3}far\b"
    r"|^i (?:was|am|m) (?:just )?(?:commenting|saying|kidding)\b"
)
_GOES_ON = re.compile(r"^(?:facing|with|which|where|near|next|at|in|by)\b")
_DOES = re.compile(
    r"\b(?:turn|turning|go|going|move|drive|walk|head|take|press|continue|keep|back|stop|claim|find|look"
    r"|looking|spin|rotate|face|target|objective|goal)\b"
)


# A turn's size in degrees or in clicks of a button, said as the words the reader knows: a person's
# "turn left 45, forward 5" was a quarter turn, and "turn left one click, go forward 4" a quarter
# turn and a step.
_SIZE_WORDS = {1: "turn slightly {side}", 2: "turn {side}", 3: "turn sharply {side}", 4: "turn around"}
_DEGREES = {"45": 1, "90": 2, "135": 3, "180": 4}
_CLICKS = {"one": 1, "a": 1, "1": 1, "two": 2, "2": 2, "three": 3, "3": 3, "four": 4, "4": 4}
_TURN_VERB = r"(?:(?:turn|go|rotate|spin|veer) )?"
_SIDE_DEGREES = re.compile(rf"\b{_TURN_VERB}(left|right) (?:by )?(45|90|135|180)(?: ?degrees?| ?deg)?\b")
_DEGREES_SIDE = re.compile(rf"\b{_TURN_VERB}(45|90|135|180)(?: ?degrees?| ?deg)? (?:to (?:the |your )?)?(left|right)\b")
_SIDE_CLICKS = re.compile(
    rf"\b{_TURN_VERB}(left|right) ({'|'.join(_CLICKS)}) (?:click|clicks|press|presses|tap|taps|notch|notches)\b"
)
# "next is the mug": the next target named, not a walk to it (read as "forward to the coffee mug").
_NEXT_IS = re.compile(r"\b(?:the )?next (?:one |target |up )?is (?:the )?(jar|mug|cup|paddle)\b")
# A whole circle, slowly: a look around ("turn all the way around slowly and tell me every color you
# see" was a half turn and one view; "spin around 360" a half turn and "forward 360 steps?").
_FULL_CIRCLE = re.compile(
    r"\b(?:(?:turn|spin|rotate|go) )?(?:all the way |fully |right )?(?:a)?round (?:slowly|in a (?:full )?circle)\b"
    r"|\b(?:(?:turn|spin|rotate) )?(?:(?:all the way |a)?round )?(?:a |do a |full )?360(?: ?degrees?)?\b|\b(?:a )?full circle\b"
)


# "go ahead and tell me": do; "the olive green paddle", "the pink mug": the object's colour, no wall.
_GO_AHEAD = re.compile(r"\bgo ahead and\b", re.I)
# Colour words proper: "the edge" is a wall of the map too, but never one of a pair ("red and white").
_COLOUR_WORDS = {
    w: label for w, label in LABEL_WORDS.items() if label in WALL_LABELS and w not in ("edge", "border", "boundary")
}


_COLOUR = (
    rf"(?:(?:light|dark|bright|pale) )?(?:{'|'.join([*_COLOUR_WORDS, *CAMERA_COLOUR_WORDS])})(?: coloured| colored)?"
)
_OBJECT = rf"(?:{'|'.join(w for w, label in LABEL_WORDS.items() if label in OBJECT_LABELS)}|cylinder)s?"
_OBJECT_COLOUR = re.compile(rf"\b{_COLOUR} (?={_OBJECT}\b)", re.I)  # "the olive green paddle"
_OBJECT_THEN_COLOUR = re.compile(
    rf"\b({_OBJECT}),? (?:the |a )?{_COLOUR} (?:one|thing)\b", re.I
)  # "the jar, the light blue one"


def instructing(text: str) -> str:
    """`text` without its clauses that only say where the Driver is or what a move is for, its
    objects' colours and its "go ahead and"; the text itself where it has none of these."""
    plain = _OBJECT_THEN_COLOUR.sub(r"\1", _OBJECT_COLOUR.sub("", _GO_AHEAD.sub("", text)))
    kept: list[str] = []
    dropped = describing = False
    for part in (p for piece in re.split(r"[:?]", plain) for p in ins.clauses(piece)):
        said = " ".join(words(part))
        if not said:
            continue
        state = _STATE.match(said) or (describing and _GOES_ON.match(said))
        # "i didn't ask you to turn right!", "don't turn left", "i didn't mean forward": nothing to do
        if _NOT_TO.search(said) or _CHATTER.search(said):
            dropped = True
            continue
        # One that names an object or claims stays: "you're at the jar", "you are right by it" claim,
        # "you are next to the jar" places.
        if state and not _DOES.search(said) and not _places_or_claims(said):
            dropped = describing = True
            continue
        describing = False
        kept.append(part.strip())
    return ". ".join(kept) if dropped else plain


def plainly(text: str) -> str:
    """`text` (in lower case) with a turn's size in degrees or clicks said in words ("turn left
    45" -> "turn slightly left", "right two clicks" -> "turn right"), "next is the X" said as
    "now find the X" and a whole circle as a look around; as it is where it has none of these."""
    said = text.lower()  # its punctuation kept: it cuts the clauses
    plain = _SIDE_DEGREES.sub(lambda m: _sized(m.group(1), _DEGREES[m.group(2)]), said)
    plain = _DEGREES_SIDE.sub(lambda m: _sized(m.group(2), _DEGREES[m.group(1)]), plain)
    plain = _SIDE_CLICKS.sub(lambda m: _sized(m.group(1), _CLICKS[m.group(2)]), plain)
    plain = _NEXT_IS.sub(r"now find the \1", plain)
    plain = _FULL_CIRCLE.sub("look around", plain)
    return text if plain == said else plain


def _sized(side: str, eighths: int) -> str:
    return _SIZE_WORDS[eighths].format(side=side)


def _places_or_claims(said: str) -> bool:
    return any(label in OBJECT_LABELS for label in _named(said.split())) or _CLAIMS in ins.parse(said).instructions


_PRESS_FOUND = re.compile(rf"\b{ins.PRESS_FOUND}\b")
_CLAIM_NOW = Clause.of(Op.STOP, claim=True)
_TO_WALL_SAID = frozenset({"wall", "walls", "end", "until", "till", "til"})
_WALK_SAID = frozenset({"go", "forward", "drive", "walk", "move", "straight", "ahead", "head", "keep"})


def _claimed_as_said(program: Program, said: list[str]) -> Program:
    """The Driver told to press its "I found the target" button ("go up to it and press the found
    button"), as the rules hear it: a claim, after the moves; the reader read it as nothing clear,
    or as a walk to a wall or a target it named (a person typed the button's label to be heard)."""
    if not _PRESS_FOUND.search(" ".join(said)) or _CLAIM_NOW in program:
        return program
    named = set(_named(said))
    kept = [c for c in program if c.op != Op.UNCLEAR and not (c.op == Op.TARGET and _label(c.args[0]) not in named)]
    # "go up to it and press the found button", "click i found the target": no walk on to a wall
    # that no word names, after the walk said or where none is
    walks_said = any(c.op == Op.FORWARD for c in kept[:-1]) or not _WALK_SAID.intersection(said)
    if kept and kept[-1] == _TO_A_WALL and walks_said and not _TO_WALL_SAID.intersection(said):
        kept.pop()
    return (*kept, _CLAIM_NOW)


def _right_as_said(program: Program, said: list[str]) -> Program:
    """The reading without right turns where no "right" of the words is a turn ("if you're right next
    to the mug, go ahead and tell me you found it" was read as a right turn and a walk)."""
    if any(w == "right" and turns_to(said, k) for k, w in enumerate(said)):
        return program
    return tuple(c for c in program if not _turns(c, left=False))


def _turned_as_often(program: Program, text: str) -> Program:
    """A program's one turn made as many times as the words say ("make two right turns", "turn
    right 4 times"): the reader learnt these from the rules, which knew only "twice", and reads one."""
    times = times_turned(words(text))
    turns = [k for k, clause in enumerate(program) if clause.op == Op.TURN]
    if times == 1 or len(turns) != 1:
        return program
    k = turns[0]
    return (*program[:k], *[program[k]] * times, *program[k + 1 :])


_SIDED_U_TURN = re.compile(r"\b(left|right) u[ -]?turn\b")  # on the words as written: "uturn" is no keyword
_AROUND = Clause.of(Op.TURN, eighths=4)


def _turned_around_as_said(program: Program, text: str) -> Program:
    """A u-turn said with a side ("take a right u turn"): turning around, which the reader read as a
    quarter turn that way."""
    found = _SIDED_U_TURN.search(text.lower())
    if found is None or _AROUND in program:
        return program
    left = found.group(1) == "left"
    quarter = Clause.of(Op.TURN, eighths=2 if left else -2)
    if quarter not in program:
        return program
    last = len(program) - 1 - program[::-1].index(quarter)  # "turn right, then a right u-turn"
    return (*program[:last], _AROUND, *program[last + 1 :])


_LATELY = re.compile(r"\b(ago|just were|were before|where you were|way you came|came from|last spot)\b")


def _back_as_said(program: Program, text: str) -> Program:
    """Back to where the Driver just was, where the words say so ("where you were a moment ago"):
    the reader read it as back to the start, 38 moves back to where the trial began."""
    if not _LATELY.search(" ".join(words(text))) or ins.BACK_START.search(text.lower()):
        return program
    return tuple(
        Clause(Op.BACK, ("previous", c.args[1])) if c.op == Op.BACK and c.args[0] != "previous" else c for c in program
    )


_NOT_DONE = frozenset({"not", "dont", "didnt", "never", "shouldnt", "neednt", "without"})


def turns_missed(program: Program, rules: Program) -> bool:
    """Whether the rules hear more turns one way than the reading makes ("about face, fwd 2, then
    right, fwd 10" was read as the two walks alone)."""
    return any(sum(_turns(c, left) for c in rules) > sum(_turns(c, left) for c in program) for left in (True, False))


# Words that point at something named earlier ("go there", "follow them", "the objective").
_REFERRING = frozenset(
    {"it", "its", "them", "they", "there", "that", "those", "these", "this", "one", "ones", "same", "object"}
    | {"objective", "target", "goal", "thing", "item", "next", "again", "before", "previous", "last", "other"}
)


def _grounded(program: Program, text: str, before: tuple[str, str] | None) -> Program:
    """The reading without a colour or object the words do not name: where the turn points back
    ("go up to it"), the one the turn before names, where it names one of that kind (the reader
    took "it" after "i can see the mug" for the jar); elsewhere the clause is dropped ("take the
    second opening on your left" was read as "the paddle should be on your left"). Nothing left of
    a reading: not understood."""
    said = words(text)
    own = _named(said)
    earlier = _named(words(before[1])) if before else []
    if _REFERRING.intersection(said):
        # "it", "there" point at objects: a wall colour neither turn names is dropped all the same (a
        # person's "Hello there! ... tell me what you can see" was asked back about a yellow wall).
        referred = (_as_referred(c, own, earlier) for c in program)
        kept = tuple(
            c for c in referred if all(_label(v) in own + earlier + list(OBJECT_LABELS) for v in _labels_named(c))
        )
    else:
        kept = tuple(c for c in program if all(_label(v) in own + earlier for v in _labels_named(c)))
    return kept if kept or not program else (Clause.of(Op.UNCLEAR),)


def _named(said: list[str]) -> list[Label]:
    return [label for w in said if (label := LABEL_WORDS.get(w)) is not None]


def _as_referred(clause: Clause, own: list[Label], earlier: list[Label]) -> Clause:
    """`clause` with a colour or object it names that the turn does not replaced by the one of
    its kind the turn before names, where that names exactly one."""
    args = list(clause.args)
    for k, (name, value) in enumerate(zip(CLAUSE_FIELDS[clause.op], clause.args, strict=True)):
        label = _label(value) if name in ("label", "until") and value != "wall" else None
        if label is None or label in own:
            continue
        kind = set(OBJECT_LABELS) if label in OBJECT_LABELS else set(Label) - set(OBJECT_LABELS)
        candidates = {e for e in earlier if e in kind}
        if len(candidates) == 1:
            args[k] = candidates.pop().name.lower()
    return Clause(clause.op, tuple(args))


def _labels_named(clause: Clause) -> list[str]:
    """The colours and objects a clause names (a walk "until" any wall names none)."""
    fields = zip(CLAUSE_FIELDS[clause.op], clause.args, strict=True)
    return [v for name, v in fields if name in ("label", "until") and isinstance(v, str) and v != "wall"]


def _openings_as_said(program: Program, text: str) -> Program:
    """The openings the words count ("the 2nd opening on your left"), which the rules read and
    the reader, having met almost none in people's words, reads with another count or not at all."""
    if not ORDINAL_WORDS.keys() & set(words(text)):
        return program  # no count of openings: the rules' reading, a few milliseconds, is not needed
    ruled = program_of(ins.parse(text))
    said = [c for c in ruled if c.op == Op.OPENING]
    read = [k for k, c in enumerate(program) if c.op == Op.OPENING]
    if not said or [program[k] for k in read] == said:
        return program
    if len(read) != len(said):  # the reader missed one: the rules' reading, which has them all
        return ruled
    out = list(program)
    for k, opening in zip(read, said, strict=True):
        out[k] = opening
    return tuple(out)


_TO_A_WALL = Clause.of(Op.FORWARD, steps=None, until="wall")


def _pairs(said: list[str]) -> list[tuple[Label, Label]]:
    """Colours said as a pair, in the order said ("the green and yellow walls", "white and a green wall")."""
    out = []
    for k in range(1, len(said) - 1):
        if said[k] != "and" or said[k - 1] not in _COLOUR_WORDS:
            continue
        nxt = said[k + 2] if said[k + 1] in ("a", "the") and k + 2 < len(said) else said[k + 1]
        if nxt in _COLOUR_WORDS:
            out.append((_COLOUR_WORDS[said[k - 1]], _COLOUR_WORDS[nxt]))
    return out


def _pairs_as_said(program: Program, said: list[str]) -> Program:
    """Both colours of a pair the Driver should see ("green and yellow walls to your left"): the reader
    keeps one of two colours said together, as the rules' single-colour views taught it."""
    for first, second in _pairs(said):
        out: list[Clause] = []
        for clause in program:
            if clause.op == Op.EXPECT and _label(clause.args[0]) in (first, second):
                pair = [Clause.of(Op.EXPECT, label=label.word, side=clause.args[1]) for label in (first, second)]
                out += [c for c in pair if c == clause or c not in program]
            else:
                out.append(clause)
        program = tuple(out)
    return program


_TURN_BETWEEN = re.compile(r"\b(?:turn (left|right)|(left|right) turn) (?:in )?between (?:the )?(\w+)")


def _turned_between(program: Program, said: list[str]) -> Program:
    """A turn made between walls ("turn left between the red and brown walls"): a walk to the first
    colour, then the turn, as "turn left at the red wall" is (the reader walks to any wall, or drops
    the walk)."""
    found = _TURN_BETWEEN.search(" ".join(said))
    colour = _COLOUR_WORDS.get(found.group(3)) if found else None
    if found is None or colour is None:
        return program
    left = (found.group(1) or found.group(2)) == "left"
    walk = Clause.of(Op.FORWARD, steps=None, until=colour.word)
    turn = next((j for j, c in enumerate(program) if _turns(c, left)), None)
    if turn is None:  # the turn dropped too: where the reading ends on a walk to a wall, after it
        if not program or program[-1] != _TO_A_WALL:
            return program
        return (*program[:-1], walk, Clause.of(Op.TURN, eighths=2 if left else -2))
    if turn > 0 and program[turn - 1].op == Op.FORWARD:
        if program[turn - 1].args[0] is not None:
            return program  # a count of steps said
        return (*program[: turn - 1], walk, *program[turn:])
    return (*program[:turn], walk, *program[turn:])


_STRAIGHT_ON = frozenset({"forward", "straight", "ahead", "forwards"})


def _walks_as_said(program: Program, text: str, said: list[str]) -> Program:
    """The walk a Commander's message opens with ("go straight, then turn left", "move forward and
    follow the red walls") or ends on after a turn ("turn around and follow the corridor"), where
    the rules read that part as a walk alone: the reader folds the first into what follows it, and
    drops the last."""
    if not program:
        return program
    opens = program[0].op not in (Op.FORWARD, Op.BACK) and bool(_STRAIGHT_ON.intersection(said))
    ends = program[-1].op in (Op.TURN, Op.OPENING)
    if not (opens or ends):
        return program  # the rules' cutting and parsing, a few milliseconds, are not needed
    parts = [part for part in ins.clauses(text) if words(part)]
    if opens and _STRAIGHT_ON.intersection(words(parts[0])) and program_of(ins.parse(parts[0])) == (_TO_A_WALL,):
        program = (_TO_A_WALL, *program)
    if ends and len(parts) >= 2 and program_of(ins.parse(parts[-1])) == (_TO_A_WALL,):
        program = (*program, _TO_A_WALL)
    return program


_FACING = re.compile(r"\b(?:facing|face) (?:the |a |an )?(\w+)")
_UNTIL = frozenset({"until", "till", "til", "when", "unless"})


def _facing_as_said(program: Program, said: list[str]) -> Program:
    """What the Driver is to face once there ("turn around so you are facing the blue walls"): a
    check that it is ahead, where the reader walked up to it."""
    found = _FACING.search(" ".join(said))
    label = LABEL_WORDS.get(found.group(1)) if found else None
    if label is None or _UNTIL.intersection(said):  # "go on until you are facing the red wall": a walk
        return program
    walk = Clause.of(Op.FORWARD, steps=None, until=label.word)
    faced = Clause.of(Op.EXPECT, label=label.word, side="ahead")
    return tuple(faced if c == walk else c for c in program)


_PLACE_WORDS = frozenset({"your", "my", "the", "on", "to", "its"})  # "on your right 3 steps on": where, not a turn


def _sided_walk(program: Program, text: str) -> Program:
    """A side said just before a count of steps ("right 3", "go left 2 steps") is most likely a turn
    that way, then the walk (a person may mean a turn counted: "left 1 then fwd 2"). No recorded Commander writes it, and the reader read "right 3" as the walk alone
    (the Driver went straight), "left 3" as the turn alone and "forward 2 right 3" as the first walk
    alone; each gets the part it dropped, in the order said."""
    said, done = words(text), 0  # the clauses before `done` are those of sides and counts already seen
    for side, count in _sides_with_counts(said, counts(text)):
        left = side == "left"
        turn = next((j for j in range(done, len(program)) if _turns(program[j], left)), None)
        walk = next((j for j in range(done, len(program)) if _walks(program[j], count.steps)), None)
        steps = Clause.of(Op.FORWARD, steps=count.steps, until=None)
        if turn is not None and walk is not None:
            done = max(turn, walk) + 1
        elif turn is not None:
            program, done = (*program[: turn + 1], steps, *program[turn + 1 :]), turn + 2
        elif walk is not None:
            program, done = (*program[:walk], Clause.of(Op.TURN, eighths=2 if left else -2), *program[walk:]), walk + 2
        else:  # both dropped: the walk where the words put the count, the turn before it
            placed, _ = with_count(program, text, count)
            at = next((j for j, (a, b) in enumerate(zip(program, placed, strict=False)) if a != b), len(program))
            program, done = (*program[:at], Clause.of(Op.TURN, eighths=2 if left else -2), *placed[at:]), at + 2
    return program


def _sides_with_counts(said: list[str], named: list[Count]) -> list[tuple[str, Count]]:
    """Each count of steps said just after "left" or "right" (not "on your right 3 steps on"), in order."""
    out, k = [], 0
    for count in named:
        number = count.said.split()[0]
        k = next((j for j in range(max(k, 1), len(said)) if said[j] == number), len(said))
        sided = k < len(said) and count.of_steps and said[k - 1] in ("left", "right")
        if sided and (k < 2 or said[k - 2] not in _PLACE_WORDS):
            out.append((said[k - 1], count))
        k += 1
    return out


def _turns(clause: Clause, left: bool) -> bool:
    eighths = clause.args[0] if clause.op == Op.TURN else None
    return isinstance(eighths, int) and (eighths > 0) == left


def _walks(clause: Clause, steps: int) -> bool:
    return clause.op == Op.FORWARD and clause.args[0] == steps


VIEW_KINDS = frozenset(
    {FactKind.LABEL, FactKind.EDGE, FactKind.CORRIDOR, FactKind.CORNER, FactKind.DEAD_END, FactKind.NEXT_TO}
)


def _joined(read: frozenset[FactForm], ruled: frozenset[FactForm], text: str) -> frozenset[FactForm]:
    """A Driver turn's dialog acts (answers, questions, claims) as the reader reads them, its view as
    the rules do where they make anything of it: they bind each colour to the direction written
    with it, where the reader learnt which colours go with which directions and now and then
    swaps them ("white to my left, red to my right" read the other way round). Where they make
    nothing of it, the reader's view only for a "yes" or "no", which it reads against the turn
    before; of other words it guessed ("and took a left" read as a dead end)."""
    view = frozenset(f for f in ruled if f.kind in VIEW_KINDS)
    said = lexicon.tokens(text)
    if not view and said and said[0] in lexicon.YES | lexicon.NO:
        view = frozenset(f for f in read if f.kind in VIEW_KINDS)
    asked = frozenset(f for f in ruled if f.kind == FactKind.QUESTION)  # a question's first word, or its "?"
    return frozenset(f for f in read if f.kind not in VIEW_KINDS) | asked | view


def _label(word: object) -> Label | None:
    return Label[str(word).upper()] if isinstance(word, str) and word.upper() in Label.__members__ else None


def _side(word: object) -> Side | None:
    return Side(word) if isinstance(word, str) and word in ("ahead", "left", "right", "behind") else None


_QUESTION = {"view": ins.AskedAbout.VIEW, "side": ins.AskedAbout.SIDE, "is_there": ins.AskedAbout.IS_THERE}


def instructions(program: Program, text: str) -> list[ins.Instruction]:
    """What the Driver's executor carries out for a program (clauses with nothing to do drop out),
    with a turn the words say goes on until something is in view (`ins.turn_until`)."""
    out: list[ins.Instruction] = []
    if ins.asks_distance(text):
        # "how many steps until the wall in front of you?" asks, it does not send the Driver there
        program = tuple(c for c in program if c.op not in (Op.FORWARD, Op.FOLLOW))
        if not any(c.op == Op.ASK for c in program):
            program = (*program, Clause.of(Op.ASK, question="other", side=None, label=None))
    for clause in program:
        args = dict(zip(CLAUSE_FIELDS[clause.op], clause.args, strict=True))
        match clause.op:
            case Op.TURN:
                out.append(ins.Turn(int(args["eighths"] or 0)))
            case Op.FORWARD:
                steps = args["steps"]
                out.append(ins.Forward(steps if isinstance(steps, int) else None, _label(args["until"])))
            case Op.FOLLOW:
                out.append(ins.Forward())
            case Op.OPENING:
                side, nth = _side(args["side"]), args["nth"]
                if side is not None:
                    out.append(ins.TakeOpening(side, nth if isinstance(nth, int) else 1))
            case Op.BACK if args["place"] == "start":
                out.append(ins.GoBack(ins.Place.START))
            case Op.BACK if args["place"] == "turn":
                out.append(ins.GoBack(ins.Place.TURN))
            case Op.BACK:  # the way it came: turn around (unless just told to) and walk
                steps = args["steps"]
                if not (out and out[-1] == ins.Turn(4)):  # "turn around and go back the way you came"
                    out.append(ins.Turn(4))
                out.append(ins.Forward(steps if isinstance(steps, int) else None))
            case Op.TARGET:
                label = _label(args["label"])
                if label is not None:
                    out.append(ins.Target(label))
            case Op.EXPECT:
                label = _label(args["label"])
                if label in OBJECT_LABELS:
                    out.append(ins.Target(label, _side(args["side"])))
            case Op.ASK if ins.asks_distance(text):
                out.append(ins.Ask(ins.AskedAbout.DISTANCE))
            case Op.ASK:
                question = str(args["question"])
                out.append(
                    ins.Ask(
                        _QUESTION.get(question, ins.AskedAbout.VIEW),
                        _side(args["side"]),
                        _label(args["label"]),
                        # Looking all around is eight scored moves: only when the words ask for it.
                        look_around=question == "look_around" and ins.asks_to_look(plainly(text)),
                    )
                )
            case Op.STOP:
                out.append(ins.Stop(claim=bool(args["claim"])))
            case Op.UNCLEAR:
                out.append(ins.Unclear(text))
    if (back_to := ins.turned_back_to(text)) is not None:
        return _turning_back_to(out, back_to)
    found = ins.turn_until(text)
    return out if found is None else _turning_until(out, found)


def _turning_back_to(out: list[ins.Instruction], label: Label) -> list[ins.Instruction]:
    """ "turn so the green wall is behind you": on until it is ahead (the Driver's camera sees only
    ahead), then around, in place of the program's turns and of a walk to it that the reader read
    in the words."""
    kept = [i for i in out if not isinstance(i, ins.Turn) and not (isinstance(i, ins.Forward) and i.until == label)]
    at = next((k for k, i in enumerate(out) if isinstance(i, ins.Turn)), 0)
    at = min(at, len(kept))
    return kept[:at] + [ins.Turn(2, label, facing=True), ins.Turn(4)] + kept[at:]


def _turning_until(out: list[ins.Instruction], found: ins.TurnUntil) -> list[ins.Instruction]:
    """The program's turn goes on until the thing is in view (the way the words name, else the
    program's, else left); the walk to it or the check of it that the program read into "until
    you see it" is dropped, unless the message also says to walk."""

    def of_it(item: ins.Instruction) -> bool:
        return (
            isinstance(item, ins.Forward)
            and item.until == found.until
            or (isinstance(item, ins.Target) and item.label == found.until)
        )

    at = next((k for k, item in enumerate(out) if isinstance(item, ins.Turn)), None)
    turned = out[at] if at is not None else None
    if found.side is not None:
        way = 1 if found.side == Side.LEFT else -1
    else:
        way = -1 if isinstance(turned, ins.Turn) and turned.eighths < 0 else 1
    turn = ins.Turn(2 * way, found.until, found.facing)
    if at is None:
        at = next((k for k, item in enumerate(out) if of_it(item)), 0)
        out = out[:at] + [turn] + out[at:]
    else:
        out = out[:at] + [turn] + out[at + 1 :]
    return out if found.walk else [item for item in out if not of_it(item)]


_SECTOR = {str(side): sector for side, sector in SIDE_SECTOR.items()} | {"any": Sector.ANY}  # a fact's side


def belief_facts(facts: frozenset[FactForm]) -> list[lexicon.Fact]:
    """The view facts the Commander's belief weighs (answers, questions and claims are not views)."""
    out: list[lexicon.Fact] = []
    for fact in facts:
        f = dict(zip(FACT_FIELDS[fact.kind], fact.args, strict=True))
        sectors = (_SECTOR[str(f.get("side", "any"))],)
        match fact.kind:
            case FactKind.LABEL:
                label = _label(f["label"])
                if label is not None:
                    distance = lexicon.Distance(str(f["distance"]))
                    out.append(lexicon.Fact(lexicon.ViewKind.LABEL, sectors, label, None, distance, bool(f["negated"])))
            case FactKind.EDGE:
                out.append(lexicon.Fact(lexicon.ViewKind.EDGE, sectors, negated=bool(f["negated"])))
            case FactKind.CORRIDOR:
                out.append(lexicon.Fact(lexicon.ViewKind.CORRIDOR, sectors))
            case FactKind.CORNER:
                out.append(lexicon.Fact(lexicon.ViewKind.CORNER, sectors))
            case FactKind.DEAD_END:
                out.append(lexicon.Fact(lexicon.ViewKind.DEAD_END, (Sector.FRONT,)))
            case FactKind.NEXT_TO:
                first, second = _label(f["label"]), _label(f["other"])
                if first is not None and second is not None:
                    out.append(lexicon.Fact(lexicon.ViewKind.NEXT_TO, (Sector.ANY,), first, second))
    return out


def turn_words(eighths: int) -> str:
    """A turn's way and size as the Driver says it: "left 90 degrees", "right 45 degrees", "around"."""
    if abs(eighths) == 4:
        return "around"
    return f"{'left' if eighths > 0 else 'right'} {45 * abs(eighths)} degrees"


def read_back(items: Sequence[ins.Instruction]) -> str:
    """What the Driver will do, in a few words ("turning around, then forward to the yellow wall")."""
    parts: list[str] = []
    for item in items:
        match item:
            case ins.Turn(eighths, until, facing) if until is not None:
                way = "left" if eighths > 0 else "right"
                seen = f"the {wall_name(until)} is ahead" if facing else f"i see the {wall_name(until)}"
                parts.append(f"turning {way} until {seen}")
            case ins.Turn(eighths) if eighths:
                parts.append(f"turning {turn_words(eighths)}")
            case ins.Forward(steps, until) if steps is not None:
                parts.append(f"forward {steps} steps")
            case ins.Forward(_, until):
                parts.append(f"forward to the {wall_name(until) if until is not None else 'wall'}")
            case ins.TakeOpening(side, nth):
                parts.append(f"into opening {nth} on the {side}")
            case ins.GoBack(place):
                parts.append("back where i started" if place == ins.Place.START else "back where i turned")
            case ins.Target(label, side) if side is not None:
                parts.append(f"to the {wall_name(label)} {SIDE_PHRASE[side]}")
            case ins.Stop(claim):
                parts.append("claiming" if claim else "stopping")
    return ", then ".join(parts)


MOVING_OPS = (Op.TURN, Op.FORWARD, Op.FOLLOW, Op.OPENING, Op.BACK)  # the clauses that move the robot


def with_count(program: Program, text: str, count: Count) -> tuple[Program, bool]:
    """The reading with a count it left unread put in as that many steps forward where the words
    say it: before the moves the rules hear after it ("advance 14 cm and left 45": before the
    turn; "left 3": after it). And whether it comes after every move, so that the Driver may do
    the reading's moves first."""
    parts = ins.clauses(text)
    at = next((k for k, part in enumerate(parts) if any(c.said == count.said for c in counts(part))), len(parts))
    later = sum(isinstance(i, ins.MOVING) for part in parts[at + 1 :] for i in ins.parse(part).instructions)
    if at < len(parts):  # in its own clause, a side after the count ("3 left") is a move after it
        said = words(parts[at])
        number = count.said.split()[0]
        later += number in said and any(w in ("left", "right", "around") for w in said[said.index(number) :])
    moving = [k for k, clause in enumerate(program) if clause.op in MOVING_OPS]
    where = len(program) if later == 0 else moving[max(len(moving) - later, 0)] if moving else 0
    walk = Clause.of(Op.FORWARD, steps=count.steps, until=None)
    return (*program[:where], walk, *program[where:]), later == 0


def unread_counts(program: Program, text: str) -> list[Count]:
    """The counts of steps a message names that its reading does not use ("left 3": the 3, where
    it is read as a turn alone): the Driver says it did not get them rather than drop them."""
    used = {
        value
        for clause in program
        for name, value in zip(CLAUSE_FIELDS[clause.op], clause.args, strict=True)
        if name in ("steps", "nth") and isinstance(value, int)
    }
    return [count for count in counts(text) if count.of_steps and count.steps not in used]
