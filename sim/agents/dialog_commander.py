"""A Commander that takes part in the dialog from what a person in its seat has: the map with the
landmarks, the next target's name, the chat and the claim frames. It never has the true pose, the
Driver's camera stream or its moves.

Localization: a belief over (node, heading) (`sim.language.localizer.Belief`) read from the
Driver's words after every message; the instructions it gave, as the Driver's parser reads them
(`sim.language.instructions`), move the belief when the Driver reports carrying them out (in
full when the report says done, anywhere along the way when it says it could not). It asks the
question whose yes / no best halves its belief and marks its estimate on the map once the belief
has settled, marking it again as the estimate moves. Guidance: the fewest-moves route from its
estimate (`sim.agents.route`), one instruction at a time, each after the Driver's report; where
the belief spreads out again it says it is unsure and asks; after two instructions not carried
out it says one move at a time. A Driver's question ("why not?", "how far?", "left or right?",
"where am i?", "what does the mug look like?", "which white wall?") is answered before the
instruction is said again; a Driver that says it is lost, or is unsure of the check of its mark,
gets its questions again. Claims: the claim frame's rays
decide (the target in view and within reach), and a rejection says why at once; a rejected frame
is evidence of where the robot is."""

from __future__ import annotations

import itertools
import math
import re
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from sim.agents.route import Router
from sim.core.dynamics import Action as Move
from sim.core.dynamics import Pose
from sim.core.geometry import (
    GRID_STEP_M,
    HEADINGS,
    MAP_WIDTH_PX,
    TABLE_WIDTH_M,
    heading_angle,
    heading_index,
    world_to_pixel,
)
from sim.core.labels import OBJECT_LABELS, WALL_LABELS, Label, object_label
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.core.rays import RayObservation
from sim.language import instructions as ins
from sim.language import lexicon
from sim.language.describe import brief, near, wall_close, within_reach
from sim.language.describe import seen as describe_seen
from sim.language.lexicon import Asked
from sim.language.localizer import Belief, Scene
from sim.language.phrases import PhraseKind, Phrases, Phrasing
from sim.language.sectors import Sector
from sim.language.understanding import Understanding, belief_facts
from sim.language.vocab import OBJECT_LOOKS, OBJECT_WORDS, wall_name
from sim.trial.agent import SeatInfo
from sim.trial.commands import Action, Judge, Localize, Say
from sim.trial.percepts import Claimed, Heard, Percept, PhaseBegan
from sim.trial.vocabulary import Phase, Role

SETTLED_M = 0.3  # expected TD of the estimate under the belief: settled enough to mark and guide
LOST_M = 0.6  # ... spread this far again while guiding: stop and ask
MAX_QUESTIONS = 6  # questions before marking the estimate anyway (and, while guiding, per stop)
SURE, SURE_M = 0.95, 0.25  # without a claim frame: confirm this much belief this close to the target
REVISE_M = 0.3  # mark the estimate again when it moved this far from the last mark
MAX_WALK = 60  # the Driver's own cap on a walk "until"
DEPTH_SCALE_M = 0.15  # a claim frame's ray this far off the map's depth counts as a wrong label
VIEW_WEIGHT = 1.0
ELSEWHERE = 1e-3  # after each instruction, the chance the belief lost the robot
DOUBTED = 0.5  # ... after the Driver said no to the check of its mark
BLOCKED_PENALTY = 5.0  # log-likelihood against a pose whose way forward is free, when told it is not
CLOSE_PENALTY = 3.0  # ... against a pose with a longer way ahead than the steps to a wall the Driver counts
UNSEEN_PENALTY = 3.0  # ... against a pose with the target in reach, when the Driver speaks without claiming
NEAR_TARGET_STEPS = 3  # a rejected claim this few steps' walk from where it should be made: "close to it now"
RISKY = 0.4  # the belief's chance of a counted walk meeting a wall before its count: walk less
NEAR_ENOUGH = 0.5  # the belief's share within SURE_M of the target to say "press i found the target"
LANDMARK_M = 0.5  # walls this close to the target name where it stands ("next to the red wall") ...
ALSO_NEAR_M = 0.1  # ... the nearest, and another no further than this beyond it
DESCRIBED_SPLIT = 0.1  # a question on a side the Driver has not described, unless none splits the belief this well
REPHRASE_AFTER = 2  # instructions in a row not carried out: say the next one move at a time
LOST_AFTER = 3  # ... stop guiding and ask
# The same instruction this many times within the last CIRCLING_WITHIN said in a row, each after a
# report of the last one done: lost, going round in circles.
CIRCLING_AFTER = 3
CIRCLING_WITHIN = 5
# A report of an instruction not carried out in full: the Driver stopped somewhere along the way.
# Whole words: "hit" inside "white" made every report naming a white wall one not carried out.
# "do not" only as the scripted Driver's "i do not see a red wall ahead": a person's "i don't think
# there's anything on my left" describes.
_STUCK = re.compile(
    r"\b(?:hit|cannot|can only|could not|do not see (?:a|the)|not the one|no opening|still|not turned|did the part)\b"
)
MISCOUNT = math.log(0.1)  # a person's count of the steps it made before it stopped, one off
# Questions on how to carry out the instruction out: asked before doing it, whatever else is said
# ("ok. turn right how much, one click or two?").
_HOW_TO = (Asked.TURN_SIZE, Asked.WHICH_ONE, Asked.LOOKS)
# A question's sector as the Commander says it; never behind: a person in the Driver's seat cannot
# see behind (and a Driver agent turns around and back to answer, eight scored moves).
_YOUR_SIDE = {Sector.FRONT: "ahead of you", Sector.LEFT: "on your left", Sector.RIGHT: "on your right"}
LOOK_AROUND = "look around and tell me what you see"


@dataclass(frozen=True)
class Estimate:
    pose: Pose
    x: float
    y: float
    spread_m: float  # the belief's expected TD from the estimate's node


