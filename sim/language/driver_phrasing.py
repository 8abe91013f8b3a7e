"""What the dialog Driver says, as typed facts, and two ways of putting them into words: the scripted
Driver's (its words as they have always been) and a frozen persona's (`driver_personas`), with the
persona's slips drawn from a seeded generator.

The Driver decides what to say from its percepts (`sim.agents.dialog_driver`); a phrasing only words
it, and says how many steps the person really drives when told a number (a persona miscounts now
and then)."""

from __future__ import annotations

import random
from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol

import numpy as np

from sim.core.geometry import GRID_STEP_M
from sim.core.labels import OBJECT_LABELS, WALL_LABELS, Label
from sim.core.rays import RayObservation
from sim.language.describe import Seen, Sighting, Spot, brief, describe, glance, seen, sighting
from sim.language.driver_personas import (
    DriverPersona,
    DriverPersonaBook,
    Lead,
    Message,
    Slip,
    load_driver_persona,
)
from sim.language.phrases import NUMBER_NAMES
from sim.language.sectors import NEAR_M
from sim.language.vocab import SIDE_PHRASE, Side, wall_name

View = RayObservation | None


@dataclass(frozen=True)
class Described:
    """An answer to "what do you see": the views of the sides asked about, from where it stands."""

    views: Mapping[Side, View]
    look_around: bool


@dataclass(frozen=True)
class Answered:
    """An answer to "is there a `label` on your `side`?" from that side's view."""

    label: Label
    side: Side
    view: View
    anywhere: bool = False  # asked with no side: every side it has looked at (`side`: where it is seen)
    unlooked: tuple[Side, ...] = ()  # asked anywhere and not seen: the sides it has not looked at


@dataclass(frozen=True)
class Measured:
    """An answer to "how many steps to the wall ahead?" from the view ahead."""

    view: View


# The three middle rays, about 5 degrees either side: the way a forward press goes (the five of
# `CENTRE_RAYS` met side walls the robot passes).
STRAIGHT_RAYS = slice(5, 8)


def measured(view: View) -> str:
    """How far the nearest thing straight ahead is, in forward presses: a step is 7 cm and the robot
    stops a step short of a wall (on a diagonal a press goes further, and a wall at a slant can stop
    it sooner: "about")."""
    met = view.valid[STRAIGHT_RAYS] & (view.labels[STRAIGHT_RAYS] != Label.FLOOR) if view is not None else None
    if view is None or met is None or not met.any():
        return f"i cannot tell how far it is. {brief(view)}"
    depth = np.where(met, view.depth[STRAIGHT_RAYS], np.inf)
    k = int(depth.argmin())
    steps = max(int(float(depth[k]) / GRID_STEP_M) - 1, 0)
    thing = wall_name(Label(int(view.labels[STRAIGHT_RAYS][k])))
    if steps == 0:
        return f"the {thing} is right in front of me: forward would bump"
    return f"the {thing} ahead is about {steps} {'step' if steps == 1 else 'steps'} away"


@dataclass(frozen=True)
class Done:
    """An instruction carried out: what it did last ("turned left 90 degrees", "at the red wall";
    "" says nothing of it) and what it sees now; where it did only the part it understood, the
    words it did not get and its best reading of them, asked."""

    did: str
    view: View
    unread: str = ""
    offer: str = ""


@dataclass(frozen=True)
class Stopped:
    """Told to stop, it stopped."""

    view: View


class Why(StrEnum):
    """Why a walk or a turn could not be carried out to its end."""

    COLLISION = "collision"  # a move bumped into a wall
    CANNOT_GO = "cannot_go"  # counted steps, the way ahead blocked
    WRONG_WALL = "wrong_wall"  # at a wall, not the one it was sent to
    EXCLUDED = "excluded"  # at the wall it was told is not the one
    NOT_IN_VIEW = "not_in_view"  # sent to a wall it cannot see
    TOO_FAR = "too_far"  # walked a long way and not there yet
    NO_OPENING = "no_opening"
    IN_THE_WAY = "in_the_way"  # a wall on the way back
    NOWHERE = "nowhere"  # looked all around for the target, and it is not in view


@dataclass(frozen=True)
class Stuck:
    """It could not carry out what it was told: why, after how many steps, what it sees; after
    several failures in a row it asks for one move at a time."""

    why: Why
    steps: int
    view: View
    found: Label | None = None  # WRONG_WALL, EXCLUDED: the wall it is at
    wanted: Label | None = None  # WRONG_WALL, NOT_IN_VIEW: the wall it was sent to
    side: Side | None = None  # NO_OPENING
    where: str = ""  # IN_THE_WAY: "back where i started"
    one_at_a_time: bool = False


