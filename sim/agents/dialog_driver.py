"""A Driver that takes part in the dialog, from percepts alone: it describes what it sees, answers,
waits for instructions, carries them out, says when it is done or lost, and claims.

All rules, no learned part (see docs/model_card_dialog_driver.md). It never has a pose, a map or a
graph: its inputs are the chat, its frames' rays and its moves' outcomes. Its own odometry (grid
steps and 45-degree headings relative to where it started, from its moves' results) serves the
dialog's history ("go back to where you started") and tells it which views it has looked at from
where it stands. One instruction set runs at a time; a new Commander message replaces what is left
of the last one, as a person drops an old plan when told something new."""

from __future__ import annotations

import math
import random
from collections import deque
from dataclasses import dataclass, field

from sim.agents.turns import (
    Claimed,
    DoClaim,
    DoMove,
    DoSay,
    Heard,
    Judged,
    Move,
    Moved,
    MoveResult,
    Percept,
    Phase,
    PhaseChanged,
    Saw,
    SeatInfo,
    Speaker,
    Turn,
)
from sim.geometry import HEADING_DI, HEADING_DJ, HEADINGS
from sim.labels import OBJECT_LABELS, Label
from sim.language import instructions as ins
from sim.language.describe import ahead, at_wall, brief, describe, near, seen
from sim.language.vocab import SIDE_PHRASE, SIDE_STEPS, Side, wall_name
from sim.perception import RayObservation

OPENING_M = 0.6  # a side ray further than this after a nearer one: an opening on that side
MAX_WALK = 60  # forward moves one "until" may take before the Driver asks
NEXT = ("what next?", "where to now?", "what should i do next?")


@dataclass
class _Task:
    """One step of the current instruction set; `turns` / `steps` count what is left of it."""

    kind: str  # "turn", "walk", "opening", "goto", "look", "say", "claim"
    turns: int = 0
    steps: int | None = None
    until: Label | None = None
    exclude: frozenset[Label] = frozenset()
    side: Side | None = None
    nth: int = 0
    goal: tuple[int, int] = (0, 0)
    text: str = ""
    question: ins.Ask | None = None
    done: int = 0
    edge_near: bool = False
    look_back: int = 0


@dataclass
class _Odometry:
    i: int = 0
    j: int = 0
    heading: int = 0  # 45-degree steps counter-clockwise from the start heading
    turns: list[tuple[Side, tuple[int, int]]] = field(default_factory=list)  # where it turned, in order


