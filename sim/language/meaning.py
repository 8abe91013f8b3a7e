"""What a dialog turn means, in the one form every reader of the dialog is judged in.

A Commander turn means a program: the clauses the Driver is to carry out, in order. A Driver
turn means a set of facts about its view and its dialog acts. The forms are those of the gold set
of human turns (docs/language_gold.md); the rules' readers (`instructions.parse`,
`lexicon.facts` / `lexicon.answer`) are put into them by `program_of` and `facts_of`, so a
trained reader and the rules are scored on the same terms.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum

from sim.core.labels import Label
from sim.language import instructions as ins
from sim.language import lexicon
from sim.language.sectors import Sector
from sim.language.vocab import Side

Value = str | int | bool | None


class Op(StrEnum):
    TURN = "turn"
    FORWARD = "forward"
    FOLLOW = "follow"
    OPENING = "opening"
    BACK = "back"
    TARGET = "target"
    EXPECT = "expect"
    ASK = "ask"
    ANSWER = "answer"
    STOP = "stop"
    REJECT = "reject"
    UNCLEAR = "unclear"


class FactKind(StrEnum):
    LABEL = "label"
    EDGE = "edge"
    CORRIDOR = "corridor"
    CORNER = "corner"
    DEAD_END = "dead_end"
    NEXT_TO = "next_to"
    ANSWER = "answer"
    QUESTION = "question"
    CLAIM = "claim"


# Each op's and fact kind's fields, in the order the gold set writes them.
CLAUSE_FIELDS: dict[Op, tuple[str, ...]] = {
    Op.TURN: ("eighths",),
    Op.FORWARD: ("steps", "until"),
    Op.FOLLOW: ("label",),
    Op.OPENING: ("side", "nth"),
    Op.BACK: ("place", "steps"),
    Op.TARGET: ("label",),
    Op.EXPECT: ("label", "side"),
    Op.ASK: ("question", "side", "label"),
    Op.ANSWER: ("value",),
    Op.STOP: ("claim",),
    Op.REJECT: (),
    Op.UNCLEAR: (),
}
FACT_FIELDS: dict[FactKind, tuple[str, ...]] = {
    FactKind.LABEL: ("label", "side", "distance", "negated"),
    FactKind.EDGE: ("side", "negated"),
    FactKind.CORRIDOR: ("side",),
    FactKind.CORNER: ("side",),
    FactKind.DEAD_END: (),
    FactKind.NEXT_TO: ("label", "other"),
    FactKind.ANSWER: ("value",),
    FactKind.QUESTION: (),
    FactKind.CLAIM: (),
}
LABELS = tuple(label.word for label in Label if label != Label.FLOOR)
SIDES = ("ahead", "left", "right", "behind", "any")
_SECTOR_SIDE = {
    Sector.FRONT: "ahead",
    Sector.LEFT: "left",
    Sector.RIGHT: "right",
    Sector.BEHIND: "behind",
    Sector.ANY: "any",
}
_QUESTION = {
    ins.AskedAbout.VIEW: "view",
    ins.AskedAbout.SIDE: "side",
    ins.AskedAbout.IS_THERE: "is_there",
    ins.AskedAbout.DISTANCE: "other",  # the gold set's guide has no kind of its own for it
}


def _exactly(item: Mapping[str, Value], head: Op | FactKind, fields: tuple[str, ...]) -> dict[str, Value]:
    """A clause's (`head` an Op) or fact's fields from JSON; a `ValueError` where one is missing or another is there."""
    key, what = ("op", "clause") if isinstance(head, Op) else ("kind", "fact")
    if set(item) != {key, *fields}:
        raise ValueError(f"{what} {dict(item)}: {head.value} takes exactly {', '.join(fields) or 'no fields'}")
    return {name: item[name] for name in fields}


@dataclass(frozen=True)
class Clause:
    """One step of a Commander's program; `args` are its op's fields in CLAUSE_FIELDS' order."""

    op: Op
    args: tuple[Value, ...] = ()

    @classmethod
    def of(cls, op: Op, **fields: Value) -> Clause:
        clause = cls(op, tuple(fields[name] for name in CLAUSE_FIELDS[op]))
        return clause.canonical()

    def canonical(self) -> Clause:
        # A walk with neither a count nor a stop is carried out to the next wall: one meaning.
        if self.op == Op.FORWARD and self.args == (None, None):
            return Clause(Op.FORWARD, (None, "wall"))
        # Turning around is half a turn whichever way.
        if self.op == Op.TURN and self.args in ((-4,), (4,)):
            return Clause(Op.TURN, (4,))
        return self

    def to_json(self) -> dict[str, Value]:
        return {"op": self.op.value, **dict(zip(CLAUSE_FIELDS[self.op], self.args, strict=True))}

    @classmethod
    def from_json(cls, item: Mapping[str, Value]) -> Clause:
        op = Op(str(item["op"]))
        return cls.of(op, **_exactly(item, op, CLAUSE_FIELDS[op]))


@dataclass(frozen=True)
class FactForm:
    """One thing a Driver's turn states; `args` are its kind's fields in FACT_FIELDS' order."""

    kind: FactKind
    args: tuple[Value, ...] = ()

    @classmethod
    def of(cls, kind: FactKind, **fields: Value) -> FactForm:
        return cls(kind, tuple(fields[name] for name in FACT_FIELDS[kind]))

    def to_json(self) -> dict[str, Value]:
        return {"kind": self.kind.value, **dict(zip(FACT_FIELDS[self.kind], self.args, strict=True))}

    @classmethod
    def from_json(cls, item: Mapping[str, Value]) -> FactForm:
        kind = FactKind(str(item["kind"]))
        return cls.of(kind, **_exactly(item, kind, FACT_FIELDS[kind]))


