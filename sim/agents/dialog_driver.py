"""A Driver that takes part in the dialog, from percepts alone: it describes what it sees, answers,
waits for instructions, carries them out, says when it is done or lost, and claims.

All rules, no learned part (see docs/model_card_dialog_driver.md). It never has a pose, a map or a
graph: its inputs are the chat, its frames' rays and its moves' outcomes. Its own odometry (grid
steps and 45-degree headings relative to where it started, from its moves' results) serves the
dialog's history ("go back to where you started") and tells it which views it has looked at from
where it stands. One instruction set runs at a time; a new Commander message replaces what is left
of the last one, as a person drops an old plan when told something new. What it says is decided
here as typed facts and worded by its `DriverPhrasing` (`sim.language.driver_phrasing`): the
scripted Driver's words by default, or a frozen Driver persona's, slips and all."""

from __future__ import annotations

import math
import re
from collections import deque
from dataclasses import dataclass, field, replace
from enum import StrEnum

import numpy as np

from sim.core.geometry import HEADING_DI, HEADING_DJ, HEADINGS
from sim.core.labels import OBJECT_LABELS, Label
from sim.core.rays import RayObservation
from sim.language import instructions as ins
from sim.language import lexicon
from sim.language.describe import CENTRE_RAYS, LEFT_EDGE, RIGHT_EDGE, ahead, at_wall, near, seen
from sim.language.driver_phrasing import (
    Answered,
    Claiming,
    Described,
    Done,
    DriverPhrasing,
    Fact,
    Measured,
    NotHere,
    ReadBack,
    ScriptedDriverPhrasing,
    Stopped,
    Stuck,
    Trouble,
    Troubled,
    Why,
)
from sim.language.meaning import Clause, Op, Program, program_of
from sim.language.understanding import (
    MOVING_OPS,
    Understanding,
    instructions,
    read_back,
    turn_words,
    turns_missed,
    unread_counts,
    with_count,
)
from sim.language.vocab import SIDE_STEPS, Side, wall_name
from sim.trial.agent import SeatInfo
from sim.trial.commands import Action, Claim, RequestMove, Say, named
from sim.trial.percepts import Declined, Heard, Judged, Moved, PauseSet, Percept, PhaseBegan, Saw
from sim.trial.vocabulary import Move, Outcome, Phase, Role

OPENING_M = 0.6  # a side ray further than this after a nearer one: an opening on that side
MAX_WALK = 60  # forward moves one "until" may take before the Driver asks
# The reader this unsure of a message: say its best reading and ask before acting (on val_seen's
# gold turns 7 of 206 fall below, and the reader had 1 of those 7 right; 70 % of the rest).
ASK_BELOW = 0.8
READ_BACK_CLAUSES = 2  # with read-back on, a plan of this many moving clauses is said before it is done
FAILED_TRIES = 2  # instructions in a row it could not carry out: ask for one move at a time
_YES = Clause.of(Op.ANSWER, value="yes")
_NO = Clause.of(Op.ANSWER, value="no")
_CLAIM = Clause.of(Op.STOP, claim=True)
_UNCLEAR = Clause.of(Op.UNCLEAR)
_HOLD = Clause.of(Op.STOP, claim=False)
# The "no" a correction opens with ("no, right"): the lexicon's no-words, "nooo" and a bare "n".
_NO_WORD = re.compile(rf"^\W*(?:no+|n|{'|'.join(sorted(lexicon.NO))})\b\W*", re.IGNORECASE)


# Words that name a new thing to find ("now find the mug", "i meant the jar"): only these change the
# target in the middle of a leg ("next to the jar" places the robot).
_NEW_TARGET = re.compile(
    r"\b(?:find|look(?:ing)? for|search|next (?:one|target|objective|goal|thing|object)|target|objective|goal"
    r"|instead|i mean|meant)\b",
    re.I,
)
_STRAIGHT_ON = re.compile(r"\b(?:until|till|til|straight|forward)\b", re.I)
_AGREE = lexicon.YES - {"right"}  # "right" after "turning left?" may be the other way
# A message that only agrees ("Yes, that is right.", "that is the right way"): no turn, no claim.
_AGREEMENT = re.compile(
    rf"^\W*(?:(?:{'|'.join(sorted(_AGREE))}|ok|okay|good|great|exactly)\W+)*"
    r"(?:(?:that|this|it)\W*(?:is|s|was)?\W*(?:the\W+)?right(?:\W+(?:way|one|direction|path|spot))?|correct|exactly)\W*$",
    re.I,
)