class DialogDriver:
    """The Driver's seat agent (`sim.agents.turns.Agent`); deterministic given `seed`."""

    def __init__(self, seed: int = 0) -> None:
        self._rng = random.Random(seed)
        self.reset(SeatInfo(Speaker.DRIVER, 0))

    def reset(self, info: SeatInfo) -> None:
        self._info = info
        self._phase = Phase.WAITING
        self._odo = _Odometry()
        self._views: dict[int, RayObservation | None] = {}  # heading -> view, from where it stands
        self._view: RayObservation | None = None
        self._plan: deque[_Task] = deque()
        self._moving = False  # a move is out; wait for its outcome and frame
        self._target: Label | None = None
        self._claiming = False
        self._rejected_at: set[tuple[int, int]] = set()
        self._done_words = ""

    # -- percepts -------------------------------------------------------------------------------

    def perceive(self, percept: Percept) -> list[Turn]:
        if isinstance(percept, PhaseChanged):
            if percept.phase == Phase.NAVIGATING and self._phase == Phase.NAVIGATING:
                self._target = None  # a confirmed target: the next one is told anew
            self._phase = percept.phase
            return []
        if isinstance(percept, Heard):
            return self._heard(percept.text) if percept.speaker == Speaker.COMMANDER else []
        if isinstance(percept, Moved):
            return self._moved(percept)
        if isinstance(percept, Saw):
            self._view = percept.rays
            self._views[self._odo.heading] = percept.rays
            self._moving = False
            return self._advance()
        if isinstance(percept, Judged):
            self._claiming = False
            if percept.confirmed:
                return []
            self._rejected_at.add((self._odo.i, self._odo.j))
            return [DoSay("ok, not here then. where should i go?")]
        if isinstance(percept, Claimed):
            return []
        return []

    def _moved(self, moved: Moved) -> list[Turn]:
        if moved.result != MoveResult.OK:
            self._plan.clear()
            if moved.result == MoveResult.COLLISION:
                return [DoSay("i hit a wall, which way now?")]
            return [DoSay(f"i could not move ({moved.reason or 'refused'}). what should i do?")]
        if moved.move == Move.FORWARD:
            self._odo.i += int(HEADING_DI[self._odo.heading])
            self._odo.j += int(HEADING_DJ[self._odo.heading])
            self._views = {}
        else:
            self._odo.heading = (self._odo.heading + (1 if moved.move == Move.LEFT else -1)) % HEADINGS
        return []

    # -- instructions -> tasks ------------------------------------------------------------------

    def _heard(self, text: str) -> list[Turn]:
        parsed = ins.parse(text)
        self._plan.clear()
        tasks: list[_Task] = []
        for item in parsed.instructions:
            tasks += self._tasks(item)
        if parsed.unclear:
            tasks = [_Task("say", text="sorry, i did not understand. which way should i go?")]
        if self._phase == Phase.LOCALIZING and any(t.kind in ("walk", "opening", "goto") for t in tasks):
            tasks = [t for t in tasks if t.kind not in ("walk", "opening", "goto")]
            tasks.append(
                _Task("say", text="i will stay here until you have found me on the map. what should i describe?")
            )
        if tasks and tasks[-1].kind not in ("say", "claim", "look"):
            tasks.append(_Task("say"))  # the report when the moves are done
        self._plan.extend(tasks)
        self._done_words = ""
        return [] if self._moving else self._advance()

    def _tasks(self, item: ins.Instruction) -> list[_Task]:
        if isinstance(item, ins.Turn):
            return [_Task("turn", turns=item.eighths)]
        if isinstance(item, ins.Forward):
            return [_Task("walk", steps=item.steps, until=item.until, exclude=item.exclude)]
        if isinstance(item, ins.TakeOpening):
            return [_Task("opening", side=item.side, nth=item.nth)]
        if isinstance(item, ins.Target):
            self._target = item.label
            if item.side is None:
                return []
            return [_Task("turn", turns=SIDE_STEPS[item.side] if item.side != Side.RIGHT else -2)] + [
                _Task("walk", until=item.label)
            ]
        if isinstance(item, ins.Ask):
            return [_Task("look", question=item)]
        if isinstance(item, ins.GoBack):
            return [self._go_back(item)]
        if isinstance(item, ins.Stop):
            if item.claim:
                return [_Task("claim")]
            return [_Task("say", text=f"ok, stopped. {brief(self._view)}. {self._rng.choice(NEXT)}")]
        return []

    def _go_back(self, item: ins.GoBack) -> _Task:
        if item.place == ins.Place.START:
            return _Task("goto", goal=(0, 0), text="back where i started")
        turns = [where for side, where in self._odo.turns if item.side is None or side == item.side]
        if len(turns) < item.nth:
            side = f" {item.side.value}" if item.side else ""
            return _Task("say", text=f"i have not turned{side} that many times yet. where should i go?")
        return _Task("goto", goal=turns[item.nth - 1], text="back where i turned")

    # -- carrying tasks out ---------------------------------------------------------------------

    def _advance(self) -> list[Turn]:
        out: list[Turn] = []
        while self._plan and not self._moving and not self._claiming:
            if self._sees_target() and self._plan[0].kind != "claim":
                self._plan.clear()
                self._plan.append(_Task("claim"))
            task = self._plan.popleft()
            step = self._step(task)  # may clear the plan or put tasks before what is left
            if isinstance(step, DoMove):
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
        if (self._odo.i, self._odo.j) in self._rejected_at:
            return False
        return near(self._view, self._target)

    def _step(self, task: _Task) -> DoMove | DoSay | list[Turn] | None:
        """The task's next move, or None (or its closing words) when it is finished."""
        if task.kind == "turn":
            return self._turn(task)
        if task.kind == "walk":
            return self._walk(task)
        if task.kind == "opening":
            return self._opening(task)
        if task.kind == "goto":
            return self._goto(task)
        if task.kind == "look":
            return self._look(task)
        if task.kind == "claim":
            if self._phase != Phase.NAVIGATING:
                return DoSay("you have not placed me on the map yet; tell me when i may go")
            self._claiming = True
            thing = wall_name(self._target) if self._target is not None else "target"
            return [DoSay(f"i think i found the {thing}"), DoClaim()]
        text = task.text or f"ok, {self._done_words or 'done'}, {brief(self._view)}. {self._rng.choice(NEXT)}"
        return DoSay(text)

    def _turn(self, task: _Task) -> DoMove | None:
        if task.turns == 0:
            return None
        if task.done == 0 and abs(task.turns) >= 2:
            self._odo.turns.append((Side.LEFT if task.turns > 0 else Side.RIGHT, (self._odo.i, self._odo.j)))
        task.done += 1
        step = 1 if task.turns > 0 else -1
        task.turns -= step
        self._done_words = "turned"
        return DoMove(Move.LEFT if step > 0 else Move.RIGHT)

    def _walk(self, task: _Task) -> DoMove | DoSay | None:
        view = self._view
        if task.steps is not None:
            if task.done >= task.steps:
                self._done_words = f"went {task.done} steps"
                return None
            if view is not None and view.forward_blocked:
                self._plan.clear()
                return DoSay(f"i can only go {task.done} steps, {brief(view)}. which way now?")
            task.done += 1
            return DoMove(Move.FORWARD)
        if view is None or view.problem is not None:
            self._plan.clear()
            return DoSay("i cannot see clearly. what should i do?")
        front = ahead(view)
        if task.until is not None and task.until in OBJECT_LABELS:
            reached = near(view, task.until) or view.forward_blocked
        else:
            reached = at_wall(view)
        if reached:
            label = front.label if front is not None else None
            if task.until is not None and label != task.until and task.until not in OBJECT_LABELS:
                self._plan.clear()
                found = wall_name(label) if label is not None else "something"
                return DoSay(f"i am at a {found}, i do not see a {wall_name(task.until)} ahead. which way now?")
            if label is not None and label in task.exclude:
                self._plan.clear()
                return DoSay(f"i am at the {wall_name(label)}, which you said is not the one. which way now?")
            self._done_words = f"at the {wall_name(label)}" if label is not None else "at the wall"
            return None
        wall = task.until if task.until not in OBJECT_LABELS else None
        if task.done == 0 and wall is not None and not any(s.label == wall for s in seen(view)):
            self._plan.clear()
            return DoSay(f"i do not see a {wall_name(wall)} ahead, {brief(view)}. which way?")
        if task.done >= MAX_WALK:
            self._plan.clear()
            return DoSay(f"i have gone {task.done} steps and still {brief(view)}. where am i going?")
        task.done += 1
        return DoMove(Move.FORWARD)

    def _opening(self, task: _Task) -> DoMove | DoSay | None:
        view = self._view
        if view is None or view.problem is not None:
            self._plan.clear()
            return DoSay("i cannot see clearly. what should i do?")
        ray = 12 if task.side == Side.LEFT else 0
        far = not view.valid[ray] or view.labels[ray] == Label.FLOOR or float(view.depth[ray]) > OPENING_M
        if task.edge_near and far:
            task.nth -= 1
        task.edge_near = not far
        if task.nth <= 0:
            self._plan.extendleft([_Task("walk", steps=1), _Task("turn", turns=2 if task.side == Side.LEFT else -2)])
            return None
        if view.forward_blocked or task.done >= MAX_WALK:
            self._plan.clear()
            return DoSay(f"i found no opening on my {task.side}, {brief(view)}. which way now?")
        task.done += 1
        return DoMove(Move.FORWARD)

    def _goto(self, task: _Task) -> DoMove | DoSay | None:
        di, dj = task.goal[0] - self._odo.i, task.goal[1] - self._odo.j
        if di == 0 and dj == 0:
            self._done_words = task.text
            return None
        if task.done >= 4 * (abs(di) + abs(dj)) + 16:
            self._plan.clear()
            return DoSay(f"i cannot find my way {task.text}. which way?")
        task.done += 1
        wanted = round(math.atan2(dj, di) / (math.pi / 4)) % HEADINGS
        turn = (wanted - self._odo.heading) % HEADINGS
        if turn == 0:
            if self._view is not None and self._view.forward_blocked:
                self._plan.clear()
                return DoSay(f"a wall is in my way {task.text}, {brief(self._view)}. which way?")
            return DoMove(Move.FORWARD)
        return DoMove(Move.LEFT if turn <= 4 else Move.RIGHT)

    def _look(self, task: _Task) -> DoMove | DoSay:
        """Turn in place until the sides the question needs have been seen (and back), then answer."""
        ask = task.question
        assert ask is not None  # look tasks are made from questions
        if ask.look_around:
            sides = list(Side)
        elif ask.question == ins.Question.SIDE and ask.side is not None:
            sides = [ask.side]
        elif ask.question == ins.Question.IS_THERE:
            sides = [ask.side or Side.AHEAD]
        else:
            sides = [Side.AHEAD]
        if task.look_back == 0:
            task.look_back = self._odo.heading + 1  # the heading to come back to, plus one
        home = task.look_back - 1
        missing = [s for s in sides if (home + SIDE_STEPS[s]) % HEADINGS not in self._views]
        if missing:
            return DoMove(Move.LEFT)
        if self._odo.heading != home:
            return DoMove(Move.LEFT if (home - self._odo.heading) % HEADINGS <= 4 else Move.RIGHT)
        views = {s: self._views[(home + SIDE_STEPS[s]) % HEADINGS] for s in sides}
        if ask.question == ins.Question.IS_THERE and ask.label is not None:
            return DoSay(self._is_there(ask.label, sides[0], views[sides[0]]))
        if ask.question == ins.Question.VIEW and not ask.look_around:
            views = {
                s: self._views[(home + SIDE_STEPS[s]) % HEADINGS]
                for s in Side
                if (home + SIDE_STEPS[s]) % HEADINGS in self._views
            }
        return DoSay(describe(views))

    def _is_there(self, label: Label, side: Side, view: RayObservation | None) -> str:
        hits = [s for s in seen(view) if s.label == label] if view is not None else []
        if hits:
            return f"yes, {'close' if hits[0].depth <= 0.5 else 'far'} {wall_name(label)} {SIDE_PHRASE[side]}"
        return f"no, no {wall_name(label)} {SIDE_PHRASE[side]}. {describe({side: view})}"