def _moves(said: ins.Parsed) -> list[ins.Instruction]:
    """The moves of an instruction, without the words around them."""
    return [i for i in said.instructions if isinstance(i, ins.MOVING)]


def _same_first_move(proposed: str, instruction: str) -> bool | None:
    """Whether a move a Driver proposes starts as the instruction does (a walk, or a turn the same
    way); None where the words propose no move."""
    theirs, ours = _moves(ins.parse(proposed)), _moves(ins.parse(instruction))
    if not theirs or not ours:
        return None
    if isinstance(theirs[0], ins.Turn) and isinstance(ours[0], ins.Turn):
        return (theirs[0].eighths > 0) == (ours[0].eighths > 0)
    return type(theirs[0]) is type(ours[0])


def _is_there(label: Label, sector: Sector) -> str:
    """Its yes / no question about `label` on a side; a landmark with its colour in the camera (a
    person asked about the paddle said "no paddle. the olive cylinder is right-ish behind me")."""
    thing = f"{OBJECT_LOOKS[label]} {wall_name(label)}" if label in OBJECT_LOOKS else wall_name(label)
    return f"is there {'an' if thing[0] in 'aeiou' else 'a'} {thing} {_YOUR_SIDE[sector]}?"


def _object_named(text: str) -> Label | None:
    """The landmark a Driver's question names first ("is the olive cylinder the paddle?"), if any."""
    return next((label for label in lexicon.question(text).labels if label in OBJECT_LABELS), None)


def _counted(said: ins.Parsed) -> int | None:
    """The count of an instruction's one counted walk, which presses said to have bumped are taken
    from ("done, but the last 2 presses did not move"); None where it has none or several."""
    counts = [i.steps for i in said.instructions if isinstance(i, ins.Forward)]
    return counts[0] if len(counts) == 1 else None


def _wall_close_ahead(fact: lexicon.Fact) -> bool:
    """A wall (or the edge), not an object, said to be close ahead."""
    return (
        fact.kind in (lexicon.ViewKind.LABEL, lexicon.ViewKind.EDGE)
        and fact.label not in OBJECT_LABELS
        and fact.distance == lexicon.Distance.NEAR
        and Sector.FRONT in fact.sectors
        and not fact.negated
    )