def _answer(program: Program, text: str) -> Clause | None:
    """A yes or no to its question: as the reader reads it, or a turn that moves nothing and opens
    with a yes or no word the reader never met ("yep", "sure", "nope")."""
    if program in ((_YES,), (_NO,)):
        return program[0]
    words = lexicon.tokens(text)
    if not words or _moves(program):
        return None
    return _YES if words[0] in _AGREE else _NO if words[0] in lexicon.NO else None


# A clause that asks something of the view ("then tell me what you see", "what's on your left?"),
# where "could you ...?" only asks politely.
_ASKS = re.compile(r"\b(?:what|whats|where|which|how|describe|tell me|see|any|is there|are there)\b")


def _asked_in(text: str) -> Program:
    """The questions of a message's clauses, each read alone: the message's moves do not make
    its side or its look all around ("turn around and tell me what you see")."""
    return tuple(
        clause
        for part in ins.clauses(text)
        if _ASKS.search(part)
        for clause in program_of(ins.parse(part))
        if clause.op == Op.ASK
    )


def _sees(view: RayObservation | None, label: Label) -> bool:
    return view is not None and any(s.label == label for s in seen(view))


def _moves(program: Program) -> int:
    """How many of a program's clauses move the robot."""
    return sum(c.op in MOVING_OPS for c in program)


class Task(StrEnum):
    TURN = "turn"
    WALK = "walk"  # forward some steps, or until a wall / the target
    OPENING = "opening"  # forward to the nth opening on a side, then turn into it
    GOTO = "goto"  # back to a place of its odometry
    LOOK = "look"  # turn in place to see what a question needs, then answer
    SEEK = "seek"  # turn in place until the named target is in view, then go up to it
    SAY = "say"
    CLAIM = "claim"


MOVING = (Task.WALK, Task.OPENING, Task.GOTO)  # tasks that leave the spot: not while localizing


@dataclass
class _Task:
    """One step of the current instruction set; `turns` / `steps` count what is left of it."""

    kind: Task
    turns: int = 0
    steps: int | None = None
    until: Label | None = None  # WALK, SEEK: what to go up to; TURN: what to turn until it is in view
    facing: bool = False  # TURN until: until it is ahead
    exclude: frozenset[Label] = frozenset()
    side: Side | None = None
    nth: int = 0
    route: list[tuple[int, int]] = field(default_factory=list)  # GOTO: places still to pass, in order
    text: str = ""
    question: ins.Ask | None = None
    done: int = 0
    edge_near: bool = False  # OPENING: the side ray met a wall at the last step
    home: int | None = None  # LOOK: the heading to answer from
    missed: tuple[str, str] | None = None  # SAY the report: words it did not get, and its best reading


@dataclass
class _Odometry:
    i: int = 0
    j: int = 0
    heading: int = 0  # 45-degree steps counter-clockwise from the start heading
    trail: list[tuple[int, int]] = field(default_factory=lambda: [(0, 0)])  # every place it stood, in order
    turns: list[tuple[Side, int]] = field(default_factory=list)  # which way it turned, at which trail index

    @property
    def here(self) -> tuple[int, int]:
        return (self.i, self.j)

    def route_back(self, index: int) -> list[tuple[int, int]]:
        """The way back to `trail[index]` along the trail, loops cut: the way it came is free."""
        route: list[tuple[int, int]] = []
        for place in reversed(self.trail[index:]):
            if place in route:
                del route[route.index(place) + 1 :]
            else:
                route.append(place)
        return route[1:]