@dataclass(frozen=True)
class Claiming:
    """It thinks it is at the target."""

    target: Label | None


@dataclass(frozen=True)
class NotHere:
    """Its claim was rejected: it asks where to go."""


class Trouble(StrEnum):
    """What it did not get, or cannot do now."""

    ASK_ABOUT = "ask_about"  # unsure of an instruction: its best reading, asked back
    UNCLEAR = "unclear"  # understood nothing of it
    PARTLY = "partly"  # did the part it understood
    NOT_MEANT = "not_meant"  # its reading, asked back, was wrong
    NOT_TURNED = "not_turned"  # "back where you turned" before it turned that often
    STAYING = "staying"  # told to move while the Commander is still finding it on the map
    NOT_PLACED = "not_placed"  # told to claim before being placed on the map
    BLIND = "blind"  # its frame is unreadable
    NOT_MOVED = "not_moved"  # the robot did not carry out a move
    REFUSED = "refused"  # the trial did not allow its turn


@dataclass(frozen=True)
class Troubled:
    """It did not get an instruction, or cannot do it now. `quoted`: the Commander's words (or the
    turn refused); `detail`: its reading of them (or why refused); `side`: NOT_TURNED's side."""

    trouble: Trouble
    quoted: str = ""
    detail: str = ""
    side: Side | None = None


@dataclass(frozen=True)
class ReadBack:
    """A long plan said in short before it is carried out (for a person in the Commander's seat):
    the reader's own words, said as they are."""

    text: str


Fact = Described | Answered | Measured | Done | Stopped | Stuck | Claiming | NotHere | Troubled | ReadBack


class DriverPhrasing(Protocol):
    def say(self, fact: Fact) -> str: ...

    def count(self, steps: int) -> int:
        """How many steps the person drives when told `steps`."""
        ...


def _yes(label: Label, view: View) -> Seen | None:
    return next((s for s in seen(view) if s.label == label), None) if view is not None else None


NEXT = ("what next?", "where to now?", "what should i do next?")


class ScriptedDriverPhrasing:
    """The scripted Driver's words, as the dialog Driver has always said them; it drives the steps
    it is told. Its closing question is drawn from `seed`."""

    def __init__(self, seed: int = 0) -> None:
        self._rng = random.Random(seed)

    def count(self, steps: int) -> int:
        return steps

    def say(self, fact: Fact) -> str:
        match fact:
            case Described(views=views):
                return describe(views)
            case Answered(label=label, side=side, view=view, anywhere=anywhere, unlooked=unlooked):
                if (hit := _yes(label, view)) is not None:
                    return f"yes, {'close' if hit.depth <= NEAR_M else 'far'} {wall_name(label)} {SIDE_PHRASE[side]}"
                if not anywhere:
                    return f"no, no {wall_name(label)} {SIDE_PHRASE[side]}. {describe({side: view})}"
                if not unlooked:
                    return f"no, i do not see the {wall_name(label)} on any side. {describe({side: view})}"
                where = " or ".join(SIDE_PHRASE[s].removeprefix("on my ") for s in unlooked)
                return (
                    f"no, no {wall_name(label)} {SIDE_PHRASE[side]}. {describe({side: view})} "
                    f"i have not looked {where}. should i look around?"
                )
            case Measured(view=view):
                return measured(view)
            case Done(did=did, view=view, unread=unread, offer=offer):
                then = self._rng.choice(NEXT)
                if unread:
                    then = f"i did not get '{unread}' - {offer}?"
                return f"ok, {did or 'done'}, {brief(view)}. {then}"
            case Stopped(view=view):
                return f"ok, stopped. {brief(view)}. {self._rng.choice(NEXT)}"
            case Stuck():
                text = self._stuck(fact)
                return f"{text} could you give me one move at a time?" if fact.one_at_a_time else text
            case Claiming(target=target):
                return f"i think i found the {wall_name(target) if target is not None else 'target'}"
            case NotHere():
                return "ok, not here then. where should i go?"
            case Troubled():
                return self._troubled(fact)
            case ReadBack(text=text):
                return f"ok: {text}"

    @staticmethod
    def _stuck(fact: Stuck) -> str:
        view = fact.view
        match fact.why:
            case Why.COLLISION:
                return "i hit a wall, which way now?"
            case Why.CANNOT_GO:
                return f"i can only go {fact.steps} steps, {brief(view)}. which way now?"
            case Why.WRONG_WALL:
                found = wall_name(fact.found) if fact.found is not None else "something"
                return f"i am at a {found}, i do not see a {_name(fact.wanted)} ahead. which way now?"
            case Why.EXCLUDED:
                return f"i am at the {_name(fact.found)}, which you said is not the one. which way now?"
            case Why.NOT_IN_VIEW:
                return f"i do not see a {_name(fact.wanted)} ahead, {brief(view)}. which way?"
            case Why.TOO_FAR:
                return f"i have gone {fact.steps} steps and still {brief(view)}. where am i going?"
            case Why.NO_OPENING:
                return f"i found no opening on my {fact.side}, {brief(view)}. which way now?"
            case Why.IN_THE_WAY:
                return f"a wall is in my way {fact.where}, {brief(view)}. which way?"
            case Why.NOWHERE:
                return f"i looked all around and i do not see the {_name(fact.wanted)}. which way?"

    @staticmethod
    def _troubled(fact: Troubled) -> str:
        match fact.trouble:
            case Trouble.ASK_ABOUT:
                # A whole long message said back is a wall of text to read again: a person's were.
                got = f"'{fact.quoted}'" if len(fact.quoted) <= QUOTED_CHARS else "all of that"
                return f"i am not sure i got {got}. do you mean: {fact.detail}?"
            case Trouble.UNCLEAR:
                got = f"'{fact.quoted}'" if len(fact.quoted) <= QUOTED_CHARS else "that"
                return (
                    f"sorry, i did not understand {got}. could you say it another way, "
                    "for example 'turn left' or 'go forward to the red wall'?"
                )
            case Trouble.PARTLY:
                return "i did the part i understood; i did not get the rest. what next?"
            case Trouble.NOT_MEANT:
                return "ok, i did not get it then. could you say it another way, one move at a time?"
            case Trouble.NOT_TURNED:
                side = f" {fact.side.value}" if fact.side else ""
                return f"i have not turned{side} that many times yet. where should i go?"
            case Trouble.STAYING:
                return "i will stay here until you have found me on the map. what should i describe?"
            case Trouble.NOT_PLACED:
                return "you have not placed me on the map yet; tell me when i may go"
            case Trouble.BLIND:
                return "i cannot see clearly. what should i do?"
            case Trouble.NOT_MOVED:
                return f"i could not move ({fact.detail or 'refused'}). what should i do?"
            case Trouble.REFUSED:
                return f"i could not {fact.quoted} ({fact.detail}). what should i do?"