class DialogCommander:
    """The Commander's seat agent (`sim.agents.turns.Agent`) on one maze; deterministic given `seed`."""

    def __init__(
        self,
        maze: Maze,
        seed: int = 0,
        cache_dir: str | Path | None = None,
        understanding: Understanding | None = None,
    ) -> None:
        """`understanding`: how it reads the Driver (the rules by default; `Understanding.trained()`
        for the trained reader)."""
        self.maze = maze
        # It plans on the graph the robot drives on: its map shows the landmarks, and they block.
        self.graph = NavGraph.for_robot(maze, cache_dir=cache_dir)
        rays = RayTable.build(maze, self.graph, cache_dir=cache_dir)
        self.rays = rays
        self.scene = Scene.from_rays(rays.labels, rays.depth, self.graph.nodes)
        self.phrases = Phrases(Phrasing.BUTTONS, seed)
        self.router = Router(self.graph, rays, self.phrases)
        reach = np.isfinite(self.graph.dist)
        self.main = reach[int(reach.sum(axis=1).argmax())]
        self._dist = np.where(np.isfinite(self.graph.dist), self.graph.dist, 1e3)
        self._seen = (self.scene.near + self.scene.far) > 0  # (N, 8, 4, labels): "is there ...?" yes
        self._common = self._seen[self.main].mean(axis=(0, 1))  # (4, labels): how often the answer is yes
        # Where a walk "until the wall" / "until you see the mug" stops, by the Driver's rules.
        every = np.ones(rays.labels.shape, dtype=bool)
        blocked = np.asarray(rays.forward_blocked, dtype=bool)
        self._at_wall = blocked | wall_close(rays.labels, rays.depth, every)
        self._reach = {label: within_reach(rays.labels, rays.depth, every, label) for label in OBJECT_LABELS}
        self._near = {label: blocked | self._reach[label] for label in OBJECT_LABELS}
        # The rules read the Driver by default: with the trained Driver reader its first mark was
        # 0.29 m off instead of 0.07 m in self-play (val_seen), and fewer trials completed.
        self._understanding = understanding or Understanding.by_rules()
        self.reset(SeatInfo(Role.COMMANDER, 0))

    def reset(self, info: SeatInfo) -> None:
        self.belief = Belief(self.scene, self.main)
        self._phase = Phase.WAITING
        self._target: str | None = None
        # After a claim on the target rejected: only places closer to it than its estimate then.
        self._closer_than_m = math.inf
        self._pending: ins.Parsed | None = None  # the instruction out, not yet reported on
        self._questions = 0  # asked since the belief last settled
        self._asked: set[tuple[Sector, Label]] = set()  # at this stop
        # What the Driver said is not there since it last moved ("no blue anywhere", a no to "is there
        # a blue wall on your right?"): not asked again when the mark is doubted (a person was asked
        # about blue on their right after saying so, twice).
        self._denied: set[tuple[Sector, Label]] = set()
        self._asking: tuple[Sector, Label] | None = None  # the yes / no question out
        self._described: set[Sector] = set()  # sides the Driver has said what it sees on since the last instruction
        self._marked: tuple[float, float] | None = None
        self._plain = False
        self._looking = False  # the last question asked the Driver to look all around
        self._looked_around = False  # on this target: a look around is eight moves, asked once a target
        self._stuck = 0  # reports in a row of instructions not carried out
        self._announce: str | None = None  # the target, named with the first leg after the check
        self._checking = False  # the Driver's next message answers the check
        self._before: tuple[str, str] | None = None  # the dialog's last message, for the reader
        self._why_not: str | None = None  # why it rejected the last claim on this target ("why not?")
        self._instructed: str | None = None  # the last instruction said
        self._question_out = False  # the last thing it said asks the Driver something
        self._target_ahead = False  # the Driver's last message says the target is ahead in its camera
        # The last instructions said in a row, each after a report of the last one done.
        self._reported: deque[str] = deque(maxlen=CIRCLING_WITHIN)

    # -- percepts -------------------------------------------------------------------------------

    def perceive(self, percept: Percept) -> list[Action]:
        if isinstance(percept, PhaseBegan):
            return self._phase_changed(percept)
        if isinstance(percept, Heard):
            turns = self._heard(percept.text) if percept.speaker == Role.DRIVER else []
            self._before = ("d" if percept.speaker == Role.DRIVER else "c", percept.text)
            return turns
        if isinstance(percept, Claimed):
            return self._claimed(percept)
        return []  # Judged: its own verdict; Saw and Moved are the Driver seat's, a Commander never gets them

    def _phase_changed(self, change: PhaseBegan) -> list[Action]:
        self._phase = change.phase
        if change.phase == Phase.LOCALIZING:
            return self._say(self.phrases.say(PhraseKind.ASK_VIEW))
        if change.phase == Phase.NAVIGATING and change.target is not None:
            self._target = change.target
            self._closer_than_m = math.inf
            self._why_not = None
            self._looked_around = False
            self._target_ahead = False
            announce = self.phrases.say(PhraseKind.ANNOUNCE, thing=OBJECT_WORDS[object_label(change.target)])
            estimate = self.estimate()
            if estimate.spread_m > SETTLED_M:  # marked after its questions ran out: it says so
                return self._ask(prefix=f"{announce}. i am not sure where you are: my mark is a guess")
            if change.target_index == 0:  # its mark checked first; a Driver told the target looks for it
                self._announce = announce
                return self._check(estimate)
            return self._guide(prefix=announce)
        return []

    def _heard(self, text: str) -> list[Action]:
        lowered = text.lower()
        asked_all = lexicon.asks_all(text)
        asked = asked_all[0] if asked_all else None
        if lexicon.claims(text) and asked != Asked.SHOULD_CLAIM:
            return []  # a claim is on its way
        checked, self._checking = self._checking, False
        # Its mark doubted: the check answered no or unsure ("sort of?"), or the Driver says it is
        # lost ("i feel like im going in circles"). The robot may be anywhere the words allow.
        if checked and lexicon.says_no(text):
            doubted = "then i am not sure where you are"
        elif checked and lexicon.hedges(text):
            doubted = "ok, then i am not sure where you are"
        elif self._phase == Phase.NAVIGATING and lexicon.doubts(text):
            doubted = "sorry, i may have lost you. let me find you again"
        else:
            doubted = None
        if doubted:
            self._elsewhere(DOUBTED)
        navigating = self._phase == Phase.NAVIGATING and self._target is not None
        instructed = navigating and self._pending is not None and not doubted
        if instructed and (reading := lexicon.asked_back(text)) is not None:
            return self._confirm(reading)  # nothing done yet: yes, or no and the instruction again
        # Not a question however it reads: a report ("did it gren wall in front"), or an answer to its
        # own question ("I think so?").
        unknown = asked is None and (lexicon.reports_done(text) or self._question_out)
        if lexicon.only_asks(text) and navigating and not doubted and not unknown:
            # It reports nothing done: the belief stays where it was. (A question it has no answer
            # for, "sharply right = like 90 degrees?" before there was one, was taken for a report
            # of the instruction carried out, and the next one was given from where it was not.)
            return self._answer(asked, proposed=lexicon.proposed(text), about=_object_named(text), also=asked_all)
        blocked = lexicon.blocked(text)  # its way forward is barred where it stands
        short = lexicon.fell_short(text) or bool(_STUCK.search(lowered))
        # A wall right in front after a report of moves made ("done, ...", "ok, i went forward, but now
        # i'm right up against a wall") is where they ended, else where the Driver was stopped.
        stuck = short or (blocked and not lexicon.reports_done(text))
        if instructed and not stuck and lexicon.not_understood(text):
            # Nothing done: said again from where it still is, one move in the simplest words (it
            # was taken for the instruction carried out).
            self._stuck += 1
            return self._guide(prefix="sorry. let me say it more simply", one_move=True)
        # A question about the instruction out, with what the Driver sees, before carrying it out
        # ("theres a blue wall on my right, wont i just hit it?"): not a report of it done. (It was
        # taken for one, and the next instruction was given from where the robot was not.)
        asking = asked is not None or lexicon.has_question(text)
        asks_first = instructed and not stuck and (asked in _HOW_TO or asking and not lexicon.reports_done(text))
        understood = self._understanding.facts(text, self._before)
        read = None if understood.by_rules else belief_facts(understood.meaning)  # None: the lexicon's
        view = lexicon.facts(text) if read is None else read
        self._described |= {s for f in view for s in f.sectors if s in _YOUR_SIDE}
        answered, self._asking = self._asking, None
        denied = {
            (side, f.label)
            for f in view
            if f.negated and f.label is not None
            for side in (_YOUR_SIDE if Sector.ANY in f.sectors else f.sectors)
        }
        if answered is not None and lexicon.says_no(text):
            denied.add(answered)
        if self._target is not None:
            # Kept through a question that names it no more ("its str8 ahead of me rn, why turn left?
            # cant i just drive at it?"), as nothing was done since it was said.
            said = [f for f in view if f.label == object_label(self._target)]
            if said or not asks_first:
                self._target_ahead = any(Sector.FRONT in f.sectors and not f.negated for f in said)
        if self._pending is not None and not asks_first:
            walked = lexicon.walked(text, _counted(self._pending)) if short else None
            self._move(self._pending, whole=not stuck, walked=walked)
            self._denied.clear()  # said of where it was
            self._plain = stuck
            self._stuck = self._stuck + 1 if stuck else 0
            self._pending = None
            # A report after moving names what is ahead; its sides are the edges of the view ahead (the
            # dialog Driver's "red wall on my right") or the sides themselves (a person's "i see the
            # mug on my left"): either.
            self.belief.observe(
                f if set(f.sectors) <= {Sector.FRONT, Sector.ANY} else replace(f, sectors=(Sector.FRONT, *f.sectors))
                for f in view
            )
        elif asks_first:  # what it sees from where it stands; its words of moves are the question's
            self.belief.observe(view)
        else:
            self.belief.message("navigator", text, read)
            if self._looking:  # an object in view would have been named: those not named are not in view
                named = {f.label for f in view}
                self.belief.observe(
                    lexicon.Fact(lexicon.ViewKind.LABEL, (Sector.ANY,), label, negated=True)
                    for label in OBJECT_LABELS
                    if label not in named
                )
        self._denied |= denied
        self._looking = False
        if self._phase == Phase.NAVIGATING and self._target is not None:
            # A Driver told its target claims when it sees it within reach: it does not, so it is not.
            self.belief.log = self.belief.log - np.where(self._reach[object_label(self._target)], UNSEEN_PENALTY, 0.0)
        if blocked:  # its way forward barred: a wall no step ahead
            self._wall_within(0, BLOCKED_PENALTY)
        elif (away := lexicon.steps_away(text)) is not None and any(_wall_close_ahead(f) for f in view):
            # Only where counted: "close ahead" alone is any wall in the view's front within 0.5 m,
            # off to the side too, which no more bars the way ahead than it did the dialog Driver's.
            self._wall_within(away + 1, CLOSE_PENALTY)  # a person's count one off
        estimate = self.estimate()
        if self._phase == Phase.LOCALIZING:
            if estimate.spread_m <= SETTLED_M or self._questions >= MAX_QUESTIONS:
                return self._mark(estimate)
            # Asked anything while it localizes ("where am i?"), it says it does not know yet; called
            # ("hello??"), that it is there; asked to say it again, it asks (it has no instruction out).
            match asked:
                case None | Asked.AGAIN:
                    prefix = None
                case Asked.THERE:
                    prefix = "i am here"
                case _:
                    prefix = "i do not know yet where you are"
            return self._ask(prefix=prefix)
        if self._phase != Phase.NAVIGATING or self._target is None:
            return []
        turns = self._revise(estimate)
        if doubted:
            # "no paddle. the olive cylinder is right-ish behind me. is that your paddle?", asked at its
            # check, went unanswered, and was asked again: what it looks like goes with the doubt.
            if asked in (Asked.IS_IT, Asked.LOOKS):
                doubted = f"{doubted}. {self._looks(_object_named(text))}"
            elif asked == Asked.NEAR_WHAT:  # "... going in circles. what colour walls are near the mug?"
                doubted = f"{doubted}. {self._landmark()}"
            return turns + self._ask(prefix=doubted)
        if asks_first and estimate.spread_m <= LOST_M:
            if asked is not None and asked not in (Asked.WHICH_WAY, Asked.WHY):
                return turns + self._answer(asked, about=_object_named(text), also=asked_all)
            return turns + self._guide(questioned=True, proposed=lexicon.proposed(text))
        lost = estimate.spread_m > LOST_M
        if (lost or self._stuck >= LOST_AFTER) and self._questions < MAX_QUESTIONS:
            self._stuck = 0
            # Said once, with its first question: not again before every one that follows.
            unsure = lost and self._questions == 0
            prefix = "i am not sure where you are now" if unsure else None
            if asked is not None:  # not left unanswered: why not yet
                prefix = "i am not sure where you are yet, so first this"
            return turns + self._ask(prefix=prefix)
        one_move = self._stuck >= REPHRASE_AFTER
        # Asked along with a report ("bumped again. where is the jar?"): answered too, but "where to
        # now?" by the instruction itself ("right first. turn right" reads as two turns).
        if asked is not None and asked != Asked.WHICH_WAY:
            return turns + self._answer(asked, one_move=one_move, about=_object_named(text), also=asked_all)
        return turns + self._guide(one_move=one_move, reported=True, proposed=lexicon.proposed(text))

    def _claimed(self, claim: Claimed) -> list[Action]:
        if self._pending is not None:
            self._move(self._pending, whole=False)  # the claim cut the instruction short somewhere
            self._pending = None
        if self._target is None:
            return [Judge(False)]
        if claim.rays is None:  # no frame to judge from: the belief must be sure
            return [Judge(self._mass_near(self.maze.objects[self._target]) >= SURE)]
        self._observe_view(claim.rays)
        confirmed = near(claim.rays, object_label(self._target))
        if not confirmed:
            # Not within reach from there by the frame: guide it closer, not back to a place as far.
            target = self.maze.objects[self._target]
            self._closer_than_m = min(
                self._closer_than_m, math.dist(self.graph.nodes[self.estimate().pose.node], target)
            )
            # Said so that a Driver reads no move in it (the trained reader took "about 12 steps
            # away" for a walk, an object named for one to go to): no count, no side, no name, and
            # in words the reader reads as no move after any of the Driver's own last messages.
            seen = {s.label for s in describe_seen(claim.rays)}
            if object_label(self._target) in seen:
                why = "no, not yet. you see it, but you are not close enough"
            elif seen & set(OBJECT_LABELS):
                why = "no, not yet. you see something else, not it"
            else:
                why = "no, not yet. it is not in your picture"
            steps = self._steps_to_go(self.estimate())
            self._why_not = (
                f"{why}: by my map it is {'close to you now' if steps <= NEAR_TARGET_STEPS else 'still far from you'}"
            )
            return [Judge(False), Say(self._why_not)]  # said at once: a person waits to hear why
        return [Judge(True)]

    # -- belief ---------------------------------------------------------------------------------

    def _wall_within(self, steps: int, penalty: float) -> None:
        """The Driver says a wall is `steps` ahead (0: barred, right in front): poses with a longer
        free way ahead lose `penalty`. Where the belief had no such pose (it put the robot in the
        open), the robot faces some other way at one of the places it thought likely: a person
        turned, or drifted off the line. (A person said "a white wall right in front, maybe 3
        steps away" and was told to go forward 9 steps: the views alone had not moved the belief.)"""
        run = np.zeros(self.graph.forward.shape, dtype=int)
        at = np.repeat(np.arange(self.graph.n)[:, None], HEADINGS, axis=1)
        headings = np.arange(HEADINGS)[None, :]
        for k in range(steps + 1):  # the free steps ahead, counted up to one more than said
            ahead = self.graph.forward[at, headings]
            free = (ahead >= 0) & (run == k)
            run = run + free
            at = np.where(free, ahead, at)
        longer = run > steps
        p = np.exp(self.belief.log - np.logaddexp.reduce(self.belief.log, axis=None))
        if p[~longer].sum() < 0.5:
            node = np.logaddexp.reduce(self.belief.log, axis=1, keepdims=True)
            self.belief.log = np.logaddexp(self.belief.log, node - math.log(HEADINGS))
        self.belief.log = self.belief.log - np.where(longer, penalty, 0.0)

    def _mass_near(self, xy: tuple[float, float]) -> float:
        log = self.belief.node_logits()
        p = np.exp(log - log.max()).sum(axis=1)
        close = np.hypot(*(self.graph.nodes - xy).T) <= SURE_M
        return float(p[close].sum() / p.sum())

    def estimate(self) -> Estimate:
        """The node with the least expected TD under the belief, facing its likeliest heading."""
        log = self.belief.node_logits()
        p = np.exp(log - log.max()) if np.isfinite(log).any() else np.ones_like(log) * self.main[:, None]
        p = p / p.sum()
        node_p = p.sum(axis=1)
        expected = self._dist @ node_p
        expected[~self.main] = np.inf
        node = int(expected.argmin())
        heading = int(p[node].argmax())
        x, y = self.graph.nodes[node]
        return Estimate(Pose(node, heading), float(x), float(y), float(expected[node]))

    def _move(self, said: ins.Parsed, whole: bool, walked: int | None = None) -> None:
        """Carry the belief through the moves `said` asks for (a counted walk a step short or long
        less likely): to where they end (`whole`); where the Driver stopped short, `walked` steps
        into one of its walks (a step either side less likely), or any pose along the way, each as
        likely, where it did not say how far it got."""
        log = self.belief.log
        along = [log]
        stops: list[np.ndarray] = []
        for item in said.instructions:
            steps = self._steps(item)
            if walked is not None and isinstance(item, ins.Forward):
                stops += self._stops(log, steps, walked)
            previous = log
            for step in steps:
                previous, log = log, self._shift(log, step)
                along.append(log)
            if isinstance(item, ins.Forward) and item.steps is not None and item.steps > 1:
                # A person miscounts a counted walk now and then: a step fewer, or one more.
                further = self._shift(log, np.zeros_like(self._at_wall))
                log = np.logaddexp(log, MISCOUNT + np.logaddexp(previous, further))
        if whole:
            moved = log
        else:
            moved = np.logaddexp.reduce(np.stack(stops or along), axis=0)
        self.belief.log = moved
        # The robot may be anywhere else: a belief sure of a wrong place can still be talked out of it.
        self._elsewhere(ELSEWHERE)

    def _elsewhere(self, share: float) -> None:
        """`share` of the belief spread evenly over every pose of the maze's main part."""
        log = self.belief.log - np.logaddexp.reduce(self.belief.log, axis=None)
        anywhere = np.where(self.main[:, None], math.log(share / self.main.sum() / HEADINGS), -np.inf)
        self.belief.log = np.logaddexp(log + math.log(1 - share), anywhere)

    def _stops(self, log: np.ndarray, steps: list[np.ndarray | int], walked: int) -> list[np.ndarray]:
        """Where a walk of `steps` from `log` stands after `walked` of them, and a step either side
        (less likely: a person miscounts)."""
        out = []
        for k in range(min(walked + 1, len(steps)) + 1):
            if k >= walked - 1:
                out.append(log + (0.0 if k == walked else MISCOUNT))
            if k < len(steps):
                log = self._shift(log, steps[k])
        return out

    def _steps(self, item: ins.Instruction) -> list[np.ndarray | int]:
        """An instruction as per-pose transitions: an int turns by that many eighths, an (N, 8)
        mask walks one step forward wherever it is False (and the way is free)."""
        if isinstance(item, ins.Turn):
            return [item.eighths]
        if isinstance(item, ins.Forward):
            if item.steps is not None:
                return [np.zeros_like(self._at_wall)] * item.steps
            stop = self._near[item.until] if item.until in OBJECT_LABELS else self._at_wall
            return [stop] * MAX_WALK
        return []

    def _shift(self, log: np.ndarray, step: np.ndarray | int) -> np.ndarray:
        if isinstance(step, int):
            return np.roll(log, step, axis=1)
        forward = self.graph.forward
        moves = ~step & (forward >= 0)
        nodes = np.where(moves, forward, np.arange(self.graph.n)[:, None])
        heads = np.broadcast_to(np.arange(HEADINGS), log.shape)
        out = np.full_like(log, -np.inf)
        np.logaddexp.at(out, (nodes, heads), log)
        return out

    def _observe_view(self, obs: RayObservation) -> None:
        """A frame's rays against what every pose sees on the map: a ray of another label, or a
        depth well off, counts against the pose."""
        valid = obs.valid
        wrong = (self.rays.labels[..., valid] != obs.labels[valid]).astype(np.float64)
        off = np.minimum(np.abs(self.rays.depth[..., valid] - obs.depth[valid]) / DEPTH_SCALE_M, 1.0)
        self.belief.log = self.belief.log - VIEW_WEIGHT * np.maximum(wrong, off).sum(axis=-1)

    # -- turns ----------------------------------------------------------------------------------

    def _say(self, text: str, instruction: str | None = None) -> list[Action]:
        """Say `text`; a question is read by the belief with the answer to it. `instruction`: the part
        of `text` the Driver is to carry out, after an answer or an announcement. (The whole text
        was parsed: "about 9 steps away" in an answer to "how far?" was a walk of 9 steps more, and
        the belief went 9 steps further than the Driver once it said it was done.)"""
        self.belief.message("oracle", text)
        self._question_out = text.rstrip().endswith("?")
        parsed = ins.parse(text if instruction is None else instruction)
        self._looking = any(isinstance(i, ins.Ask) and i.look_around for i in parsed.instructions)
        self._pending = parsed if parsed.moves else None
        return [Say(text)]

    def _mark(self, estimate: Estimate) -> list[Action]:
        self._questions = 0
        self._asked.clear()
        self._marked = (estimate.x, estimate.y)
        return [Localize(estimate.x, estimate.y, float(heading_angle(estimate.pose.heading)))]

    def _revise(self, estimate: Estimate) -> list[Action]:
        """Mark the estimate again where it moved from the last mark and has settled."""
        moved = self._marked is not None and math.dist(self._marked, (estimate.x, estimate.y)) >= REVISE_M
        return self._mark(estimate) if moved and estimate.spread_m <= SETTLED_M else []

    def _ask(self, prefix: str | None = None) -> list[Action]:
        """The yes / no question that best halves the belief; first, once a target, a look around."""
        self._questions += 1
        lead = f"{prefix}. " if prefix else ""
        if self._phase == Phase.NAVIGATING and not self._asked and not self._looked_around:
            self._asked.add((Sector.ANY, Label.FLOOR))  # the look around, at this stop
            self._looked_around = True
            return self._say(f"{lead}stop there. {LOOK_AROUND}?")
        log = self.belief.node_logits()
        p = np.exp(log - log.max())
        p = p / p.sum()
        yes = np.einsum("nh,nhsl->sl", p, self._seen)  # (4 sectors, labels)

        def split(question: tuple[Sector, Label]) -> float:
            return min(float(yes[question]), 1.0 - float(yes[question]))

        open_ = [
            (s, label)
            for s in _YOUR_SIDE
            for label in Label
            if label != Label.FLOOR and (s, label) not in self._asked and (s, label) not in self._denied
        ]
        # A side the Driver has told what it sees on is asked about again only where no other side
        # splits the belief: a person told "no, green on my right" was asked "is there a white wall
        # on your right?", and asked about its left after saying "white on my left".
        best = max((q for q in open_ if q[0] not in self._described), key=split, default=None)
        if best is None or split(best) < DESCRIBED_SPLIT:
            best = max(open_, key=split, default=None)
        if best is None or split(best) < 0.02:
            self._questions = MAX_QUESTIONS
            return self._mark(self.estimate()) if self._phase == Phase.LOCALIZING else self._guide()
        self._asked.add(best)
        self._asking = best
        sector, label = best
        return self._say(f"{lead}{_is_there(label, sector)}")

    def _check(self, estimate: Estimate) -> list[Action]:
        """Before the first leg, a question its estimate answers yes and most of the maze no: a
        belief sure of the wrong place (a person's words misread) shows before the Driver is walked
        into walls (a person playing Driver met that twice in four trials). The answer moves the
        belief as any answer does; a no spreads it, and the Commander asks on."""
        seen = self._seen[estimate.pose.node, estimate.pose.heading]
        asked = [(s, label) for s in _YOUR_SIDE for label in Label if label != Label.FLOOR and seen[s, label]]
        if not asked:
            return self._guide()
        # On a side the Driver has not described where there is one: told "a long white wall straight
        # ahead", a person was asked "to check: is there a yellow wall ahead of you?"
        asked = [q for q in asked if q[0] not in self._described] or asked
        sector, label = min(asked, key=lambda q: self._common[q])
        self._asked.add((sector, label))
        self._asking = (sector, label)
        self._checking = True
        # The trial moves on with the mark: "stay where you are", or a person's page says "drive to
        # target 1 of 3" while it checks (two people did not know whether to drive).
        where = _is_there(label, sector)
        return self._say(f"i think i know where you are, but stay where you are for now. to check: {where}")

    def goal(self, node: int) -> int:
        """Where it guides the Driver from `node`: the nearest place from which the target is in view
        within reach; after a rejected claim, the nearest such place closer to the target than the
        estimate was then (the frame's pixels can put the target beyond reach where its rays do not)."""
        assert self._target is not None
        places = np.flatnonzero(self._reach[object_label(self._target)].any(axis=1))
        if not places.size:  # no place of the robot's graph has it in view within reach: the nearest
            away = np.hypot(*(self.graph.nodes - self.maze.objects[self._target]).T)
            places = np.flatnonzero(away <= away.min() + GRID_STEP_M)
        away = np.hypot(*(self.graph.nodes[places] - self.maze.objects[self._target]).T)
        closer = places[away < self._closer_than_m]
        places = closer if closer.size else places
        return int(places[self._dist[node, places].argmin()])

    def _guide(
        self,
        prefix: str | None = None,
        one_move: bool = False,
        questioned: bool = False,
        reported: bool = False,
        proposed: str | None = None,
        is_it: bool = False,
    ) -> list[Action]:
        """The next instruction from the estimate, towards the target: a leg of the route, or after
        instructions not carried out, its first move alone in the simplest words; `questioned` (the
        Driver questioned the last one before carrying it out): said whether it still stands;
        `reported` (after a report of the last one done): the same instruction a third time in a
        row is a belief gone wrong (a person was led round in circles by "go forward about 1 step,
        then turn slightly left", four times): it says so and asks instead; `proposed`: a move the
        Driver asked whether to make ("go straight?"), answered yes or no by the instruction's first;
        asked about it (`questioned`, `proposed`, or `is_it`: "is that the paddle?") with the target
        said to be ahead, straight up to it."""
        assert self._target is not None
        self._questions = 0
        self._asked.clear()
        self._described.clear()
        if self._announce is not None:
            prefix = f"{self._announce}. {prefix}" if prefix else self._announce
            self._announce = None
        estimate = self.estimate()
        label = object_label(self._target)
        reach = self._reach[label]
        goal = self.goal(estimate.pose.node)
        if estimate.pose.node == goal:
            # There: face the target and go up to it; the Driver claims once it sees it within reach.
            headings = np.flatnonzero(reach[goal])
            if not headings.size:  # no place has it in view within reach (`goal`): face it from the nearest
                dx, dy = self.maze.objects[self._target] - self.graph.nodes[goal]
                headings = np.array([heading_index(math.atan2(dy, dx))])
            eighths = min(((int(h) - estimate.pose.heading + 4) % HEADINGS - 4 for h in headings), key=abs)
            turn = self.phrases.turn(eighths)
            until = self.phrases.say(PhraseKind.UNTIL_TARGET, thing=OBJECT_WORDS[label])
            text = f"{turn}, then {until}" if turn else until
        elif self._target_ahead and (questioned or proposed is not None or is_it):
            # The Driver sees it ahead and asks to drive at it: yes, whatever the map's route. A
            # person who said "its str8 ahead of me rn, cant i just drive at it?" was told "by my map
            # that is still the way", twice in a trial. (Sent up to it whenever it was said to be
            # ahead, self-play completed 0.96 of val_seen's trials, not 1.00, in 72 messages, not 62.)
            text = f"go up to the {OBJECT_WORDS[label]}"
        elif one_move:
            text = self._safer(self.router.one_move(estimate.pose, label, goal))
        else:
            text = self._safer(self.router.instruction(estimate.pose, label, goal, plain=self._plain))
        if questioned and self._target_ahead:
            prefix = "yes, you see it"
        elif proposed is not None and (agrees := _same_first_move(proposed, text)) is not None:
            prefix = "yes" if agrees else "no"  # "should I just drive straight down this gap?" asked with a report
        elif questioned:
            prefix = "by my map that is still the way" if text == self._instructed else "thanks, that changes it"
        if self._circling(text, reported):
            self._elsewhere(DOUBTED)
            return self._ask(prefix="i keep saying the same things, so i may have lost you")
        self._instructed = text
        return self._say(f"{prefix}. {text}" if prefix else text, instruction=text)

    def _circling(self, text: str, reported: bool) -> bool:
        """Whether the instruction `text`, said after a report of the last one done, goes round in
        circles: said a third time in a short row of such (a person was led round by "go forward
        about 1 step, then turn slightly left", four times, and another by two that alternated)."""
        if not reported:
            self._reported.clear()
            return False
        self._reported.append(text)
        if self._reported.count(text) < CIRCLING_AFTER:
            return False
        self._reported.clear()
        return True

    def _safer(self, text: str) -> str:
        """`text` where the belief gives its counted walk little chance of meeting a wall before its
        count; else its turn and as many steps as are likely free (then it says the rest from where
        the Driver says it got to), or the turn alone. Where not even a step ahead is likely free,
        `text` still: asking instead (once, "i am not sure which way you are facing") cost more
        messages and moves on val_seen than the walks it spared."""
        said = ins.parse(text)
        if self._refusal(said.instructions) <= RISKY:
            return text
        walks = [(k, i) for k, i in enumerate(said.instructions) if isinstance(i, ins.Forward)]
        if not walks:
            return text
        walk, first = walks[0]
        lead = said.instructions[:walk]
        steps = first.steps or 0  # a walk "until" stops at the wall: never risky
        eighths = sum(i.eighths for i in lead if isinstance(i, ins.Turn))
        turn = [t] if (t := self.phrases.turn(eighths)) else []
        for n in range(steps - 1, 0, -1):
            if self._refusal((*lead, ins.Forward(n))) <= RISKY:
                return ", then ".join([*turn, self.phrases.say(PhraseKind.FORWARD, n=n)])
        return turn[0] if turn else text

    def _refusal(self, said: tuple[ins.Instruction, ...]) -> float:
        """The belief's chance that a counted walk of `said` meets a wall before its count (the
        Driver stops there: a walk into a wall)."""
        log = self.belief.node_logits()
        log = log - np.logaddexp.reduce(log, axis=None)
        blocked = self.graph.forward < 0
        refused = 0.0
        for item in said:
            if isinstance(item, ins.Forward) and item.steps is not None:
                for _ in range(item.steps):
                    refused += float(np.exp(np.logaddexp.reduce(log[blocked]))) if blocked.any() else 0.0
                    log = self._shift(np.where(blocked, -np.inf, log), np.zeros_like(blocked))
                continue
            for step in self._steps(item):
                log = self._shift(log, step)
        return refused

    # -- answers --------------------------------------------------------------------------------

    def _answer(
        self,
        asked: Asked | None,
        one_move: bool = False,
        proposed: str | None = None,
        about: Label | None = None,
        also: Sequence[Asked] = (),
    ) -> list[Action]:
        """A Driver's question answered (one it has no answer for, said so; a move it `proposed`,
        yes or no; what the landmark it is `about` looks like, also where the message asks that among
        what it asks, `also`), then the instruction again from where it still is (a question reports nothing
        done)."""
        assert self._target is not None
        pending, self._pending = self._pending, None
        estimate = self.estimate()
        unsure = "i am not sure where you are, but " if estimate.spread_m > SETTLED_M else ""
        reply: str | None
        match asked:
            case Asked.WHY:  # why it rejected the claim, else why this way
                thing = OBJECT_WORDS[object_label(self._target)]
                reply = self._why_not or f"that is the way to the {thing}. {unsure}{self._where(estimate)}"
            case Asked.HOW_FAR:
                reply = f"{unsure}{self._where(estimate)}"
            case Asked.WHERE_AM_I:
                seen_there = brief(self.router.view(estimate.pose)).replace(" my ", " your ")
                guess = "i am not sure; my best guess (marked on the map) is" if unsure else "i think you are"
                reply = f"{guess} where you see {seen_there}. {self._where(estimate)}"
            case Asked.LOOKS | Asked.IS_IT:  # it cannot see the camera: it says what to look for
                reply = self._looks(about)
                if asked == Asked.IS_IT and about in (None, object_label(self._target)):
                    return self._guide(prefix=reply, one_move=one_move, is_it=True)
            case Asked.SHOULD_CLAIM:
                near_it = self._mass_near(self.maze.objects[self._target]) >= NEAR_ENOUGH
                reply = "yes, if it is right in front of you, press i found the target" if near_it else None
                reply = reply or f"not yet, by my map. {unsure}{self._where(estimate)}"
            case Asked.NEAR_WHAT:
                reply = self._landmark()
            case Asked.WHICH_ONE:  # the wall it named is not clear: the leg in counted steps instead
                self._plain = True
                reply = "let me say it in steps"
            case Asked.TURN_SIZE:
                reply = self._turn_size(pending)
            case Asked.THERE:  # "hello??", "u there?" had been "sorry, i did not get your question"
                reply = "i am here"
            case Asked.AGAIN:
                reply = "again"
            case None if proposed is not None:
                return self._guide(one_move=one_move, proposed=proposed)
            case None:
                reply = "sorry, i did not get your question. again"
            case Asked.WHICH_WAY:
                actions, _ = self.router.plan(estimate.pose, self.goal(estimate.pose.node))
                first = actions[0] if actions else None
                way = {Move.LEFT: "left", Move.RIGHT: "right", Move.FORWARD: "straight ahead"}
                reply = f"{unsure}{way[first]} first" if first in way else None
        if asked not in (Asked.LOOKS, Asked.IS_IT) and Asked.LOOKS in also:
            # "u didnt answer, what color is the mug n is it close?": told how far, not the colour
            reply = f"{reply}. {self._looks(about)}" if reply else self._looks(about)
        return self._guide(prefix=reply, one_move=one_move)

    def _confirm(self, reading: str) -> list[Action]:
        """A Driver's reading of the instruction out, said back and asked about: "yes" where it
        moves as the instruction does, else "no" and the instruction again."""
        assert self._pending is not None and self._instructed is not None
        if _moves(ins.parse(reading)) == _moves(self._pending):
            return self._say("yes", instruction=self._instructed)
        return self._guide(prefix="no")

    def _turn_size(self, said: ins.Parsed | None) -> str:
        """How far the turns of the instruction out turn, in degrees, each as its presses of Left or
        Right (a run of presses one way is one turn)."""
        turns = [i.eighths for i in (said.instructions if said else ()) if isinstance(i, ins.Turn) and i.eighths]
        if not turns:
            return "each press of left or right turns 45 degrees"
        sizes = [sum(run) for _, run in itertools.groupby(turns, key=lambda eighths: eighths > 0)]
        return ", and ".join(f"{self.phrases.turn(e)}: that turns {45 * abs(e)} degrees, 45 a press" for e in sizes)

    def _landmark(self) -> str:
        """The walls nearest the target on the map, by colour: the nearest, and another about as near."""
        assert self._target is not None
        col, row = (int(round(float(v))) for v in world_to_pixel(*self.maze.objects[self._target]))
        r = int(LANDMARK_M / TABLE_WIDTH_M * MAP_WIDTH_PX)
        top, left = max(row - r, 0), max(col - r, 0)
        around = self.maze.labels[top : row + r + 1, left : col + r + 1]
        rows, cols = np.indices(around.shape)
        away = np.hypot(rows + top - row, cols + left - col) * TABLE_WIDTH_M / MAP_WIDTH_PX
        nearest = {label: float(away[around == label].min()) for label in WALL_LABELS if (around == label).any()}
        thing = OBJECT_WORDS[object_label(self._target)]
        if not nearest:
            return f"the {thing} stands in the open, away from the walls"
        first = min(nearest.values())
        walls = [
            wall_name(label) for label, d in sorted(nearest.items(), key=lambda kv: kv[1]) if d <= first + ALSO_NEAR_M
        ]
        return f"the {thing} is next to the {' and the '.join(walls[:2])}"

    def _looks(self, label: Label | None = None) -> str:
        """What landmark `label` looks like (the target's where None), in words the Driver agent reads
        as that landmark named, no move ("is that the jar?" while the mug was next had been told
        what the mug looks like)."""
        if label is None:
            assert self._target is not None
            label = object_label(self._target)
        return f"the {OBJECT_WORDS[label]} is {OBJECT_LOOKS[label]} in the camera"

    def _steps_to_go(self, estimate: Estimate) -> int:
        return int(round(self._dist[estimate.pose.node, self.goal(estimate.pose.node)] / GRID_STEP_M))

    def _where(self, estimate: Estimate) -> str:
        """Where the target is from the estimate: how many steps' walk, and which side of the Driver."""
        assert self._target is not None
        label = object_label(self._target)
        x, y = self.maze.objects[self._target]
        steps = self._steps_to_go(estimate)
        bearing = math.degrees(math.atan2(y - estimate.y, x - estimate.x) - heading_angle(estimate.pose.heading))
        bearing = (bearing + 180) % 360 - 180  # left positive
        side = "left" if bearing > 0 else "right"
        if abs(bearing) <= 30:
            where = "ahead of you"
        elif abs(bearing) <= 75:
            where = f"ahead on your {side}"
        elif abs(bearing) <= 120:
            where = f"on your {side}"
        elif abs(bearing) <= 160:
            where = f"behind you on your {side}"
        else:
            where = "behind you"
        said = f"i think the {OBJECT_WORDS[label]} is {where}, about {steps} steps away"
        # A target on one side and a route that turns the other way first ("the paddle is on your
        # right ... turn sharply left") left a person driving unsure which to trust: both are said.
        actions, _ = self.router.plan(estimate.pose, self.goal(estimate.pose.node))
        first = actions[0] if actions else None
        if 30 < abs(bearing) <= 160 and first == (Move.RIGHT if bearing > 0 else Move.LEFT):
            said += f", but the way there starts to your {'right' if first == Move.RIGHT else 'left'}"
        return said