class DialogDriver:
    """The Driver's seat agent (`sim.agents.turns.Agent`); deterministic given `seed`."""

    def __init__(
        self,
        seed: int = 0,
        read_back: bool = False,
        understanding: Understanding | None = None,
        phrasing: DriverPhrasing | None = None,
    ) -> None:
        """`read_back`: say a long plan in short before carrying it out (for a person's benefit);
        `understanding`: how it reads the Commander (the shipped readers by default); `phrasing`:
        how it words what it says (the scripted Driver's words by default)."""
        self._phrasing = phrasing or ScriptedDriverPhrasing(seed)
        self._read_back = read_back
        self._understanding = understanding or Understanding.trained()
        self.reset(SeatInfo(Role.DRIVER, 0))

    def reset(self, info: SeatInfo) -> None:
        self._phase = Phase.WAITING
        self._odo = _Odometry()
        self._views: dict[int, RayObservation | None] = {}  # heading -> view, from where it stands
        self._view: RayObservation | None = None
        self._seen = False
        self._plan: deque[_Task] = deque()
        self._moving = False  # a move is out; wait for its outcome and frame
        self._target: Label | None = None
        self._claimed: Label | None = None  # what its claim out names
        self._found: set[Label] = set()  # targets confirmed: none is sought or claimed again
        self._claiming = False
        self._paused = False
        self._claim_on_resume = False  # its claim was refused while paused: claim again once it runs
        self._rejected_at: set[tuple[int, int]] = set()
        self._done_words = ""
        self._before: tuple[str, str] | None = None  # the dialog's last message, for the reader
        self._offered: tuple[Program, str] | None = None  # a reading it asked about, and its message
        self._failed = 0  # instructions in a row it could not carry out
        self._walked = 0  # forward moves since the last instruction
        self._turned = 0  # eighths turned by turn tasks since it last moved forward, for its report
        self._not_found: Label | None = None  # the target it last looked all around for in vain
        self.refused_for_walls = 0  # walks it stopped short of what it was told, a wall in its way

    def _say(self, fact: Fact) -> Say:
        return Say(self._phrasing.say(fact))

    # -- percepts -------------------------------------------------------------------------------

    def perceive(self, percept: Percept) -> list[Action]:
        actions = self._perceive(percept)
        said = [a.text for a in actions if isinstance(a, Say)]
        if said:
            self._before = ("d", said[-1])  # what a "yes" after its question is read with
        return actions

    def _perceive(self, percept: Percept) -> list[Action]:
        if isinstance(percept, PhaseBegan):
            if percept.phase == Phase.NAVIGATING and self._phase == Phase.NAVIGATING:
                self._target = None  # a confirmed target: the next one is told anew
            self._phase = percept.phase
            return []
        if isinstance(percept, Heard):
            turns = self._heard(percept.text) if percept.speaker == Role.COMMANDER else []
            self._before = ("c" if percept.speaker == Role.COMMANDER else "d", percept.text)
            return turns
        if isinstance(percept, Moved):
            return self._moved(percept)
        if isinstance(percept, Saw):
            self._view, self._seen = percept.rays, True
            self._views[self._odo.heading] = percept.rays
            self._moving = False
            return self._advance()
        if isinstance(percept, Judged):
            self._claiming = False
            if percept.confirmed:
                if self._claimed is not None:
                    self._found.add(self._claimed)
                return []
            self._rejected_at.add(self._odo.here)
            return [self._say(NotHere())]
        if isinstance(percept, PauseSet):
            self._paused = percept.paused
            if percept.paused or not self._claim_on_resume:
                return []
            self._claim_on_resume = False
            self._plan.appendleft(_Task(Task.CLAIM))
            return self._advance()
        if isinstance(percept, Declined):
            return self._refused(percept)
        return []  # Claimed: its own claim, already waiting for the verdict

    def _refused(self, refused: Declined) -> list[Action]:
        """A turn not allowed now: a claim refused while paused is made again once the trial runs;
        otherwise it drops its plan and asks (its words refused: nothing to say)."""
        if isinstance(refused.action, Say):
            return []
        self._claiming = self._moving = False
        self._plan.clear()
        if isinstance(refused.action, Claim) and self._paused:
            self._claim_on_resume = True
            return []
        return [self._say(Troubled(Trouble.REFUSED, quoted=named(refused.action), detail=refused.reason))]

    def _moved(self, moved: Moved) -> list[Action]:
        if moved.result != Outcome.OK:
            self._plan.clear()
            if moved.result == Outcome.COLLISION:
                return [self._failure(Stuck(Why.COLLISION, self._walked, self._view))]
            return [self._say(Troubled(Trouble.NOT_MOVED, detail=moved.reason or ""))]
        if moved.move == Move.FORWARD:
            self._odo.i += int(HEADING_DI[self._odo.heading])
            self._odo.j += int(HEADING_DJ[self._odo.heading])
            self._odo.trail.append(self._odo.here)
            self._walked += 1
            self._turned = 0
            self._views = {}
        else:
            self._odo.heading = (self._odo.heading + (1 if moved.move == Move.LEFT else -1)) % HEADINGS
        return []

    # -- instructions -> tasks ------------------------------------------------------------------

    def _heard(self, text: str) -> list[Action]:
        understood = self._understanding.program(text, self._before)
        program, offered, self._offered = understood.meaning, self._offered, None
        answer = _answer(program, text) if offered is not None else None
        if offered is not None and answer == _YES:
            program, text = offered  # "yes": the reading it asked about
        elif offered is not None and answer == _NO:
            self._plan.clear()
            # "no, right": the correction after the "no", where the rules hear a move in it.
            correction = program_of(ins.parse(_NO_WORD.sub("", text, count=1)))
            if _moves(correction) or _CLAIM in correction:  # "no. you are at the paddle. claim it"
                return self._follow(correction, text, said_unclear=False)
            return [self._say(Troubled(Trouble.NOT_MEANT))]
        elif self._phase == Phase.NAVIGATING and _AGREEMENT.match(text.strip()):
            # "Yes, that is right.", "that is the right way": agreement, not a turn nor a claim (the
            # reader read one or the other, and a person's agent turned 90 or 135 degrees).
            return []
        elif self._phase == Phase.LOCALIZING and not any(c.op == Op.ASK for c in program):
            # While it is being found, what it is asked to describe is what matters: a question the
            # rules hear and the reader did not is answered ("Hello there! ... Could you please tell
            # me what you can see in front of you? And maybe turn around slowly and tell me ..." was
            # answered about a yellow wall nobody named).
            rules = program_of(ins.parse(understood.read))
            if any(c.op == Op.TURN for c in program) and any(c.op == Op.ASK for c in rules):
                # "please turn to your left a quarter turn and tell me what is in front of you": the
                # turn, then the view from there (the rules' reading, a question about its left
                # alone, had it stay put and describe the same view again)
                program = (*program, Clause.of(Op.ASK, question="view", side=None, label=None))
            elif any(c.op == Op.ASK for c in rules):
                program = rules
        elif self._phase == Phase.NAVIGATING:
            # The rules' reading, of what the reader reads: a second opinion, read once.
            rules = program_of(ins.parse(understood.read))
            unsure = understood.confidence < ASK_BELOW or understood.ambiguous
            at_one = self._view is not None and any(near(self._view, label) for label in OBJECT_LABELS)
            if (
                _CLAIM in rules
                and not _moves(rules)
                and (unsure or not _moves(program) or at_one)
                and _CLAIM not in program
            ):
                # The rules hear "you are right by it": a claim costs no move and is judged, so it
                # claims rather than offer the reader's guess ("turning right?") or do nothing (the
                # reader heard "got it, you found it, ..." as what it should see).
                return self._follow(rules, text, said_unclear=False)
            if not _moves(rules) and any(c.op == Op.ASK for c in rules) and _moves(program):
                if not unsure:
                    # The rules hear a whole message as a question where it has one in it, or is a
                    # polite request ("could you turn around and go to the red wall?", "turn left,
                    # 3 steps, then tell me what you see"): the moves the reader is sure of, then
                    # the questions its clauses ask, answered from where the moves end (a person's
                    # polite messages got "do you mean: ...?" one time in three, and "turn around
                    # and tell me what you see" a look all around).
                    program += tuple(c for c in _asked_in(text) if c not in program)
                else:
                    # A question the reader read moves into, unsure: answered, with no move it was
                    # not asked for, and the reader's moves asked about.
                    answered = self._follow(rules, text, said_unclear=False)
                    if self._plan or self._moving:  # it turns to look first: the walk is left unsaid
                        return answered
                    return answered + self._ask(program, text, quoted=text.strip())
            if not program and rules == (_UNCLEAR,):
                program = rules  # words the reader read nothing in and the rules find no chat in ("say found")
            if program == (_HOLD,) and not rules:
                program = rules  # chat the reader read as "stop" ("thanks"): nothing to answer "ok, stopped" to
            # A guess where the rules make nothing of a turn led by a word the reader never met
            # ("pirouette till the wall ...").
            guessed = _moves(program) and understood.strange_lead and all(c.op == Op.UNCLEAR for c in rules)
            if unsure or guessed or not _moves(program) and _moves(rules):
                return self._ask_about(program, rules, text)  # or the rules hear moves the reader did not
            if turns_missed(program, rules):  # or a turn it did not: its reading clause by clause, asked about
                return self._ask_about(self._understanding.mended(text), rules, text)
        unclear = [c for c in program if c.op == Op.UNCLEAR]
        if unclear and len(unclear) < len(program):
            program = tuple(c for c in program if c.op != Op.UNCLEAR)  # act on what it understood
        unread = unread_counts(program, text) if _moves(program) and self._phase == Phase.NAVIGATING else []
        if unread:
            # A count its reading left unused ("left 3" read as a turn): where it comes after all
            # it understood, it does that and then asks; before, it asks first (a walk done after
            # the turn it belonged before would go elsewhere).
            offer, after = with_count(program, text, unread[0])
            if not after:
                return self._ask(offer, text, quoted=unread[0].said)
            return self._follow(program, text, said_unclear=bool(unclear), unread=(unread[0].said, offer[-1:]))
        return self._follow(program, text, said_unclear=bool(unclear))

    def _ask_about(self, program: Program, rules: Program, text: str) -> list[Action]:
        """Not sure what was meant: say its best reading (the rules' where it read no move) and ask."""
        best = program if _moves(program) else rules
        if not _moves(best):
            # No move at stake: the reader's reading, or the rules' where the reader read nothing or
            # nothing it understood ("Hello. What do you see in front of you?" was "not understood").
            lost = all(c.op == Op.UNCLEAR for c in program)
            return self._follow(rules if lost and rules else program or best, text, said_unclear=False)
        unread = unread_counts(best, text)
        if unread:
            best, _ = with_count(best, text, unread[0])
        return self._ask(best, text, quoted=text.strip())

    def _ask(self, reading: Program, text: str, quoted: str) -> list[Action]:
        """Say its best reading of the words it did not get (`quoted`, of the message `text`) and
        ask; a "yes" carries the reading out."""
        self._plan.clear()
        self._offered = (reading, text)
        return [self._say(Troubled(Trouble.ASK_ABOUT, quoted=quoted, detail=read_back(instructions(reading, text))))]

    def _failure(self, stuck: Stuck) -> Say:
        """It could not carry out what it was told: it drops the plan; after FAILED_TRIES in a row it asks for less."""
        self._plan.clear()
        self._failed += 1
        self.refused_for_walls += stuck.why in (Why.CANNOT_GO, Why.IN_THE_WAY)
        return self._say(replace(stuck, one_at_a_time=self._failed >= FAILED_TRIES))

    def _follow(
        self, program: Program, text: str, said_unclear: bool, unread: tuple[str, Program] | None = None
    ) -> list[Action]:
        """Plan and start what it understood; `unread`: words it did not get and its reading of
        them, asked about once it has done the rest."""
        parsed = ins.Parsed(tuple(instructions(program, text)))
        self._plan.clear()
        self._claim_on_resume = False
        self._walked = self._turned = 0
        tasks: list[_Task] = []
        for item in parsed.instructions:
            tasks += self._tasks(item, text)
        if parsed.unclear:
            tasks = [_Task(Task.SAY, text=self._phrasing.say(Troubled(Trouble.UNCLEAR, quoted=text.strip())))]
        elif said_unclear and tasks:
            tasks.append(_Task(Task.SAY, text=self._phrasing.say(Troubled(Trouble.PARTLY))))
        moving = [i for i in parsed.instructions if isinstance(i, ins.MOVING)]
        if self._read_back and len(moving) >= READ_BACK_CLAUSES and self._phase == Phase.NAVIGATING:
            tasks.insert(0, _Task(Task.SAY, text=self._phrasing.say(ReadBack(read_back(parsed.instructions)))))
        if self._phase == Phase.LOCALIZING and any(t.kind in MOVING for t in tasks):
            tasks = [t for t in tasks if t.kind not in MOVING]
            tasks.append(_Task(Task.SAY, text=self._phrasing.say(Troubled(Trouble.STAYING))))
        sought = next((i.label for i in parsed.instructions if isinstance(i, ins.Target) and i.side is None), None)
        if not tasks and sought is not None and self._phase == Phase.NAVIGATING:
            # Told it is at the target, or to go to it, with the target out of view: a person looks
            # around for it rather than claim blind or say nothing; told so again after looking in
            # vain, it trusts the map over its camera and claims.
            tasks = [_Task(Task.CLAIM if sought == self._not_found else Task.SEEK, until=sought)]
        self._not_found = None
        missed = None
        if unread is not None and tasks:
            said, offer = unread
            self._offered = (offer, said)  # a "yes" carries it out
            missed = (said, read_back(instructions(offer, said)))
        if tasks and (tasks[-1].kind not in (Task.SAY, Task.CLAIM, Task.LOOK) or missed is not None):
            tasks.append(_Task(Task.SAY, missed=missed))  # the report when the moves are done
        self._plan.extend(tasks)
        self._done_words = ""
        return [] if self._moving else self._advance()

    def _tasks(self, item: ins.Instruction, text: str) -> list[_Task]:
        if isinstance(item, ins.Turn):
            if item.until is not None:  # on until it is in view; all the way round at most
                turns = (HEADINGS - 1) * (1 if item.eighths > 0 else -1)
                return [_Task(Task.TURN, turns=turns, until=item.until, facing=item.facing)]
            return [_Task(Task.TURN, turns=item.eighths)]
        if isinstance(item, ins.Forward):
            steps = self._phrasing.count(item.steps) if item.steps is not None else None
            walk = _Task(Task.WALK, steps=steps, until=item.until, exclude=item.exclude)
            # "go to the paddle" heads for it; "go forward until you see the jar" walks on straight.
            heads = steps is None and not _STRAIGHT_ON.search(text)
            return [*self._toward(item.until), walk] if heads else [walk]
        if isinstance(item, ins.TakeOpening):
            return [_Task(Task.OPENING, side=item.side, nth=item.nth)]
        if isinstance(item, ins.Target):
            found = item.label in self._found  # "great, that's the jar!" after its confirmation: not again
            if found or self._target not in (None, item.label) and not _NEW_TARGET.search(text):
                # Another object than this leg's target, named but not to find, places the robot ("i
                # think you are facing the red wall near the mug", "you are next to the jar"): said
                # whether it is seen, and nothing more (a person's words made the agent look all
                # around for the mug, and claim the jar when the mug was next).
                return [_Task(Task.LOOK, question=ins.Ask(ins.AskedAbout.IS_THERE, item.side, item.label))]
            self._target = item.label
            if item.side is None:
                # Told what to find: where it is in view, go up to it.
                visible = _sees(self._view, item.label)
                if not visible or self._phase != Phase.NAVIGATING:
                    return []
                return [*self._toward(item.label), _Task(Task.WALK, until=item.label)]
            return [_Task(Task.TURN, turns=SIDE_STEPS[item.side] if item.side != Side.RIGHT else -2)] + [
                _Task(Task.WALK, until=item.label)
            ]
        if isinstance(item, ins.Ask):
            return [_Task(Task.LOOK, question=item)]
        if isinstance(item, ins.GoBack):
            return [self._go_back(item)]
        if isinstance(item, ins.Stop):
            if item.claim:
                return [_Task(Task.CLAIM)]
            return [_Task(Task.SAY, text=self._phrasing.say(Stopped(self._view)))]
        return []

    def _go_back(self, item: ins.GoBack) -> _Task:
        if item.place == ins.Place.START:
            return _Task(Task.GOTO, route=self._odo.route_back(0), text="back where i started")
        turns = [index for side, index in self._odo.turns if item.side is None or side == item.side]
        if len(turns) < item.nth:
            return _Task(Task.SAY, text=self._phrasing.say(Troubled(Trouble.NOT_TURNED, side=item.side)))
        return _Task(Task.GOTO, route=self._odo.route_back(turns[item.nth - 1]), text="back where i turned")

    # -- carrying tasks out ---------------------------------------------------------------------

    def _advance(self) -> list[Action]:
        out: list[Action] = []
        while self._plan and not self._moving and not self._claiming:
            if self._sees_target() and self._plan[0].kind != Task.CLAIM:
                self._plan.clear()
                self._plan.append(_Task(Task.CLAIM))
            if self._plan[0].kind == Task.LOOK and self._odo.heading not in self._views:
                break  # no frame yet from where it stands (a rover's first): it answers once one comes
            if self._plan[0].kind == Task.CLAIM and not self._seen:
                break  # a claim sends the Driver's frame: none yet
            task = self._plan.popleft()
            step = self._step(task)  # may clear the plan or put tasks before what is left
            if isinstance(step, RequestMove):
                self._plan.appendleft(task)
                self._moving = True
                out.append(step)
                break
            if step is not None:
                out += step if isinstance(step, list) else [step]
        return out

    def _sees_target(self) -> bool:
        if self._target is None or self._phase != Phase.NAVIGATING or self._view is None:
            return False
        if self._odo.here in self._rejected_at:
            return False
        return near(self._view, self._target)

    def _step(self, task: _Task) -> RequestMove | Say | list[Action] | None:
        """The task's next move, or None (or its closing words) when it is finished."""
        if task.kind == Task.TURN:
            return self._turn(task)
        if task.kind == Task.WALK:
            return self._walk(task)
        if task.kind == Task.OPENING:
            return self._opening(task)
        if task.kind == Task.GOTO:
            return self._goto(task)
        if task.kind == Task.LOOK:
            return self._look(task)
        if task.kind == Task.SEEK:
            return self._seek(task)
        if task.kind == Task.CLAIM:
            if self._phase != Phase.NAVIGATING:
                return self._say(Troubled(Trouble.NOT_PLACED))
            self._claiming, self._claimed = True, self._target
            return [self._say(Claiming(self._target)), Claim()]
        if not task.text:
            self._failed = 0  # an instruction set carried out to its end
            unread, offer = task.missed or ("", "")
            return self._say(Done(self._done_words, self._view, unread, offer))
        return Say(task.text)

    def _turn(self, task: _Task) -> RequestMove | Say | None:
        if task.until is not None and self._turned_to(task.until, task.facing):
            if task.until not in OBJECT_LABELS:  # its report names the objects in view, not every wall
                self._done_words = ", ".join(filter(None, [self._done_words, f"i see the {wall_name(task.until)}"]))
            return None
        if task.turns == 0:
            if task.until is not None:
                return self._failure(Stuck(Why.NOWHERE, 0, self._view, wanted=task.until))
            return None
        if task.done == 0 and abs(task.turns) >= 2:
            self._odo.turns.append((Side.LEFT if task.turns > 0 else Side.RIGHT, len(self._odo.trail) - 1))
        task.done += 1
        step = 1 if task.turns > 0 else -1
        task.turns -= step
        self._turned += step
        self._done_words = f"turned {turn_words(self._turned)}" if self._turned else ""
        return RequestMove(Move.LEFT if step > 0 else Move.RIGHT)

    def _toward(self, label: Label | None) -> list[_Task]:
        """Where an object to walk up to is in view off to one side: the turn that brings it to the
        middle of the view first (told "go to the paddle" with it at the edge of its view, it walked
        straight on into the wall beside it)."""
        view = self._view
        if label not in OBJECT_LABELS or view is None:
            return []
        rays = np.flatnonzero(view.valid & (view.labels == label))
        if not rays.size or self._turned_to(label, facing=True):
            return []
        way = 1 if rays.mean() > (LEFT_EDGE + RIGHT_EDGE) / 2 else -1  # ray 0 is on the right
        return [_Task(Task.TURN, turns=(HEADINGS - 1) * way, until=label, facing=True)]

    def _turned_to(self, label: Label, facing: bool) -> bool:
        """Whether a turn that goes on until `label` is in view (where `facing`: in the middle of
        the view) has come to it."""
        view = self._view
        if view is None or not facing:
            return _sees(self._view, label)
        return bool((view.valid[CENTRE_RAYS] & (view.labels[CENTRE_RAYS] == label)).any())

    def _walk(self, task: _Task) -> RequestMove | Say | None:
        view = self._view
        if task.steps is not None:
            if task.done >= task.steps:
                self._done_words = f"went {task.done} steps"
                return None
            if view is not None and view.forward_blocked:
                return self._failure(Stuck(Why.CANNOT_GO, task.done, view))
            task.done += 1
            return RequestMove(Move.FORWARD)
        if view is None or view.problem is not None:
            self._plan.clear()
            return self._say(Troubled(Trouble.BLIND))
        front = ahead(view)
        if task.until is not None and task.until in OBJECT_LABELS:
            # Where its claim was rejected it is not close enough yet: it goes on up to the target.
            close = near(view, task.until) and self._odo.here not in self._rejected_at
            reached = close or view.forward_blocked
        else:
            close, reached = False, at_wall(view)
        if reached:
            label = front.label if front is not None else None
            # Stopped by a wall short of the thing it was sent to: not done ("ok, at the white wall"
            # with no step made, when told it was next to the jar).
            if task.until is not None and label != task.until and (task.until not in OBJECT_LABELS or not close):
                return self._failure(Stuck(Why.WRONG_WALL, self._walked, view, found=label, wanted=task.until))
            if label is not None and label in task.exclude:
                return self._failure(Stuck(Why.EXCLUDED, self._walked, view, found=label))
            if close and task.until is not None:  # up to the thing itself, or there already
                self._done_words = f"{'' if task.done else 'already '}at the {wall_name(task.until)}"
            else:
                self._done_words = f"at the {wall_name(label)}" if label is not None else "at the wall"
            return None
        wall = task.until if task.until not in OBJECT_LABELS else None
        if task.done == 0 and wall is not None and not any(s.label == wall for s in seen(view)):
            return self._failure(Stuck(Why.NOT_IN_VIEW, self._walked, view, wanted=wall))
        if task.done >= MAX_WALK:
            return self._failure(Stuck(Why.TOO_FAR, task.done, view))
        task.done += 1
        return RequestMove(Move.FORWARD)

    def _opening(self, task: _Task) -> RequestMove | Say | None:
        view = self._view
        if view is None or view.problem is not None:
            self._plan.clear()
            return self._say(Troubled(Trouble.BLIND))
        ray = LEFT_EDGE if task.side == Side.LEFT else RIGHT_EDGE
        far = not view.valid[ray] or view.labels[ray] == Label.FLOOR or float(view.depth[ray]) > OPENING_M
        if task.edge_near and far:
            task.nth -= 1
        task.edge_near = not far
        if task.nth <= 0:
            self._plan.extendleft(
                [_Task(Task.WALK, steps=1), _Task(Task.TURN, turns=2 if task.side == Side.LEFT else -2)]
            )
            return None
        if view.forward_blocked or task.done >= MAX_WALK:
            return self._failure(Stuck(Why.NO_OPENING, self._walked, view, side=task.side))
        task.done += 1
        return RequestMove(Move.FORWARD)

    def _goto(self, task: _Task) -> RequestMove | Say | None:
        while task.route and task.route[0] == self._odo.here:
            task.route.pop(0)
        if not task.route:
            self._done_words = task.text
            return None
        di, dj = task.route[0][0] - self._odo.i, task.route[0][1] - self._odo.j
        wanted = round(math.atan2(dj, di) / (math.pi / 4)) % HEADINGS
        turn = (wanted - self._odo.heading) % HEADINGS
        if turn == 0:
            if self._view is not None and self._view.forward_blocked:
                return self._failure(Stuck(Why.IN_THE_WAY, self._walked, self._view, where=task.text))
            return RequestMove(Move.FORWARD)
        return RequestMove(Move.LEFT if turn <= 4 else Move.RIGHT)

    def _seek(self, task: _Task) -> RequestMove | Say | None:
        """Left a turn at a time until the target is in view (then up to it), or all the way round."""
        assert task.until is not None  # seek tasks are made from a named target
        if _sees(self._view, task.until):
            self._plan.appendleft(_Task(Task.WALK, until=task.until))
            return None
        if task.done >= HEADINGS - 1:
            failure = self._failure(Stuck(Why.NOWHERE, 0, self._view, wanted=task.until))
            self._not_found = task.until
            return failure
        task.done += 1
        return RequestMove(Move.LEFT)

    def _look(self, task: _Task) -> RequestMove | Say:
        """Action in place until the sides the question needs have been seen (and back), then answer."""
        ask = task.question
        assert ask is not None  # look tasks are made from questions
        if ask.look_around:
            sides = list(Side)
        elif ask.question == ins.AskedAbout.SIDE and ask.side is not None:
            sides = [ask.side]
        elif ask.question == ins.AskedAbout.IS_THERE:
            sides = [ask.side or Side.AHEAD]
        else:
            sides = [Side.AHEAD]
        if task.home is None:
            task.home = self._odo.heading
        home = task.home
        around = {s: self._views[h] for s in Side if (h := (home + SIDE_STEPS[s]) % HEADINGS) in self._views}
        missing = [s for s in sides if s not in around]
        facing = (home + SIDE_STEPS[missing[0]]) % HEADINGS if missing else home
        if self._odo.heading != facing:  # the shorter way round to the next side to see, then back
            return RequestMove(Move.LEFT if (facing - self._odo.heading) % HEADINGS <= 4 else Move.RIGHT)
        if ask.question == ins.AskedAbout.IS_THERE and ask.label is not None:
            if ask.side is not None:
                return self._say(Answered(ask.label, ask.side, around[ask.side]))
            # "can you see the mug anywhere?": every side it has looked at from here (a person's got
            # "no" from the view ahead with the mug on its left); not seen, it offers to look around
            # rather than spend eight scored moves unasked.
            side = next((s for s in around if _sees(around[s], ask.label)), Side.AHEAD)
            unlooked = () if _sees(around[side], ask.label) else tuple(s for s in Side if s not in around)
            if unlooked:
                look = Clause.of(Op.ASK, question="look_around", side=None, label=ask.label.word)
                self._offered = ((look,), "look around")  # a "yes" looks
            return self._say(Answered(ask.label, side, around[side], anywhere=True, unlooked=unlooked))
        if ask.question == ins.AskedAbout.VIEW and not ask.look_around:
            return self._say(Described(around, look_around=False))  # all it has seen from here
        if ask.question == ins.AskedAbout.DISTANCE:
            return self._say(Measured(around[Side.AHEAD]))
        return self._say(Described({s: around[s] for s in sides}, look_around=ask.look_around))