Program = tuple[Clause, ...]


def _side(side: Side | None) -> str | None:
    return None if side is None else side.value


def _clause(instruction: ins.Instruction) -> Clause:
    match instruction:
        case ins.Turn(eighths):
            return Clause.of(Op.TURN, eighths=eighths)
        case ins.Forward(steps, until, _):
            return Clause.of(Op.FORWARD, steps=steps, until=None if until is None else until.word)
        case ins.TakeOpening(side, nth):
            return Clause.of(Op.OPENING, side=side.value, nth=nth)
        case ins.Target(label, None):
            return Clause.of(Op.TARGET, label=label.word)
        case ins.Target(label, side):
            return Clause.of(Op.EXPECT, label=label.word, side=_side(side))
        case ins.Ask(question, side, label, look_around):
            asked = "look_around" if look_around else _QUESTION[question]
            return Clause.of(Op.ASK, question=asked, side=_side(side), label=None if label is None else label.word)
        case ins.GoBack(place, _, _):
            return Clause.of(Op.BACK, place=place.value, steps=None)
        case ins.Stop(claim):
            return Clause.of(Op.STOP, claim=claim)
        case ins.Unclear():
            return Clause.of(Op.UNCLEAR)
    raise TypeError(f"not an instruction: {instruction!r}")


def program_of(parsed: ins.Parsed) -> Program:
    """The rules' reading of a Commander turn as a program."""
    return tuple(_clause(i) for i in parsed.instructions)


def _forms(fact: lexicon.Fact) -> list[FactForm]:
    sides = [_SECTOR_SIDE[s] for s in fact.sectors]
    match fact.kind:
        case lexicon.ViewKind.LABEL if fact.label is not None:
            return [
                FactForm.of(
                    FactKind.LABEL, label=fact.label.word, side=side, distance=fact.distance.value, negated=fact.negated
                )
                for side in sides
            ]
        case lexicon.ViewKind.EDGE:
            return [FactForm.of(FactKind.EDGE, side=side, negated=fact.negated) for side in sides]
        case lexicon.ViewKind.CORRIDOR if not fact.negated:
            return [FactForm.of(FactKind.CORRIDOR, side=side) for side in sides]
        case lexicon.ViewKind.CORNER if not fact.negated:
            return [FactForm.of(FactKind.CORNER, side=side) for side in sides]
        case lexicon.ViewKind.DEAD_END if not fact.negated:
            return [FactForm.of(FactKind.DEAD_END)]
        case lexicon.ViewKind.NEXT_TO if fact.label is not None and fact.other is not None and not fact.negated:
            first, second = sorted((fact.label.word, fact.other.word))
            return [FactForm.of(FactKind.NEXT_TO, label=first, other=second)]
    return []


def facts_of(text: str, question: str | None = None) -> frozenset[FactForm]:
    """The rules' reading of a Driver turn (the Commander agent's): its facts, resolved against the
    Commander's question it answers where there is one, and its yes / no and question acts."""
    asked = lexicon.question(question) if question is not None and lexicon.is_question(question) else None
    stated = lexicon.answer(asked, text) if asked is not None else lexicon.facts(text)
    out = {form for fact in stated for form in _forms(fact)}
    words = lexicon.tokens(text)
    if asked is not None and words and words[0] in lexicon.YES:
        out.add(FactForm.of(FactKind.ANSWER, value="yes"))
    if asked is not None and words and words[0] in lexicon.NO:
        out.add(FactForm.of(FactKind.ANSWER, value="no"))
    if lexicon.is_question(text):
        out.add(FactForm.of(FactKind.QUESTION))
    return frozenset(out)


@dataclass(frozen=True)
class Score:
    """Micro-averaged agreement of readings with the gold set over a number of turns."""

    turns: int
    exact: int  # turns read exactly
    matched: int  # clauses or facts in both
    predicted: int
    gold: int

    @property
    def exact_match(self) -> float:
        return self.exact / self.turns if self.turns else 0.0

    @property
    def f1(self) -> float:
        return 2 * self.matched / (self.predicted + self.gold) if self.predicted + self.gold else 1.0


def score_programs(pairs: Iterable[tuple[Sequence[Clause], Sequence[Clause]]]) -> Score:
    """(predicted, gold) programs: exact match in order, and clauses matched as multisets."""
    return _score((tuple(got), tuple(want)) for got, want in pairs)


def score_facts(pairs: Iterable[tuple[frozenset[FactForm], frozenset[FactForm]]]) -> Score:
    """(predicted, gold) fact sets."""
    return _score(pairs)


def _score(pairs: Iterable[tuple[Collection[Clause | FactForm], Collection[Clause | FactForm]]]) -> Score:
    """Equal readings are exact (a program's order counts, a fact set's cannot); items match as multisets."""
    turns = exact = matched = predicted = gold = 0
    for got, want in pairs:
        turns += 1
        exact += got == want
        matched += sum((Counter(got) & Counter(want)).values())
        predicted += len(got)
        gold += len(want)
    return Score(turns, exact, matched, predicted, gold)
