"""How the agents understand the other seat: the trained reader, and what its readings ask of them.

The Driver agent reads a Commander turn as a program (`program`) and carries it out through the
rules' instructions (`instructions`), the executor it always had; the Commander agent reads a
Driver turn as facts (`facts`) and weighs them in its belief through the lexicon's facts
(`belief_facts`). The Driver reads with the trained reader (`sim.language.reader`) by default, the
Commander by the rules (docs/model_card_language.md says why). `read_back` says a program in a few words, so an
agent can tell a person what it understood before acting on it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Generic, TypeVar

from sim.core.labels import OBJECT_LABELS, Label
from sim.language import instructions as ins
from sim.language import lexicon
from sim.language.meaning import CLAUSE_FIELDS, FACT_FIELDS, FactForm, FactKind, Op, Program, facts_of, program_of
from sim.language.reader import Reader, Role, shipped
from sim.language.sectors import Sector
from sim.language.vocab import SIDE_SECTOR, Side, wall_name

M = TypeVar("M", Program, frozenset[FactForm])


@dataclass(frozen=True)
class Understood(Generic[M]):
    meaning: M
    confidence: float
    by_rules: bool  # read by the rules (no reader for this seat's words)
    strange_lead: bool = False  # the reader never met the turn's first word


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
            return Understood(program_of(ins.parse(text)), 1.0, True)
        reading = self.commander_reader.read(text, before)
        assert isinstance(reading.meaning, tuple)  # a Commander reader writes programs
        return Understood(reading.meaning, reading.confidence, False, reading.strange_lead)

    def facts(
        self, text: str, before: tuple[str, str] | None = None, asked: str | None = None
    ) -> Understood[frozenset[FactForm]]:
        """A Driver turn; `asked` the Commander's question it answers, for the rules."""
        if self.driver_reader is None:
            return Understood(facts_of(text, asked), 1.0, True)
        reading = self.driver_reader.read(text, before)
        assert isinstance(reading.meaning, frozenset)  # a Driver reader writes facts
        return Understood(_joined(reading.meaning, facts_of(text, asked)), reading.confidence, False)


VIEW_KINDS = frozenset(
    {FactKind.LABEL, FactKind.EDGE, FactKind.CORRIDOR, FactKind.CORNER, FactKind.DEAD_END, FactKind.NEXT_TO}
)


def _joined(read: frozenset[FactForm], ruled: frozenset[FactForm]) -> frozenset[FactForm]:
    """A Driver turn's dialog acts (answers, questions, claims) as the reader reads them, its view as
    the rules do where they make anything of it: they bind each colour to the direction written
    with it, where the reader learnt which colours go with which directions and now and then
    swaps them ("white to my left, red to my right" read the other way round)."""
    view = frozenset(f for f in ruled if f.kind in VIEW_KINDS) or frozenset(f for f in read if f.kind in VIEW_KINDS)
    return frozenset(f for f in read if f.kind not in VIEW_KINDS) | view


def _label(word: object) -> Label | None:
    return Label[str(word).upper()] if isinstance(word, str) and word.upper() in Label.__members__ else None


def _side(word: object) -> Side | None:
    return Side(word) if isinstance(word, str) and word in ("ahead", "left", "right", "behind") else None


_QUESTION = {"view": ins.AskedAbout.VIEW, "side": ins.AskedAbout.SIDE, "is_there": ins.AskedAbout.IS_THERE}


def instructions(program: Program, text: str) -> list[ins.Instruction]:
    """What the Driver's executor carries out for a program (clauses with nothing to do drop out)."""
    out: list[ins.Instruction] = []
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
            case Op.BACK:  # the way it came: turn around and walk
                steps = args["steps"]
                out += [ins.Turn(4), ins.Forward(steps if isinstance(steps, int) else None)]
            case Op.TARGET:
                label = _label(args["label"])
                if label is not None:
                    out.append(ins.Target(label))
            case Op.EXPECT:
                label = _label(args["label"])
                if label in OBJECT_LABELS:
                    out.append(ins.Target(label, _side(args["side"])))
            case Op.ASK:
                question = str(args["question"])
                out.append(
                    ins.Ask(
                        _QUESTION.get(question, ins.AskedAbout.VIEW),
                        _side(args["side"]),
                        _label(args["label"]),
                        # Looking all around is eight scored moves: only when the words ask for it.
                        look_around=question == "look_around" and ins.asks_to_look(text),
                    )
                )
            case Op.STOP:
                out.append(ins.Stop(claim=bool(args["claim"])))
            case Op.UNCLEAR:
                out.append(ins.Unclear(text))
    return out


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


def read_back(program: Program) -> str:
    """A program in a few words ("turning around, then forward to the yellow wall")."""
    parts: list[str] = []
    for clause in program:
        args = dict(zip(CLAUSE_FIELDS[clause.op], clause.args, strict=True))
        match clause.op:
            case Op.TURN:
                e = int(args["eighths"] or 0)
                size = {1: "slightly ", 2: "", 3: "sharply "}.get(abs(e), "")
                parts.append("turning around" if abs(e) == 4 else f"turning {size}{'left' if e > 0 else 'right'}")
            case Op.FORWARD:
                until, steps = args["until"], args["steps"]
                if isinstance(steps, int):
                    parts.append(f"forward {steps} steps")
                elif until in (None, "wall"):
                    parts.append("forward to the wall")
                else:
                    label = _label(until)
                    parts.append(f"forward to the {wall_name(label) if label is not None else until}")
            case Op.FOLLOW:
                parts.append(f"along the {args['label']} walls")
            case Op.OPENING:
                parts.append(f"into opening {args['nth']} on the {args['side']}")
            case Op.BACK:
                parts.append("back where i started" if args["place"] == "start" else "back the way i came")
            case Op.STOP:
                parts.append("claiming" if args["claim"] else "stopping")
    return ", then ".join(parts)