def _name(label: Label | None) -> str:
    return wall_name(label) if label is not None else "something"


OTHER_SIDE = {Side.LEFT: Side.RIGHT, Side.RIGHT: Side.LEFT}
QUOTED_CHARS = 100  # words it did not get, said back up to this long (a sentence, not a whole message)
_SAYS_QUESTION = (Trouble.STAYING, Trouble.NOT_PLACED)  # troubles a person words as a question


class PersonaDriverPhrasing:
    """A frozen persona's words for the same facts; its slips (a side swapped, a wrong colour, an
    object not mentioned, a step miscounted) and its choice of template drawn from `seed`."""

    def __init__(self, persona: DriverPersona, seed: int = 0) -> None:
        self.book: DriverPersonaBook = load_driver_persona(persona)
        self._rng = random.Random(seed)

    def _pick(self, options: list[str]) -> str:
        return options[self._rng.randrange(len(options))]

    def _slips(self, slip: Slip) -> bool:
        return self._rng.random() < self.book.slips.get(slip, 0.0)

    def count(self, steps: int) -> int:
        if steps > 1 and self._slips(Slip.STEPS_OFF_BY_ONE):
            return steps + self._rng.choice((-1, 1))
        return steps

    def number(self, n: int) -> str:
        return NUMBER_NAMES[n] if self.book.numbers == "words" and n < len(NUMBER_NAMES) else str(n)

    def _say(self, message: Message, **slots: str) -> str:
        """A template of `message` that uses only the slots given: {view} is optional in "done" and
        "blocked", {colour} and {side} in "yes" and "no"."""
        templates = self.book.says[message]
        return self._pick(
            [t for t in templates if all(f"{{{name}}}" not in t or name in slots for name in _SLOTS)]
        ).format(**slots)

    # -- words for things, sides, colours -------------------------------------------------------

    def _side(self, side: Side) -> str:
        if side in OTHER_SIDE and self._slips(Slip.SWAP_LEFT_RIGHT):
            side = OTHER_SIDE[side]
        return self._pick(self.book.sides[side])

    def _thing(self, label: Label) -> str:
        return self._pick(self.book.things.get(label.word, [wall_name(label)]))

    def _colour(self, label: Label) -> str:
        if self._slips(Slip.WRONG_COLOUR):
            label = self._rng.choice([other for other in WALL_LABELS if other != label])
        return self._pick(self.book.colours.get(label.word, [label.word]))

    def _clause(self, label: Label, side: Side, depth: float | None) -> str | None:
        """One thing seen on one side; None where the persona misses the object."""
        if label in OBJECT_LABELS:
            if self._slips(Slip.MISS_OBJECT):
                return None
            return self._say(Message.OBJECT, thing=self._thing(label), side=self._side(side))
        distance = self._pick(self.book.near if depth is None or depth <= NEAR_M else self.book.far)
        return self._say(Message.WALL, colour=self._colour(label), side=self._side(side), distance=distance)

    def _join(self, clauses: list[str | None]) -> str:
        said = [c for c in clauses if c]
        out = said[0] if said else ""
        for clause in said[1:]:
            out += self._pick(self.book.says[Message.JOIN]) + clause
        return out

    def _ordered(self, clauses: list[tuple[Label | None, str | None]]) -> list[str | None]:
        """The clauses in the persona's order: objects first for one who leads with landmarks."""
        if self.book.lead == Lead.OBJECTS:
            clauses = sorted(clauses, key=lambda c: c[0] not in OBJECT_LABELS)
        return [text for _, text in clauses]

    def _sighting(self, sight: Sighting) -> str:
        clauses: list[tuple[Label | None, str | None]] = []
        if sight.spot is not None:
            clauses.append((None, self._say(Message.CORNER if sight.spot == Spot.CORNER else Message.CORRIDOR)))
        for side, items in sight.sides.items():
            if not items:
                clauses.append((None, self._say(Message.OPEN, side=self._side(side))))
            clauses += [(s.label, self._clause(s.label, side, s.depth)) for s in items]
        return self._join(self._ordered(clauses))

    def _glance(self, view: View) -> str:
        """A short view: what is ahead and close at the edges, the objects in view."""
        if view is None or view.problem is not None:
            return ""
        look = glance(view)
        clauses: list[tuple[Label | None, str | None]] = []
        if look.front is not None:
            clauses.append((look.front.label, self._clause(look.front.label, Side.AHEAD, look.front.depth)))
        clauses += [(label, self._clause(label, side, None)) for side, label in look.edges]
        clauses += [(label, self._clause(label, Side.AHEAD, None)) for label in look.objects]
        return self._join(self._ordered(clauses)) or self._say(Message.OPEN, side=self._side(Side.AHEAD))

    # -- messages -------------------------------------------------------------------------------

    def say(self, fact: Fact) -> str:
        match fact:
            case Described(views=views, look_around=look_around):
                sight = sighting(views)
                if sight is None:
                    return self._say(Message.CONFUSED)
                clauses = self._sighting(sight)
                return self._say(Message.LOOK_AROUND, clauses=clauses) if look_around else clauses
            case Answered(label=label, side=side, view=view):
                return self._answer(label, side, view)
            case Measured(view=view):  # the personas were frozen with no words for it
                return measured(view)
            case Done(view=view) | Stopped(view=view):
                return self._say(Message.DONE, **_view(self._glance(view)))
            case Stuck(steps=steps, view=view):
                return self._say(Message.BLOCKED, n=self.number(steps), **_view(self._glance(view)))
            case Claiming(target=target):
                return self._say(Message.CLAIM, thing=self._thing(target) if target is not None else "target")
            case NotHere():
                return self._say(Message.QUESTION)
            case Troubled(trouble=trouble):
                return self._say(Message.QUESTION if trouble in _SAYS_QUESTION else Message.CONFUSED)
            case ReadBack(text=text):
                return text

    def _answer(self, label: Label, side: Side, view: View) -> str:
        yes = _yes(label, view) is not None
        if label in OBJECT_LABELS:
            yes = yes and not self._slips(Slip.MISS_OBJECT)
        elif self._slips(Slip.WRONG_COLOUR):
            yes = not yes
        if not yes:
            return self._say(Message.NO, side=self._side(side))
        colour = (
            self._thing(label)
            if label in OBJECT_LABELS
            else self._pick(self.book.colours.get(label.word, [label.word]))
        )
        return self._say(Message.YES, colour=colour, side=self._side(side))


_SLOTS = ("colour", "side", "distance", "thing", "clauses", "view", "n")


def _view(text: str) -> dict[str, str]:
    """The {view} slot where there is something to say."""
    return {"view": text} if text else {}
